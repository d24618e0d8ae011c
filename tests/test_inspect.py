"""`symplan inspect` (agent/inspection.py, cli/inspect_cmds.py): the symbol view, plan
steps and the page's panel on hand-made readings; bad input; and, slow, a real inspection
with a model bundle whose recording holds the drawn objects."""

from __future__ import annotations

import json
import types
from pathlib import Path

import numpy as np
import pytest
from conftest import bundle_for_tests, recorded_paths, run

from drake_symplan.abstraction.abstraction import Reading
from drake_symplan.actions import Action
from drake_symplan.agent.inspection import (
    PALETTE,
    UNCERTAIN,
    annotate_html,
    colour,
    inspection_sections,
    panel_html,
    pattern,
    plan_view,
    readable_step,
    symbol_view,
)
from drake_symplan.symbolic.states import SymbolicState
from drake_symplan.symbolic.structs import Atom, LiftedOperator, Reposition, parse_step
from drake_symplan.world.scenes import ObjectSpec, Scene, save_scene

REPO = Path(__file__).resolve().parents[1]


def scene_and_reading():
    """a on b (in contact), c apart; p0 = (1, 0, uncertain), p1 = (0, 0, 1); r0(a, b) set
    and certain, r1(a, b) set but uncertain, r0(a, c) set but not in contact."""
    objects = [types.SimpleNamespace(name=n, type=t, position=np.array(p))
               for n, t, p in (("a", "cube", [0.7, 0, 0.075]), ("b", "cube", [0.7, 0, 0.025]),
                               ("c", "long", [0.6, 0.2, 0.025]))]
    unary = np.array([[1, 0], [0, 0], [0, 1]], bool)
    unary_unc = np.array([[0, 0], [0, 0], [1, 0]], bool)
    rel = np.zeros((2, 3, 3), bool)
    rel[0, 0, 1] = rel[1, 0, 1] = rel[0, 0, 2] = True
    rel_unc = np.zeros((2, 3, 3), bool)
    rel_unc[1, 0, 1] = True
    reading = Reading(SymbolicState(("a", "b", "c"), unary, rel), unary_unc, rel_unc,
                      {("a", "b")})
    return types.SimpleNamespace(objects=objects), reading


def test_readable_steps():
    ops = {op.name: op for op in (
        LiftedOperator(2, "center", "left", 2, (), (("p0", 0),), (), 86),
        LiftedOperator(0, "left", "center", 3, (), (("p0", 0),), (), 5))}
    assert readable_step(parse_step("(pick_center_place_left_n86_op2 o3 o1)", ops)) == \
        "pick o3 at its centre, release on o1's left"
    assert readable_step(parse_step("(PICK_LEFT_PLACE_CENTER_N5_OP0 o0 o2 o1)", ops)) == \
        "pick o0 at its left end, release on o2's centre"
    assert readable_step(Reposition(Action("o1", "center", "o0", "right"))) == \
        "pick o1 at its centre, release on o0's right (repositioning)"


def test_patterns_and_colours():
    assert pattern([1, 0, 1], [0, 0, 0]) == "101" and pattern([1, 0], [0, 1]) == "1?"
    assert colour("0") == PALETTE[0] and colour("1") == PALETTE[1]
    assert colour("01") == PALETTE[2]  # p1 set: bit 1 of the index
    assert colour("1?") == UNCERTAIN


def test_symbol_view_draws_certain_set_relations_between_contacts_only():
    scene, reading = scene_and_reading()
    view = symbol_view(scene, reading)
    by_name = {o["name"]: o for o in view["objects"]}
    assert by_name["a"]["pattern"] == "10" and by_name["a"]["unary"] == {"p0": 1, "p1": 0}
    assert by_name["c"]["pattern"] == "?1" and by_name["c"]["colour"] == UNCERTAIN
    assert by_name["c"]["unary"]["p0"] is None
    assert [(r["relation"], r["x"], r["y"]) for r in view["relations"]] == [("r0", "a", "b")]
    assert view["legend"]["unary"] == {"10": PALETTE[1], "00": PALETTE[0], "?1": UNCERTAIN}
    assert list(view["legend"]["relations"]) == ["r0", "r1"]
    assert view["contacts"] == [["a", "b"]]


def test_plan_steps_are_grounded_and_the_panel_holds_them():
    op = LiftedOperator(3, "center", "left", 2, (("p0", 1),), (("r0", 0, 1),),
                        (("touching0", 0),), 40, applicable=50, succeeded=40)
    steps = plan_view([parse_step(f"({op.name} a b)", {op.name: op})])
    assert steps == [{"step": f"({op.name} a b)",
                      "readable": "pick a at its centre, release on b's left",
                      "source": "a", "target": "b", "operator": op.name, "reliability": 0.8, "preconditions": ["p0(b)"],
                      "add": ["r0(a, b)"], "delete": ["touching0(a)"]}]
    # with the plan's initial atoms and the bundle's operators: the action's other branch
    missed = LiftedOperator(4, "center", "left", 2, (("p0", 1),), (("touching1", 0),),
                            (("touching0", 0),), 10, applicable=50, succeeded=10)
    steps = plan_view([parse_step(f"({op.name} a b)", {op.name: op})],
                      {Atom("p0", "b")}, [op, missed])
    assert steps[0]["other_outcomes"] == [{"operator": missed.name, "reliability": 0.2,
                                           "add": ["touching1(a)"], "delete": ["touching0(a)"]}]
    scene, reading = scene_and_reading()
    view = symbol_view(scene, reading)
    result = {"start": view, "goal": {**view, "atoms": ["r0(a, b)"]}, "plan": steps,
              "plan_status": "solved"}
    page = annotate_html("<html><body><div id='x'></div></body></html>",
                         panel_html("title <1>", inspection_sections(result)))
    assert page.index('id="symplan-panel"') < page.index("</body>")
    assert "title &lt;1&gt;" in page and "p0=1 p1=0" in page
    assert "or: 20% add touching1(a); del touching0(a)" in page
    assert "pick a at its centre, release on b&#x27;s left" in page
    assert "pre: p0(b)" in page and "add: r0(a, b)" in page and "del: touching0(a)" in page


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    start = tmp_path / "start.yaml"
    save_scene(Scene([ObjectSpec("a", "cube", [0.6, 0.0, 0.025]),
                      ObjectSpec("b", "cube", [0.8, 0.1, 0.025])]), start)
    goal = tmp_path / "goal.yaml"
    save_scene(Scene([ObjectSpec("a", "cube", [0.6, 0.0, 0.025])]), goal)
    for argv, text in (
            (["inspect", "--scene", tmp_path / "none.yaml"], "none.yaml"),
            (["inspect", "--scene", start, "--goal", goal], "the goal lacks start objects"),
            (["inspect", "--scene", start, "--model", tmp_path / "nope"], "no model directory"),
            (["explain", "--model", tmp_path, "--data", tmp_path / "nodata"], "nodata"),
    ):
        code, out, err = run(argv, capsys)
        assert code == 2 and out == "" and err.count("\n") == 1, (argv, code, out, err)
        assert text in err, err


@pytest.mark.slow
def test_inspection_recording_holds_the_drawn_objects(tmp_path, capsys):
    model = bundle_for_tests()
    start, goal = tmp_path / "start.yaml", tmp_path / "goal.yaml"
    save_scene(Scene([ObjectSpec("o0", "cube", [0.70, -0.15, 0.025]),
                      ObjectSpec("o1", "cube", [0.70, -0.15, 0.075]),
                      ObjectSpec("o2", "cube", [0.85, 0.10, 0.025])]), start)
    save_scene(Scene([ObjectSpec("o0", "cube", [0.70, -0.15, 0.025]),
                      ObjectSpec("o1", "cube", [0.85, 0.10, 0.075]),
                      ObjectSpec("o2", "cube", [0.85, 0.10, 0.025])]), goal)
    record = tmp_path / "inspect.html"
    code, out, err = run(["inspect", "--scene", start, "--goal", goal, "--model", model,
                          "--record", record, "--json"], capsys)
    assert code in (0, 1), err
    result = json.loads(out)
    assert sorted(o["name"] for o in result["start"]["objects"]) == ["o0", "o1", "o2"]
    assert result["start"]["contacts"] == [["o0", "o1"]]
    assert result["goal"]["contacts"] == [["o1", "o2"]]
    assert result["recording"] == str(record)
    page = record.read_text()
    paths = recorded_paths(page)
    for layer in ("start", "goal"):
        for name in ("o0", "o1", "o2"):
            assert f"/symplan/{layer}/boxes/{name}" in paths, sorted(paths)
    for r in result["start"]["relations"]:
        assert f"/symplan/start/relations/{r['relation']}/{r['x']}_{r['y']}/head" in paths
    for i, _ in enumerate(result["plan"]):
        assert f"/symplan/plan/step{i}/head" in paths
    assert 'id="symplan-panel"' in page and "Start (perceived)" in page
    if result["plan_status"] == "solved":
        assert code == 0 and result["plan"]
        assert result["plan"][0]["readable"] in page.replace("&#x27;", "'")


def test_the_docs_screenshot_is_a_1200_by_800_png_of_scenes_in_docs():
    import struct

    head = (REPO / "docs" / "inspect.png").read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and struct.unpack(">II", head[16:24]) == (1200, 800)
    from drake_symplan.agent.beliefs import check_scene_pair
    from drake_symplan.world.scenes import load_scene

    scenes = REPO / "docs" / "inspect_scenes"
    check_scene_pair(load_scene(scenes / "start.yaml"), load_scene(scenes / "goal.yaml"))


def test_inspect_draws_each_cameras_noisy_cloud(tmp_path, capsys):
    start = tmp_path / "start.yaml"
    save_scene(Scene([ObjectSpec("o0", "cube", [0.70, -0.15, 0.025])]), start)
    record = tmp_path / "inspect.html"
    argv = ["inspect", "--scene", start, "--model", bundle_for_tests(), "--record", record,
            "--clouds", "--json"]
    code, out, err = run([*argv, "--camera-noise", "realsense"], capsys)
    assert code == 0, err
    noisy = json.loads(out)["start"]["cloud_points"]
    paths = recorded_paths(record.read_text())
    assert len(noisy) == 3 and min(noisy) > 1000  # three cameras see the table's cube
    for i in range(3):
        assert f"/symplan/start/clouds/camera{i}" in paths, sorted(paths)
    code, out, err = run([*argv, "--camera-noise", "none"], capsys)
    exact = json.loads(out)["start"]["cloud_points"]
    assert noisy != exact  # holes and flying pixels change what each camera returns
