"""Goals written in one line (goals/compiler.py, `symplan goal`): each word's actions and
geometry, every spec the world cannot give refused in one line before anything runs, and a
goal built by the robot holding what its spec names."""

from __future__ import annotations

import pytest
from conftest import assert_bad_input, run

from drake_symplan.actions import Action
from drake_symplan.goals import compiler, sampling
from drake_symplan.relations import SpecError, parse, unmet
from drake_symplan.world.scenes import ObjectSpec, Scene, load_scene, save_scene

START = Scene([
    ObjectSpec("o0", "cube", [0.60, -0.25, 0.025]),
    ObjectSpec("o1", "cube", [0.75, -0.25, 0.025]),
    ObjectSpec("o2", "cube", [0.60, 0.00, 0.025]),
    ObjectSpec("o3", "cube", [0.75, 0.05, 0.025]),
    ObjectSpec("o4", "long", [0.90, -0.10, 0.025]),
    ObjectSpec("o5", "cube", [0.60, 0.15, 0.025]),
])


def test_each_word_compiles_to_the_actions_that_build_it():
    objects = START.object_states()
    build = compiler.build_actions
    assert build(parse(["tower o3 o1 o0"]), objects) == [
        Action("o1", "center", "o0", "center"), Action("o3", "center", "o1", "center")]
    assert build(parse(["on o3 o4"]), objects) == [Action("o3", "center", "o4", "center")]
    # the long block lands 7.5 cm from the first support, towards the second
    assert build(parse(["bridge o4 o2 o5"]), objects) == [
        Action("o4", "center", "o2", "right")]
    assert build(parse(["bridge o4 o5 o2"]), objects) == [
        Action("o4", "center", "o5", "left")]
    assert build(parse(["row o0 o1 o3"]), objects) == [
        Action("o1", "center", "o0", "right"), Action("o3", "center", "o1", "right")]


def test_structures_build_on_what_the_ones_before_designed():
    objects = START.object_states()
    specs = parse(["row o0 o2", "tower o1 o0", "tower o3 o2", "bridge o4 o1 o3"])
    compiler.check(specs, objects)  # the supports stand 7.5 cm apart, tops level, by then
    assert compiler.build_actions(specs, objects) == [
        Action("o2", "center", "o0", "right"), Action("o1", "center", "o0", "center"),
        Action("o3", "center", "o2", "center"), Action("o4", "center", "o1", "right")]
    designed = compiler.designed(specs[3], compiler.designed(
        specs[2], compiler.designed(specs[1], compiler.designed(specs[0], objects))))
    end = {n: o.position for n, o in designed.items()}
    assert end["o2"] == pytest.approx([0.60, -0.175, 0.025])  # 7.5 cm along y from o0
    assert end["o1"] == pytest.approx([0.60, -0.25, 0.075])
    assert end["o4"] == pytest.approx([0.60, -0.175, 0.125])  # across both towers' tops
    assert unmet(specs, designed) == []
    with pytest.raises(SpecError, match="supports' tops are not level"):
        compiler.check(parse(["row o0 o2", "tower o1 o0", "bridge o4 o1 o2"]), objects)
    with pytest.raises(SpecError, match="o2 named twice"):  # moved by both
        compiler.check(parse(["row o0 o2", "on o2 o3"]), objects)


@pytest.mark.parametrize("start, spec, why", [
    (START, "tower o0 o1 o0", "o0 named twice"),
    (START, "bridge o0 o2 o5", "o0 is a cube; a bridge needs a long block"),
    (START, "tower o9 o1", "o9 not in the start scene"),
    (START, "fly o1 o2", "unknown word 'fly'"),
    (START, "on o1", "on takes 2 objects, got 1"),
    (START, "row o4 o0", "o4 is a long block"),
])
def test_a_spec_the_world_cannot_give_is_one_line_and_writes_nothing(tmp_path, capsys,
                                                                   start, spec, why):
    save_scene(start, tmp_path / "start.yaml")
    out = tmp_path / "goal.yaml"
    assert_bad_input(*run(["goal", "--start", tmp_path / "start.yaml", spec, "--out", out],
                          capsys), why)
    assert not out.exists()


def test_a_tower_above_the_arms_reach_is_refused_whatever_the_start():
    import numpy as np

    from drake_symplan.datasets import ObjectState

    cubes = {f"c{i}": ObjectState(f"c{i}", "cube", np.array([0.5 + 0.06 * i, 0.0, 0.025]))
             for i in range(9)}
    with pytest.raises(SpecError, match="45 cm tall; the arm stacks up to 40 cm"):
        compiler.check(parse([" ".join(["tower", *cubes])]), cubes)
    assert len(compiler.check(parse([" ".join(["tower", *list(cubes)[:8]])]), cubes)) == 7


def test_an_unnamed_box_on_a_named_one_is_set_down_first():
    rider = Scene([*START.objects[:5], ObjectSpec("o5", "cube", [0.60, 0.0, 0.075])])
    assert compiler.check(parse(["tower o2 o3"]), rider.object_states()) == [
        Action("o5", "center", "o2", "right"), Action("o2", "center", "o3", "center")]


def test_a_bridge_whose_supports_stand_apart_brings_one_beside_the_other():
    objects = START.object_states()  # o0 and o5 stand 40 cm apart along y
    actions = compiler.check(parse(["bridge o4 o0 o5"]), objects)
    assert actions == [Action("o5", "center", "o0", "right"), Action("o4", "center", "o0", "right")]
    built = objects
    for action in actions:
        built = compiler._placed(built, action, beside=action.source == "o5")
    assert unmet(parse(["bridge o4 o0 o5"]), built) == []


def test_a_row_with_no_room_after_its_first_box_is_built_out_from_another():
    edge = Scene([ObjectSpec("o0", "cube", [0.60, 0.36, 0.025]),
                  ObjectSpec("o1", "cube", [0.75, 0.0, 0.025]),
                  ObjectSpec("o2", "cube", [0.80, -0.20, 0.025])])
    objects = edge.object_states()  # o0 stands 4 cm from the table's +y edge
    actions = compiler.check(parse(["row o0 o1 o2"]), objects)
    assert actions == [Action("o2", "center", "o1", "right"), Action("o0", "center", "o1", "left")]
    built = objects
    for action in actions:
        built = compiler._placed(built, action, beside=True)
    assert unmet(parse(["row o0 o1 o2"]), built) == []


STACKED = Scene([*START.objects[:5], ObjectSpec("o5", "cube", [0.60, 0.0, 0.075])])  # on o2


def test_a_named_box_in_the_way_is_set_down_beside_the_nearest_free_box_first():
    objects = STACKED.object_states()
    specs = parse(["tower o2 o3", "on o5 o0"])
    compiler.check(specs, objects)
    # o5 rides on o2, which is to move: set down 7.5 cm along y from o2, then built as named
    assert compiler.build_actions(specs, objects) == [
        Action("o5", "center", "o2", "right"), Action("o2", "center", "o3", "center"),
        Action("o5", "center", "o0", "center")]
    parked = compiler._placed(objects, Action("o5", "center", "o2", "right"), beside=True)
    assert parked["o5"].position == pytest.approx([0.60, 0.075, 0.025])
    # a box that a structure built before stands on cannot be set down out of the way
    stacked = Scene([*START.objects[:1], ObjectSpec("o1", "cube", [0.60, -0.25, 0.075]),
                     *START.objects[2:]])  # o1 on o0
    with pytest.raises(SpecError, match="o2 rests on o0 or o4, which is built on before"):
        compiler.check(parse(["on o2 o1", "on o0 o4"]), stacked.object_states())


def test_a_goal_from_a_stacked_start_counts_the_boxes_set_down_in_its_k():
    import numpy as np

    objects, rng = STACKED.object_states(), np.random.default_rng(3)
    for k in (3, 4, 5):
        structures = sampling.sample_goal(rng, objects, "tower", (k,))
        assert not isinstance(structures, str), k
        assert len(compiler.build_actions(structures, objects)) == k
    assert len(compiler.build_actions(sampling.sample_goal(rng, objects, "tower", (4, 6)),
                                   objects)) in (4, 6)
    # six boxes, five of them movable at most once, one in the way: six actions at most
    assert isinstance(sampling.sample_goal(rng, objects, "tower", (7,)), str)


@pytest.mark.slow
@pytest.mark.parametrize("start, specs", [
    (START, ["tower o3 o1 o0", "bridge o4 o2 o5"]), (START, ["row o0 o1 o3"]),
    (STACKED, ["tower o2 o3", "on o5 o0"]),  # o5 set down first, then built on o0
])
def test_the_hand_builds_what_the_specs_name(tmp_path, capsys, start, specs):
    save_scene(start, tmp_path / "start.yaml")
    out = tmp_path / "goal.yaml"
    code, _, err = run(["goal", "--start", tmp_path / "start.yaml", *specs, "--out", out,
                        "--backend", "hand", "--json"], capsys)
    assert code == 0, err
    goal = load_scene(out)  # the written file, as a planner's goal would be read
    assert unmet(parse(specs), goal.object_states()) == []
    assert out.read_text().startswith(f"# goal: {'; '.join(specs)}\n")


def test_a_task_samples_a_structure_k_actions_away():
    import numpy as np

    objects, rng = START.object_states(), np.random.default_rng(0)
    (tower,) = sampling.sample_structures(rng, objects, "tower", 3)
    assert tower.word == "tower" and len(set(tower.objects)) == 4
    assert len(compiler.build_actions([tower], objects)) == 3
    two = sampling.sample_structures(rng, objects, "towers", 4)
    assert [s.word for s in two] == ["tower", "tower"] and min(len(s.objects) for s in two) >= 2
    assert len(compiler.build_actions(two, objects)) == 4
    (row,) = sampling.sample_structures(rng, objects, "row", 2)
    assert all(objects[n].type == "cube" for n in row.objects)
    assert sampling.sample_structures(rng, objects, "row", 5) == "too_few_objects"  # 5 cubes
    for task, k, words in (("bridge", 2, ["row", "bridge"]),
                           ("bridge", 5, ["row", "tower", "tower", "bridge", "on"]),
                           ("mixed", 3, ["tower", "row", "bridge"])):
        structures = sampling.sample_structures(rng, objects, task, k)
        assert [s.word for s in structures] == words, task
        compiler.check(structures, objects)
        assert len(compiler.build_actions(structures, objects)) == k, (task, k)
    assert sampling.sample_structures(rng, objects, "bridge", 6) == "too_few_objects"  # 6 cubes


@pytest.mark.slow
def test_problems_make_builds_a_tower_task(tmp_path, capsys):
    import json

    code, _, err = run(["problems", "make", "--out", tmp_path, "--objects", "3", "--k", "2",
                        "--count", "1", "--task", "tower", "--backend", "hand", "--json"],
                       capsys)
    assert code == 0, err
    problem = json.loads((tmp_path / "p000" / "problem.json").read_text())
    (spec,) = problem["spec"]
    assert spec.startswith("tower ") and len(problem["actions"]) == 2
    goal = load_scene(tmp_path / "p000" / "goal.yaml")
    assert unmet(parse([spec]), goal.object_states()) == []


@pytest.mark.slow
def test_problems_make_takes_apart_a_start_of_towers(tmp_path, capsys):
    import json

    code, _, err = run(["problems", "make", "--out", tmp_path, "--objects", "5", "--k", "4",
                        "5", "--count", "1", "--task", "towers", "--start-k", "2",
                        "--backend", "hand", "--json"], capsys)
    assert code == 0, err
    problem = json.loads((tmp_path / "p000" / "problem.json").read_text())
    start = load_scene(tmp_path / "p000" / "start.yaml")
    assert sum(o.position[2] > 0.05 for o in start.objects) == 2  # two towers of two
    # the build counts the box set down out of the way: four actions for three places
    assert problem["k"] == len(problem["actions"]) == 4
    assert sum(" place(" in a and ":right)" in a for a in problem["actions"]) == 1
    goal = load_scene(tmp_path / "p000" / "goal.yaml")
    assert unmet(parse(problem["spec"]), goal.object_states()) == []


@pytest.mark.parametrize("command, start", [("solve", "--start"), ("inspect", "--scene")])
def test_solve_and_inspect_take_a_goal_spec_checked_like_goals(tmp_path, capsys, command,
                                                               start):
    save_scene(START, tmp_path / "start.yaml")
    assert_bad_input(*run([command, start, tmp_path / "start.yaml", "--goal-spec",
                           "tower o2 o2"], capsys), "o2 named twice")
    assert_bad_input(*run([command, start, tmp_path / "start.yaml", "--goal",
                           tmp_path / "start.yaml", "--goal-spec", "on o1 o2"], capsys),
                     "not allowed with argument")


def test_inspect_stages_need_a_goal_spec(tmp_path, capsys):
    save_scene(START, tmp_path / "start.yaml")
    assert_bad_input(*run(["inspect", "--scene", tmp_path / "start.yaml", "--goal",
                           tmp_path / "start.yaml", "--stages"], capsys),
                     "--stages needs --goal-spec")


@pytest.mark.slow
def test_inspect_builds_the_written_goal_and_plans_to_it(tmp_path, capsys):
    import json

    save_scene(START, tmp_path / "start.yaml")
    code, out, err = run(["inspect", "--scene", tmp_path / "start.yaml", "--goal-spec",
                          "on o3 o2", "--stages", "--json"], capsys)
    result = json.loads(out)
    assert code == 0 and result["goal_spec"] == ["on o3 o2"], err
    assert result["plan_status"] == "solved" and len(result["plan"]) >= 1
    # one relation, one stage, planned on the symbols alone (o3 starts off o2)
    (stage,) = result["stages"]
    assert stage["relations"] == ["on o3 o2"] and stage["status"] == "solved"
    assert stage["steps"] and stage["nearest"] == []


@pytest.mark.slow
def test_solve_builds_the_written_goal_then_solves_it(tmp_path, capsys):
    import json

    save_scene(START, tmp_path / "start.yaml")
    code, out, err = run(["solve", "--start", tmp_path / "start.yaml", "--goal-spec",
                          "on o3 o2", "--backend", "hand", "--json"], capsys)
    result = json.loads(out)
    assert result["goal_spec"] == ["on o3 o2"]
    assert code == 0 and result["status"] == "success", err


def test_the_demo_takes_a_goal_spec_checked_before_anything_runs(tmp_path, capsys):
    out = tmp_path / "demo.html"
    assert_bad_input(*run(["demo", "--goal-spec", "tower o0 o0", "--out", out], capsys),
                     "o0 named twice")
    assert_bad_input(*run(["demo", "--goal-spec", "tower o0 o5", "--objects", "3", "--out",
                           out], capsys), "o5 not in the start scene")
    assert not out.exists()


def test_every_written_goal_compiles_on_a_start_that_has_its_boxes():
    """Sixty random starts of 6-8 boxes, each kind of written goal sampled on each: the
    compiler refuses none that has the boxes (a row of four on the most crowded table at
    most once)."""
    from collections import Counter

    import numpy as np

    from drake_symplan.world.scenes import sample_scene

    counts = Counter()
    for seed in range(60):
        rng = np.random.default_rng(seed)
        objects = sample_scene(rng, 6 + seed % 3, long_fraction=0.4).object_states()
        for task in sampling.WRITTEN:
            structures = sampling.sample_structures(rng, objects, task, 1)
            if isinstance(structures, str):
                continue
            try:
                compiler.check(structures, objects)
                counts[task, "built"] += 1
            except SpecError:
                counts[task, "refused"] += 1
    assert all(counts[task, "refused"] == 0 for task in sampling.WRITTEN if task != "row4")
    assert counts["row4", "refused"] <= 1
    assert min(counts[task, "built"] for task in sampling.WRITTEN) >= 30


def test_requests_no_start_could_meet_are_refused_at_once(tmp_path, capsys):
    save_scene(START, tmp_path / "start.yaml")
    many = "tower " + " ".join(f"o{i}" for i in range(15000))
    assert_bad_input(*run(["goal", "--start", tmp_path / "start.yaml", many, "--out",
                           tmp_path / "g.yaml"], capsys), "and 14989 more not in the start")
    out = tmp_path / "problems"
    assert_bad_input(*run(["problems", "make", "--out", out, "--objects", "4", "--k", "2",
                           "--count", "1", "--start-k", "2"], capsys), "--start-k needs --task")
    assert_bad_input(*run(["problems", "make", "--out", out, "--objects", "4", "--k", "99",
                           "--count", "1", "--task", "tower"], capsys),
                     "--k 99: a structure of 4 boxes takes at most 8 actions")
    assert not out.exists() and not (tmp_path / "g.yaml").exists()
