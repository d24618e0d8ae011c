"""`symplan solve`, `problems make` and `eval planning` on bad input: exit status 2 and one
line on stderr, before any station is built."""

from __future__ import annotations

import pytest
from conftest import assert_bad_input, run

from drake_symplan.world.scenes import ObjectSpec, Scene, save_scene

A = ObjectSpec("a", "cube", [0.6, 0.0, 0.025])
B = ObjectSpec("b", "cube", [0.8, 0.1, 0.025])
A_ON_B = ObjectSpec("a", "cube", [0.8, 0.1, 0.075])


@pytest.fixture
def scenes(tmp_path):
    def write(name, *objects):
        path = tmp_path / name
        save_scene(Scene(list(objects)), path)
        return path
    return write


def test_unknown_objects_in_the_goal(scenes, tmp_path, capsys):
    start, goal = scenes("start.yaml", A, B), scenes("goal.yaml", A_ON_B, B,
                                                      ObjectSpec("z", "cube", [0.5, -0.3, 0.025]))
    record = tmp_path / "solve.html"
    code, out, err = run(["solve", "--start", start, "--goal", goal, "--record", record,
                          "--json"], capsys)
    assert_bad_input(code, out, err, "symplan solve: error: unknown objects in the goal: ['z']")
    assert not record.exists()


def test_start_and_goal_with_other_objects(scenes, capsys):
    start = scenes("start.yaml", A, B)
    code, out, err = run(["solve", "--start", start, "--goal", scenes("goal.yaml", A)], capsys)
    assert_bad_input(code, out, err, "the goal lacks start objects ['b']")
    long_b = ObjectSpec("b", "long", [0.8, 0.1, 0.025])
    code, out, err = run(["solve", "--start", start, "--goal",
                          scenes("goal2.yaml", A, long_b)], capsys)
    assert_bad_input(code, out, err, "b (cube -> long)")


def test_unreadable_scene_and_model_directories(scenes, tmp_path, capsys):
    start, goal = scenes("start.yaml", A, B), scenes("goal.yaml", A_ON_B, B)
    code, out, err = run(["solve", "--start", tmp_path / "none.yaml", "--goal", goal], capsys)
    assert_bad_input(code, out, err, "none.yaml")
    missing = tmp_path / "no_model"
    code, out, err = run(["solve", "--start", start, "--goal", goal, "--model", missing],
                         capsys)
    assert_bad_input(code, out, err, f"no model directory {missing}")
    code, out, err = run(["solve", "--start", start, "--goal", goal, "--timeout", "0"], capsys)
    assert_bad_input(code, out, err, "--timeout")
    code, out, err = run(["solve", "--start", start, "--goal", goal, "--alternatives", "-1"],
                         capsys)
    assert_bad_input(code, out, err, "argument --alternatives: must be a non-negative integer")


def test_a_model_without_operators(scenes, tmp_path, capsys):
    bundle = pytest.importorskip("drake_symplan.symbolic.bundle")
    default_bundle_dir = bundle.default_bundle_dir
    start, goal = scenes("start.yaml", A, B), scenes("goal.yaml", A_ON_B, B)
    empty = tmp_path / "empty_model"
    empty.mkdir()
    code, out, err = run(["solve", "--start", start, "--goal", goal, "--model", empty], capsys)
    assert_bad_input(code, out, err, str(empty))
    (empty / "model.pt").write_bytes(b"")  # a model, but no operators.json
    code, out, err = run(["solve", "--start", start, "--goal", goal, "--model", empty], capsys)
    assert_bad_input(code, out, err, str(empty), "operators.json")
    (tmp_path / "set" / "p000").mkdir(parents=True)
    (tmp_path / "set" / "p000" / "problem.json").write_text('{"k": 1, "n_objects": 2}')
    code, out, err = run(["eval", "planning", "--runs", empty, "--problems", tmp_path / "set"],
                         capsys)
    assert_bad_input(code, out, err, str(empty), "operators.json")
    # A good model: the problem's missing scene files fail before anything is solved.
    code, out, err = run(["eval", "planning", "--runs", default_bundle_dir(), "--problems",
                          tmp_path / "set"], capsys)
    assert_bad_input(code, out, err, str(tmp_path / "set" / "p000" / "start.yaml"))


def test_problem_and_evaluation_arguments(tmp_path, capsys):
    code, out, err = run(["problems", "make", "--out", tmp_path / "p", "--objects", "1",
                          "--k", "1", "--count", "1"], capsys)
    assert_bad_input(code, out, err, "--objects must be in [2, 16]")
    code, out, err = run(["problems", "make", "--out", tmp_path / "p", "--objects", "2",
                          "--k", "0", "--count", "1"], capsys)
    assert_bad_input(code, out, err, "--k")
    assert not (tmp_path / "p").exists()
    code, out, err = run(["eval", "planning", "--runs", tmp_path / "none", "--problems",
                          tmp_path], capsys)
    assert_bad_input(code, out, err, "no model directory")
