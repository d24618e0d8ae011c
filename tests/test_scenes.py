"""Scene files: round trip, rejection of malformed or impossible scenes, the sampler."""

import numpy as np
import pytest

from drake_symplan.world.scenes import (
    ObjectSpec,
    Scene,
    SceneError,
    as_saved,
    load_scene,
    sample_cubes_scene,
    sample_scene,
    sample_towers_scene,
    save_scene,
    validate_scene,
)


def test_round_trip(tmp_path):
    scene = Scene([ObjectSpec("o0", "cube", [0.7, 0.0, 0.025], 0.0),
                   ObjectSpec("o1", "long", [0.6, 0.25, 0.025], 0.1)])
    save_scene(scene, tmp_path / "s.yaml")
    loaded = load_scene(tmp_path / "s.yaml")
    assert loaded.names == ["o0", "o1"]
    assert loaded.objects[1].type == "long"
    assert np.allclose(loaded.objects[1].position, [0.6, 0.25, 0.025])
    assert loaded.objects[1].yaw == pytest.approx(0.1)


def test_reads_the_documented_format(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("objects:\n"
                    "  - {name: o0, type: cube, position: [0.70, 0.00, 0.025], yaw: 0.0}\n"
                    "  - {name: o1, type: long, position: [0.60, 0.25, 0.025], yaw: 0.0}\n")
    assert load_scene(path).names == ["o0", "o1"]


@pytest.mark.parametrize("objects, message", [
    ([("a", "sphere", [0.7, 0, 0.025])], "unknown type 'sphere'"),
    ([("a", "cube", [0.7, 0, 0.025]), ("b", "cube", [0.72, 0, 0.025])], "overlap"),
    ([("a", "cube", [1.3, 0, 0.025])], "outside the workspace"),
    ([("a", "cube", [0.7, 0, 0.2])], "rests on neither"),
    ([("a", "cube", [0.7, 0, 0.025]), ("a", "cube", [0.5, 0, 0.025])], "unique"),
])
def test_rejects_impossible_scenes(objects, message):
    scene = Scene([ObjectSpec(n, t, p, 0.0) for n, t, p in objects])
    with pytest.raises(SceneError, match=message):
        validate_scene(scene)


def test_stacks_are_valid():
    validate_scene(Scene([ObjectSpec("a", "long", [0.7, 0, 0.025]),
                          ObjectSpec("b", "cube", [0.7, 0.1, 0.075]),
                          ObjectSpec("c", "cube", [0.7, 0.1, 0.125])]))


def test_malformed_file(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("objects:\n  - {name: o0, type: cube}\n")
    with pytest.raises(SceneError, match="malformed"):
        load_scene(path)
    with pytest.raises(FileNotFoundError):
        load_scene(tmp_path / "missing.yaml")


def test_sampler_is_seeded_and_valid():
    for n in range(2, 9):
        a = sample_scene(np.random.default_rng(n), n)
        b = sample_scene(np.random.default_rng(n), n)
        assert len(a.objects) == n
        assert [o.position for o in a.objects] == [o.position for o in b.objects]
        validate_scene(a)


def test_a_sampled_scene_holds_no_more_boxes_of_a_type_than_the_station_has():
    # sixteen boxes, nearly all long: the station has eight long blocks, the rest are cubes
    scene = sample_scene(np.random.default_rng(3), 16, long_fraction=0.95)
    types = [o.type for o in scene.objects]
    assert (types.count("long"), types.count("cube")) == (8, 8)


def test_a_towers_start_has_two_towers_side_by_side_a_bridge_apart_and_a_long_block():
    from drake_symplan.boxes import VICINITY

    scene = sample_towers_scene(np.random.default_rng(4), 6)
    validate_scene(scene)
    a, a_top, b, b_top = scene.objects[:4]
    assert [a.position[2], a_top.position[2]] == [0.025, 0.075]
    assert a.position[:2] == a_top.position[:2] and b.position[:2] == b_top.position[:2]
    assert b.position[0] == a.position[0]
    gap = b.position[1] - a.position[1] - 0.05  # between the towers' faces along y
    assert gap == pytest.approx(0.025) and gap < VICINITY
    assert len(scene.objects) == 6 and scene.objects[4].type == "long"
    assert all(o.position[2] == 0.025 for o in scene.objects[4:])  # the rest on the table
    with pytest.raises(SceneError, match="5 or more"):
        sample_towers_scene(np.random.default_rng(4), 4)


def test_a_cubes_start_has_two_cubes_a_bridge_apart_on_the_table_and_a_long_block():
    scene = sample_cubes_scene(np.random.default_rng(5), 4)
    validate_scene(scene)
    a, b, block = scene.objects[:3]
    assert a.position[2] == b.position[2] == 0.025 and a.position[0] == b.position[0]
    assert b.position[1] - a.position[1] - 0.05 == pytest.approx(0.025)
    assert block.type == "long" and len(scene.objects) == 4
    with pytest.raises(SceneError, match="3 or more"):
        sample_cubes_scene(np.random.default_rng(5), 2)


def test_a_scene_is_checked_as_its_file_reads_back(tmp_path):
    scene = Scene([ObjectSpec("a", "cube", [0.612345678, -0.1, 0.025], 0.123456789)])
    saved = as_saved(scene)  # numbers rounded as written, then validated
    assert saved.objects[0].position == [0.6123, -0.1, 0.025]
    assert saved.objects[0].yaw == 0.1235
    save_scene(scene, tmp_path / "s.yaml")
    assert load_scene(tmp_path / "s.yaml") == saved


# --- values YAML and Python accept and the world does not: one line naming file and field

SCENE = ("objects:\n  - {{name: o0, type: cube, position: {position}, yaw: {yaw}}}\n"
         "  - {{name: o1, type: cube, position: [0.6, 0.2, 0.025], yaw: 0}}\n")
BIG = "9" * 400


@pytest.mark.parametrize("position, yaw, problem", [
    ("[0.7, 0.0, 0.025]", ".nan", "objects[0] (o0): yaw must be a finite number, got nan"),
    ("[0.7, 0.0, 0.025]", ".inf", "objects[0] (o0): yaw must be a finite number, got inf"),
    ("[0.7, 0.0, 0.025]", BIG, f"objects[0] (o0): yaw must be a finite number, got {BIG[:40]}..."),
    ("[true, false, 0.025]", "0", "objects[0] (o0): position[0] must be a finite number, got true"),
    (f"[{BIG}, 0, 0.025]", "0",
     f"objects[0] (o0): position[0] must be a finite number, got {BIG[:40]}..."),
    ("[.nan, 0, 0.025]", "0", "objects[0] (o0): position[0] must be a finite number, got nan"),
    ("[0.7, 0.0]", "0", "objects[0] (o0): position must be a list of 3 numbers, got [0.7, 0.0]"),
    ("[0.7, zero, 0.025]", "0",
     "objects[0] (o0): position[1] must be a finite number, got 'zero'"),
])
def test_numbers_the_world_does_not_take_are_one_line_naming_the_field(
        position, yaw, problem, tmp_path, capsys):
    from conftest import assert_bad_input, run

    path = tmp_path / "s.yaml"
    path.write_text(SCENE.format(position=position, yaw=yaw))
    code, out, err = run(["perceive", "--scene", path], capsys)
    assert_bad_input(code, out, err)
    assert err == f"symplan perceive: error: malformed scene file {path}: {problem}\n"


@pytest.mark.parametrize("content, problem", [
    (b"objects:\n  - {name: \xe9t\xe9, position: [0.7, 0, 0.025]}\n",
     "scene file {path}: not UTF-8 text (byte 20)"),
    (("objects: " + "[" * 5000 + "]" * 5000 + "\n").encode(),
     "{path}: invalid YAML (nested too deeply)"),
    (f"objects: [{'9' * 5000}]\n".encode(),
     "{path}: invalid YAML (Exceeds the limit (4300 digits) for integer string conversion: "
     "value has 5000 digits)"),
])
def test_a_file_python_cannot_read_is_one_line_naming_it(content, problem, tmp_path, capsys):
    from conftest import assert_bad_input, run

    path = tmp_path / "s.yaml"
    path.write_bytes(content)
    code, out, err = run(["perceive", "--scene", path], capsys)
    assert_bad_input(code, out, err)
    assert err == f"symplan perceive: error: {problem.format(path=path)}\n"


def test_a_yaw_that_is_not_finite_is_refused_in_a_scene_built_in_code():
    with pytest.raises(SceneError, match="^object 'a' yaw must be a finite number, got nan$"):
        validate_scene(Scene([ObjectSpec("a", "cube", [0.7, 0, 0.025], float("nan"))]))


def test_numbers_written_as_yaml_1_1_text_still_read(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(SCENE.format(position="[7e-1, 0, 25e-3]", yaw="0"))
    assert load_scene(path).objects[0].position == [0.7, 0.0, 0.025]
