"""Systems tests of collection: the hand back-end's physics, kill -9 resume, back-end parity."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from drake_symplan.actions import Action
from drake_symplan.datasets import ObjectState
from drake_symplan.world.scenes import ObjectSpec, Scene

CUBE_ON_CUBE = [("o0", "cube", (0.6, 0.2, 0.025)), ("o1", "cube", (0.7, 0.0, 0.025))]
BLOCK_WITH_CUBE = [("o0", "long", (0.6, 0.2, 0.025)), ("o1", "cube", (0.6, 0.275, 0.075)),
                   ("o2", "cube", (0.7, 0.0, 0.025))]
BLOCK_AND_CUBE = [("o0", "long", (0.6, 0.2, 0.025)), ("o1", "cube", (0.7, 0.0, 0.025))]
# The rider 5 cm along the block: released centred on a cube, the load's centre of mass lies
# 1.5 cm inside the cube's edge (the careful carry's margin). At 7.5 cm it lies 1 cm inside,
# where boxes of modulus 1e6 lean far enough to tip (docs/world.md).
BLOCK_WITH_CUBE_INSIDE = [("o0", "long", (0.6, 0.2, 0.025)), ("o1", "cube", (0.6, 0.25, 0.075)),
                          ("o2", "cube", (0.7, 0.0, 0.025))]


@pytest.fixture(scope="module")
def hand_station():
    from drake_symplan.world.station import Station, StationConfig

    return Station(StationConfig(robot="hand", discrete_contact_approximation="similar"))


def run_hand(station, objects, action):
    from drake_symplan.robot.backends import RESET_SETTLE
    from drake_symplan.skills.hand_place import hand_pick_place

    station.reset(Scene([ObjectSpec(n, t, list(p), 0.0) for n, t, p in objects]))
    station.settle(RESET_SETTLE)  # as the back-end's reset: the boxes sink into the table
    beliefs = {n: ObjectState(n, t, np.array(p, float)) for n, t, p in objects}
    start = station.object_states()
    motion, lifted = hand_pick_place(station, action, beliefs, station.object_states)
    return motion, start, lifted, station.object_states()


def test_hand_stacks_tips_carries_and_misses(hand_station):
    motion, _, _, end = run_hand(hand_station, CUBE_ON_CUBE, Action("o0", "center", "o1", "center"))
    assert motion.held == "o0" and motion.kinematic
    assert end["o0"].position[2] == pytest.approx(0.075, abs=0.005)
    assert np.linalg.norm(end["o0"].position[:2] - end["o1"].position[:2]) < 0.01

    motion, _, lifted, end = run_hand(hand_station, BLOCK_WITH_CUBE_INSIDE,
                                      Action("o0", "center", "o2", "center"))
    assert motion.held == "o0" and not motion.kinematic  # a cube rides on the block
    assert lifted["o1"].position[2] > 0.2
    assert end["o1"].position[2] == pytest.approx(end["o0"].position[2] + 0.05, abs=0.008)

    _, _, _, end = run_hand(hand_station, BLOCK_AND_CUBE, Action("o0", "left", "o1", "center"))
    assert np.degrees(end["o0"].tilt) > 10

    motion, start, _, end = run_hand(hand_station, CUBE_ON_CUBE,
                                     Action("o0", "right", "o1", "center"))
    assert motion.held is None
    assert np.allclose(end["o0"].position, start["o0"].position, atol=1e-4)


def test_boxes_resting_on_the_table_are_still(hand_station):
    # With too little contact dissipation the blocks of this scene keep rocking in a
    # 4-step limit cycle (~0.3 rad/s), which also makes every physics step costlier.
    from drake_symplan.world.scenes import sample_scene

    rng = np.random.default_rng(3)
    scenes = [sample_scene(rng, 4, long_fraction=0.5) for _ in range(3)]
    hand_station.reset(scenes[2])
    hand_station.settle(0.5)
    plant, ctx = hand_station.plant, hand_station.plant_context
    for body in hand_station.assigned.values():
        V = plant.EvalBodySpatialVelocityInWorld(ctx, body)
        assert np.linalg.norm(V.translational()) < 0.005
        assert np.linalg.norm(V.rotational()) < 0.05


def _collect_cmd(out, n):
    return [sys.executable, "-m", "drake_symplan.cli.main", "collect", "--backend", "hand",
            "--transitions", str(n), "--workers", "1", "--out", str(out), "--seed", "3",
            "--objects", "2-3", "--chunk-size", "4", "--no-progress", "--json"]


@pytest.mark.slow
def test_kill_9_then_the_same_command_ends_with_exactly_n(tmp_path):
    from drake_symplan.data.stats import dataset_stats
    from drake_symplan.data.storage import existing_shards, load_transitions

    out, n = tmp_path / "data", 22
    proc = subprocess.Popen(_collect_cmd(out, n), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and len(existing_shards(out)) < 2:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    interrupted = len(existing_shards(out))
    assert 2 <= interrupted < 6, "kill landed before the first shards or after the end"
    subprocess.run(_collect_cmd(out, n), check=True, capture_output=True, timeout=300)
    data = load_transitions(out)
    assert len(data) == n
    keys = set()
    for path in sorted(existing_shards(out).values()):
        with np.load(path) as z:
            keys.update(zip(z["episode"].tolist(), z["step"].tolist(), strict=True))
    assert len(keys) == n  # no (episode, step) twice
    assert not list(out.glob(".*tmp*"))
    stats = dataset_stats(out)
    phases = stats["worker_seconds_by_phase"]
    assert phases["physics"] > 0 and phases["perception"] > 0 and phases["other"] >= 0
    from drake_symplan.cli.main import main

    assert main(["data", "stats", str(out), "--json"]) == 0


@pytest.mark.slow
def test_a_larger_n_extends_a_collection_and_anything_else_is_refused(tmp_path):
    from drake_symplan.data.collect import CollectConfig, collect
    from drake_symplan.data.storage import existing_shards, load_transitions, read_manifest

    def config(n, seed=3):
        return CollectConfig(transitions=n, seed=seed, max_objects=3, chunk_size=3)

    out = tmp_path / "data"
    collect(out, config(4), progress=False)  # chunks of 3 and 1
    first = existing_shards(out)[0].read_bytes()
    with pytest.raises(ValueError, match="different configuration"):
        collect(out, config(7, seed=4), progress=False)
    with pytest.raises(ValueError, match="different configuration"):
        collect(out, config(3), progress=False)
    summary = collect(out, config(7), progress=False)  # chunks of 3, 3 and 1
    assert summary["this_run"]["new_transitions"] == 4  # the short chunk 1 is redone
    assert existing_shards(out)[0].read_bytes() == first  # kept, not recollected
    assert len(load_transitions(out)) == 7
    fresh = tmp_path / "fresh"
    collect(fresh, config(7), progress=False)
    for c, path in existing_shards(fresh).items():
        with np.load(path) as a, np.load(existing_shards(out)[c]) as b:
            assert np.array_equal(a["episode"], b["episode"])
            assert np.allclose(a["effect"], b["effect"])
    manifest = read_manifest(out)
    assert manifest["config"]["transitions"] == 7 and manifest["extended_from"] == [4]


def test_a_collection_made_at_5_ms_extends_only_at_5_ms(tmp_path):
    import dataclasses as dc

    from drake_symplan.data import storage
    from drake_symplan.data.collect import CollectConfig, _prepare

    old = dc.asdict(CollectConfig(transitions=4, chunk_size=2))
    del old["time_step"]  # manifests written before the step was recorded ran at 5 ms
    storage.write_manifest(tmp_path, {"config": old, "seed": 0, "status": "done"})
    with pytest.raises(ValueError, match="different configuration"):
        _prepare(tmp_path, CollectConfig(transitions=6, chunk_size=2))  # 10 ms
    manifest, todo, done = _prepare(
        tmp_path, CollectConfig(transitions=6, chunk_size=2, time_step=0.005))
    assert todo == [0, 1, 2] and done == 0 and manifest["config"]["time_step"] == 0.005


def test_a_collection_made_before_resting_stacks_extends_only_with_their_physics(tmp_path):
    import dataclasses as dc

    from drake_symplan.data import storage
    from drake_symplan.data.collect import CollectConfig, _prepare

    old = dc.asdict(CollectConfig(transitions=4, chunk_size=2))
    del old["box_modulus"]  # manifests from before it was recorded: 1e7 Pa
    storage.write_manifest(tmp_path, {"config": old, "seed": 0, "status": "done"})
    with pytest.raises(ValueError, match="different configuration"):
        _prepare(tmp_path, CollectConfig(transitions=6, chunk_size=2))  # 1e6 Pa
    manifest, todo, _ = _prepare(
        tmp_path, CollectConfig(transitions=6, chunk_size=2, box_modulus=1e7))
    assert todo == [0, 1, 2] and manifest["config"]["box_modulus"] == 1e7


@pytest.mark.slow
def test_hand_and_arm_agree_on_a_fixed_set():
    from drake_symplan.data.parity import measure_parity

    # Perceived names follow position order (x, then y): p0 is the x = 0.6 object.
    pairs = [
        (Scene([ObjectSpec(n, t, list(p)) for n, t, p in CUBE_ON_CUBE]),
         Action("p0", "center", "p1", "center")),
        (Scene([ObjectSpec(n, t, list(p)) for n, t, p in BLOCK_AND_CUBE]),
         Action("p0", "left", "p1", "center")),
        (Scene([ObjectSpec(n, t, list(p)) for n, t, p in CUBE_ON_CUBE]),
         Action("p0", "right", "p1", "center")),
        (Scene([ObjectSpec(n, t, list(p)) for n, t, p in BLOCK_WITH_CUBE]),
         Action("p0", "center", "p2", "center")),
    ]
    report = measure_parity(len(pairs), scenes_actions=pairs)
    assert report["pairs"] == len(pairs), report["skipped"]
    assert report["class_agreement"] == 1.0, report["confusion"]
    # the block with a cube on it is the one source that carries something (careful carry)
    assert report["carrying"] == {"pairs": 1, "class_agreement": 1.0}
    assert report["not_carrying"] == {"pairs": 3, "class_agreement": 1.0}
    assert report["effect_diff_median_m"] <= 0.01
    assert {r["hand"] for r in report["rows"]} == {"placed", "tipped", "no_effect",
                                                   "carried_along"}


@pytest.mark.parametrize("field, value, rule", [
    ("seed", -1, "seed must be an integer in [0, 2**32), got -1"),
    ("long_fraction", 1.5, "long_fraction must be a probability in [0, 1], got 1.5"),
    ("noise_sigma", float("nan"), "noise_sigma must be a finite number >= 0 (m), got nan"),
    ("noise_dropout", 1.0, "noise_dropout must be a fraction in [0, 1), got 1.0"),
])
def test_a_config_out_of_range_is_refused_before_anything_is_written(field, value, rule):
    from drake_symplan.data.collect import CollectConfig

    with pytest.raises(ValueError) as caught:
        CollectConfig(**{field: value})
    assert str(caught.value) == rule
