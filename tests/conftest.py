"""Shared fixtures and helpers: one station diagram and one IK planner per test session
(building is slow), a camera station per module, and the helpers several test files use
(`from conftest import ...`: tests/ is on sys.path under pytest)."""

import argparse
import base64
import os
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DEV_BUNDLE = REPO / "runs" / "dev_ops" / "relational_inv_s0" / "bundle_effect"


@pytest.fixture(scope="session")
def station():
    from drake_symplan.world.station import Station

    return Station()


@pytest.fixture(scope="session")
def planner():
    from drake_symplan.skills.pick_place import PickPlaceMotions

    return PickPlaceMotions()


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


@pytest.fixture(scope="module")
def camera_station():
    """A station with the default depth cameras, one per test module."""
    from drake_symplan.world.cameras import default_cameras
    from drake_symplan.world.station import Station, StationConfig

    return Station(StationConfig(cameras=default_cameras()))


def run(argv, capsys):
    """(exit status, stdout, stderr) of `symplan ARGV` run in process."""
    from drake_symplan.cli import main as cli_main

    code = cli_main.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_bad_input(code, out, err, *expected):
    """Exit status 2, nothing on stdout, one line on stderr holding every `expected`."""
    assert code == 2 and out == "", (code, out, err)
    assert err.count("\n") == 1 and err.endswith("\n"), err
    for text in expected:
        assert text in err, err


def parse_learning_args(argv):
    """The learning commands' parser (train, eval effects, ...) on `argv`."""
    from drake_symplan.cli import learning_cmds

    parser = argparse.ArgumentParser()
    learning_cmds.register(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def bundle_for_tests() -> Path:
    """$SYMPLAN_TEST_BUNDLE, else the shipped default, else the development bundle under
    runs/ (not in a clone); skips without one."""
    path = os.environ.get("SYMPLAN_TEST_BUNDLE")
    if path:
        return Path(path)
    from drake_symplan.symbolic.bundle import default_bundle_dir

    for candidate in (default_bundle_dir(), DEV_BUNDLE):
        if candidate.is_dir():
            return candidate
    pytest.skip("no model bundle (set SYMPLAN_TEST_BUNDLE to one)")


def recorded_paths(page: str, prefix: str | None = None) -> set[str]:
    """The Meshcat paths under `prefix` (default: the inspection's) that a static page
    (StaticHtml) sets: its scene commands are base64 msgpack blobs, whose path strings
    are read back here."""
    if prefix is None:
        from drake_symplan.agent.inspection import PREFIX as prefix
    data = b"".join(base64.b64decode(b) for b in re.findall(r"base64,([A-Za-z0-9+/=]+)", page))
    return {m.decode() for m in re.findall(re.escape(prefix.encode()) + rb"/[A-Za-z0-9_/]+",
                                           data)}


def collect_args(seed: int, chunk: int, out, n: int) -> list[str]:
    """`symplan collect` arguments for n hand transitions of 2-3 objects into `out`."""
    return ["collect", "--backend", "hand", "--transitions", str(n), "--out", str(out),
            "--seed", str(seed), "--objects", "2-3", "--chunk-size", str(chunk),
            "--no-progress", "--json"]


def shard_arrays(path) -> dict:
    """A shard's arrays, less `info` (it holds timings)."""
    import numpy as np

    with np.load(path) as z:
        return {k: z[k] for k in z.files if k != "info"}


def write_rule_data(out: Path, n: int, shards: int = 1) -> Path:
    """`out` as a data set of n transitions of the synthetic same-group rule (seed 0,
    episodes of 5), in `shards` equal shards."""
    import numpy as np
    from synthetic_rule import same_group_rule

    from drake_symplan.shards import write_manifest, write_shard

    arrays, _ = same_group_rule(n, seed=0, episode_length=5)
    write_manifest(out)
    for i, rows in enumerate(np.array_split(np.arange(n), shards)):
        write_shard(out, i, arrays.subset(rows))
    return out
