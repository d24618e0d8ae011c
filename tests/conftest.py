"""Shared fixtures: one station diagram and one IK planner per test session (building is
slow); a copy of the shipped bundle and a tiny data set for the CLI's input checks."""

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def station():
    from drake_symplan.world.station import Station

    return Station()


@pytest.fixture(scope="session")
def planner():
    from drake_symplan.skills.pick_place import PickPlacePlanner

    return PickPlacePlanner()


@pytest.fixture
def bundle_copy(tmp_path):
    """A copy of the shipped model bundle (models/learned) to spoil."""
    import shutil

    from drake_symplan.symbolic.bundle import default_bundle_dir

    return Path(shutil.copytree(default_bundle_dir(), tmp_path / "bundle"))


@pytest.fixture
def tiny_dataset(tmp_path):
    """A data set directory of one shard of 4 made-up transitions and its manifest: what
    `symplan data stats` reads, no simulation needed."""
    import numpy as np

    from drake_symplan.actions import ACTION_DIM, EFFECT_DIM
    from drake_symplan.datasets import TransitionArrays
    from drake_symplan.shards import write_manifest, write_shard

    t, n, d = 4, 3, 5
    arrays = TransitionArrays(np.zeros((t, n, d)), np.zeros((t, n, ACTION_DIM)),
                              np.zeros((t, n, EFFECT_DIM)), np.ones((t, n), bool),
                              np.arange(t))
    out = tmp_path / "data"
    write_shard(out, 0, arrays)
    write_manifest(out, {"config": {"made": "by hand"}})
    return out
