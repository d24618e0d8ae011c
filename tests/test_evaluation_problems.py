"""Problem sets: the non-trivial filter on hand-made positions, scenes with tilted objects
(`rpy`) through save/load and validation, goal scenes from simulator poses."""

from __future__ import annotations

import json

import numpy as np
import pytest

from drake_symplan.goals.problems import (
    displacement,
    is_nontrivial,
    load_problems,
    problem_seed,
    scene_from_poses,
)
from drake_symplan.world.scenes import (
    ObjectSpec,
    Scene,
    SceneError,
    load_scene,
    save_scene,
    scene_from_dict,
    validate_scene,
)

START = {"a": np.array([0.6, 0.0, 0.025]), "b": np.array([0.8, 0.1, 0.025])}


def test_a_goal_is_trivial_unless_an_object_moved_more_than_5_cm():
    assert not is_nontrivial(START, START)
    nudged = {"a": START["a"] + [0.03, 0.03, 0.0], "b": START["b"]}  # 4.2 cm
    assert not is_nontrivial(START, nudged)
    stacked = {"a": np.array([0.8, 0.1, 0.075]), "b": START["b"]}
    assert is_nontrivial(START, stacked)
    assert displacement(START, stacked) == pytest.approx(np.linalg.norm([0.2, 0.1, 0.05]))
    lifted = {"a": START["a"] + [0.0, 0.0, 0.051], "b": START["b"]}
    assert is_nontrivial(START, lifted)


def test_displacement_needs_every_object():
    with pytest.raises(ValueError, match=r"\['b'\]"):
        displacement(START, {"a": START["a"]})


def test_a_tilted_object_round_trips_through_save_and_load(tmp_path):
    tipped = ObjectSpec("o1", "long", [0.72, -0.196, 0.0498], rpy=[-0.2055, -0.003, -0.0339])
    scene = Scene([ObjectSpec("o0", "cube", [0.72, -0.343, 0.025], 0.1), tipped])
    assert tipped.yaw == pytest.approx(-0.0339) and tipped.tilted
    save_scene(scene, tmp_path / "goal.yaml")
    assert "rpy: [-0.2055, -0.0030, -0.0339]" in (tmp_path / "goal.yaml").read_text()
    loaded = load_scene(tmp_path / "goal.yaml")
    assert loaded.objects[0].rpy is None and loaded.objects[0].yaw == pytest.approx(0.1)
    assert loaded.objects[1].rpy == pytest.approx([-0.2055, -0.003, -0.0339])
    assert loaded.objects[1].yaw == pytest.approx(-0.0339)
    assert loaded.objects[1].orientation == pytest.approx(tipped.rpy)


def test_tilted_objects_skip_the_resting_checks_upright_ones_keep_them():
    # A block leaning at 12 degrees, 5 cm up: neither on the table nor on a box top.
    leaning = ObjectSpec("b", "long", [0.7, 0.0, 0.05], rpy=[0.21, 0.0, 0.0])
    validate_scene(Scene([ObjectSpec("a", "cube", [0.7, -0.08, 0.025]), leaning]))
    # A cube resting on the leaning block is taken as supported by it.
    validate_scene(Scene([leaning, ObjectSpec("c", "cube", [0.7, 0.05, 0.1])]))
    floating = ObjectSpec("b", "long", [0.7, 0.0, 0.05], rpy=[0.0, 0.0, 0.3])  # upright
    with pytest.raises(SceneError, match="rests on neither"):
        validate_scene(Scene([floating]))


def test_rpy_and_yaw_must_agree_in_a_file():
    item = {"name": "a", "type": "cube", "position": [0.7, 0, 0.025]}
    with pytest.raises(SceneError, match="differs"):
        scene_from_dict({"objects": [{**item, "yaw": 0.5, "rpy": [0.3, 0, 0.1]}]})
    with pytest.raises(SceneError, match="roll, pitch, yaw"):
        scene_from_dict({"objects": [{**item, "rpy": [0.3, 0]}]})
    assert scene_from_dict({"objects": [{**item, "yaw": 0.1, "rpy": [0.3, 0, 0.1]}]}) \
        .objects[0].yaw == pytest.approx(0.1)


def test_goal_scenes_from_poses_use_rpy_for_tilted_bodies_only():
    from pydrake.math import RigidTransform, RollPitchYaw

    poses = {"a": RigidTransform(RollPitchYaw(0.001, 0.0, 0.2), [0.7, 0.0, 0.025]),
             "b": RigidTransform(RollPitchYaw(0.3, 0.0, -0.1), [0.7, 0.1, 0.05])}
    scene = scene_from_poses(poses, {"a": "cube", "b": "long"})
    a, b = scene.objects
    assert a.rpy is None and a.yaw == pytest.approx(0.2)
    assert b.rpy == pytest.approx([0.3, 0.0, -0.1]) and b.tilted


def test_problem_seeds_and_loading(tmp_path):
    assert problem_seed(0, 3) == problem_seed(0, 3) != problem_seed(1, 3)
    for i, (n, k) in enumerate([(2, 1), (3, 2)]):
        (tmp_path / "set" / f"p{i:03d}").mkdir(parents=True)
        (tmp_path / "set" / f"p{i:03d}" / "problem.json").write_text(
            json.dumps({"k": k, "seed": i, "n_objects": n}))
    problems = load_problems(tmp_path)
    assert [(p["n_objects"], p["k"]) for p in problems] == [(2, 1), (3, 2)]
    assert problems[0]["dir"].endswith("set/p000")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no problems"):
        load_problems(tmp_path / "empty")
    with pytest.raises(FileNotFoundError):
        load_problems(tmp_path / "absent")


@pytest.mark.slow
def test_reproducible_problems_replay_from_their_files(tmp_path):
    from drake_symplan.actions import Action
    from drake_symplan.agent import beliefs
    from drake_symplan.agent.solve import Agent
    from drake_symplan.boxes import GOAL_TOLERANCE
    from drake_symplan.goals.problems import make_problems, replay

    agent = Agent("hand")
    summary = make_problems(tmp_path, 3, [2], 2, seed=7, backend="hand", agent=agent,
                            reproducible=True)
    assert summary["kept"] == 2 and summary["settings"]["reproducible"] is True
    for problem in load_problems(tmp_path):
        folder = tmp_path / problem["dir"]
        actions = [Action.from_text(a) for a in problem["actions"]]
        goal = beliefs.positions(agent.look(load_scene(folder / "goal.yaml")).scene)
        start = load_scene(folder / "start.yaml")
        assert displacement(goal, beliefs.positions(replay(agent, start, actions))) \
            <= GOAL_TOLERANCE
        # Nothing replayed leaves the start, which is more than 5 cm off (non-trivial).
        assert displacement(goal, beliefs.positions(replay(agent, start, []))) \
            > GOAL_TOLERANCE
    with pytest.raises(ValueError, match="reproducible"):  # a set keeps its settings
        make_problems(tmp_path, 3, [2], 3, seed=7, backend="hand", agent=agent)
