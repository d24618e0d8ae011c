"""Frames on disk (perception/frames.py): `symplan frames record` writes a scene's depth
frames, `symplan perceive --frames` perceives them as the simulator's cameras would, and
`symplan solve --start-frames/--goal-frames` solves from them; a folder that cannot be read
is one line and exit status 2."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import assert_bad_input, run
from PIL import Image

from drake_symplan.world.scenes import ObjectSpec, Scene, save_scene

# A tower of two, a block and a cube: contacts, both types and some occlusion.
SCENE = Scene([ObjectSpec("a", "cube", [0.70, 0.10, 0.025]),
               ObjectSpec("b", "cube", [0.70, 0.10, 0.075]),
               ObjectSpec("c", "long", [0.80, -0.12, 0.025], 0.4),
               ObjectSpec("d", "cube", [0.55, -0.15, 0.025], -0.3)])
SEED = 3
DEMO = Path(__file__).resolve().parents[1] / "models" / "demo"


def in_memory_views(noise: str):
    """The frames `symplan frames record --seed SEED` records of SCENE, kept in memory."""
    from drake_symplan.perception.depth_filter import DepthFilter
    from drake_symplan.perception.perceive import station_views
    from drake_symplan.world.cameras import default_cameras
    from drake_symplan.world.station import Station, StationConfig

    station = Station(StationConfig(cameras=default_cameras(), camera_noise=noise,
                                    camera_seed=SEED))
    station.reset(SCENE)
    station.settle(0.5)
    return station_views(station, DepthFilter().frames)


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene.yaml"
    save_scene(SCENE, path)
    return path


@pytest.fixture(scope="module")
def clean_folder(tmp_path_factory, scene_file):
    """A folder `symplan frames record` wrote of SCENE (a perfect sensor)."""
    from drake_symplan.cli import main as cli_main

    out = tmp_path_factory.mktemp("frames") / "clean"
    assert cli_main.main(["frames", "record", "--scene", str(scene_file), "--out", str(out),
                          "--seed", str(SEED)]) == 0
    return out


def round_trip(folder, noise, capsys) -> float:
    """Perceives the recorded `folder` from disk, in process and by `symplan perceive
    --frames`, against the in-memory perception of the same frames; the largest position
    error (m)."""
    from drake_symplan.perception.frames import DEPTH_SCALE, read_frames, to_units
    from drake_symplan.perception.perceive import Perceiver

    memory = in_memory_views(noise)
    disk = read_frames(folder)
    for cam, mine, theirs in zip(memory.cameras, memory.frames, disk.frames, strict=True):
        # What was recorded is these frames, to the millimetre.
        assert np.array_equal(to_units(theirs, DEPTH_SCALE), to_units(mine, DEPTH_SCALE))
        assert np.allclose(disk.cameras[memory.cameras.index(cam)].X_WB.GetAsMatrix4(),
                           cam.X_WB.GetAsMatrix4(), rtol=0, atol=1e-12)
    assert disk.sensor == memory.sensor and len(disk.robot_shapes) == len(memory.robot_shapes)
    want = Perceiver().perceive_views(memory)
    got = Perceiver().perceive_views(disk)
    assert [(o.name, o.type) for o in got.objects] == [(o.name, o.type) for o in want.objects]
    assert got.contacts == want.contacts
    assert len(want.objects) == len(SCENE.objects)
    error = max(np.linalg.norm(g.position - w.position)
                for g, w in zip(got.objects, want.objects, strict=True))
    assert error <= 0.001, error
    code, out, err = run(["perceive", "--frames", folder, "--json"], capsys)
    assert code == 0, err
    printed = json.loads(out)
    assert [(o["name"], o["type"]) for o in printed["objects"]] == \
        [(o.name, o.type) for o in want.objects]
    assert printed["contacts"] == sorted([list(c) for c in want.contacts])
    for o, w in zip(printed["objects"], want.objects, strict=True):
        assert np.linalg.norm(np.array(o["position"]) - w.position) <= 0.001
    return error


def test_a_perfect_sensor_s_frames_perceived_from_disk_as_in_memory(clean_folder, capsys):
    cameras = ["far", "left", "right"]
    assert sorted(p.name for p in clean_folder.iterdir()) == sorted(
        [f"{c}.png" for c in cameras] + [f"{c}.yaml" for c in cameras] + ["robot.yaml"])
    with Image.open(clean_folder / "far.png") as image:
        assert (image.format, image.mode, image.size) == ("PNG", "I;16", (640, 480))
    error = round_trip(clean_folder, "none", capsys)
    print(f"round trip, no noise: {error * 1000:.3f} mm")


def test_realsense_frames_perceived_from_disk_as_in_memory(tmp_path, scene_file, capsys):
    out = tmp_path / "realsense"
    code, _, err = run(["frames", "record", "--scene", scene_file, "--out", out,
                        "--camera-noise", "realsense", "--seed", SEED], capsys)
    assert code == 0, err
    assert yaml.safe_load((out / "far.yaml").read_text())["depth"] == \
        [f"far_{i}.png" for i in range(5)]  # the depth filter's five frames
    error = round_trip(out, "realsense", capsys)
    print(f"round trip, realsense: {error * 1000:.3f} mm")


@pytest.fixture
def spoilt(clean_folder, tmp_path):
    """A copy of the clean folder to spoil."""
    return shutil.copytree(clean_folder, tmp_path / "frames")


def edit_camera(folder, name, **fields):
    path = folder / f"{name}.yaml"
    data = yaml.safe_load(path.read_text())
    path.write_text(yaml.safe_dump({**data, **fields}))


def not_a_rotation(folder):
    X = np.array(yaml.safe_load((folder / "far.yaml").read_text())["X_WC"])
    X[:3, :3] *= 1.1
    edit_camera(folder, "far", X_WC=X.tolist())


def looking_from_above_the_ceiling(folder):
    X = np.array(yaml.safe_load((folder / "left.yaml").read_text())["X_WC"])
    X[2, 3] += 3.0  # the same view 3 m higher: the table is not where the depth says
    edit_camera(folder, "left", X_WC=X.tolist())


SPOILERS = {
    "missing camera file": (lambda f: (f / "left.yaml").unlink(),
                            "left.png: no camera file names this depth image"),
    "PNG of the wrong size": (
        lambda f: Image.fromarray(np.full((240, 320), 900, np.uint16)).save(f / "far.png"),
        "far.png: 320 x 240 pixels, its camera file says 640 x 480"),
    "PNG of 8 bits": (
        lambda f: Image.fromarray(np.full((480, 640), 90, np.uint8)).save(f / "right.png"),
        "right.png: a PNG of mode L, not a 16-bit grayscale PNG"),
    "pose not a rotation": (not_a_rotation, "far.yaml: X_WC is not a pose"),
    "no table in view": (looking_from_above_the_ceiling, "left.png: no table in view"),
    "missing PNG": (lambda f: (f / "far.png").unlink(), "far.png: missing"),
}


@pytest.mark.parametrize("spoil", SPOILERS)
def test_bad_frames_are_one_line_naming_the_file(spoil, spoilt, capsys):
    make, message = SPOILERS[spoil]
    make(spoilt)
    before = sorted(p.name for p in spoilt.iterdir())
    code, out, err = run(["perceive", "--frames", spoilt, "--json"], capsys)
    assert_bad_input(code, out, err, "symplan perceive: error: ", str(spoilt / message))
    assert sorted(p.name for p in spoilt.iterdir()) == before


def test_recording_into_a_folder_in_use_writes_nothing(clean_folder, scene_file, tmp_path,
                                                       capsys):
    out = tmp_path / "used"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    code, stdout, err = run(["frames", "record", "--scene", scene_file, "--out", out], capsys)
    assert_bad_input(code, stdout, err, f"--out {out} is not empty")
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["used"]


@pytest.mark.parametrize("option", ["--start-frames", "--goal-frames"])
def test_solve_from_bad_frames_is_one_line_and_writes_nothing(option, spoilt, tmp_path,
                                                               capsys):
    make, message = SPOILERS["PNG of the wrong size"]
    make(spoilt)
    record = tmp_path / "solve.html"
    goal = [] if option == "--goal-frames" else ["--goal", DEMO / "goal.yaml"]
    code, out, err = run(["solve", "--start", DEMO / "start.yaml", *goal, option, spoilt,
                          "--backend", "hand", "--record", record, "--json"], capsys)
    assert_bad_input(code, out, err, "symplan solve: error: ", str(spoilt / message))
    assert not record.exists()
    code, out, err = run(["solve", "--start", DEMO / "start.yaml", "--goal", DEMO / "goal.yaml",
                          "--goal-frames", spoilt], capsys)
    assert_bad_input(code, out, err, "argument --goal-frames: not allowed with argument --goal")


@pytest.mark.slow
def test_solve_reaches_a_goal_seen_only_in_frames(tmp_path, capsys):
    """The demo's goal recorded as frames, and its start too: the hand solves from them,
    with no goal scene file (the goal's boxes take the start's names by type)."""
    folders = {}
    for scene in ("start", "goal"):
        folders[scene] = tmp_path / scene
        code, _, err = run(["frames", "record", "--scene", DEMO / f"{scene}.yaml", "--out",
                            folders[scene], "--json"], capsys)
        assert code == 0, err
    code, out, err = run(["solve", "--start", DEMO / "start.yaml", "--start-frames",
                          folders["start"], "--goal-frames", folders["goal"], "--backend",
                          "hand", "--json"], capsys)
    result = json.loads(out)
    assert code == 0 and result["status"] == "success", (err, result)
    assert result["start_frames"] == str(folders["start"])
    assert result["goal_frames"] == str(folders["goal"])
    # The goal as the simulator built it, by type: every box of the file's goal has a box
    # of its type within 5 cm of it at the end, as the simulator has them.
    types = {o["name"]: o["type"]
             for o in yaml.safe_load((DEMO / "start.yaml").read_text())["objects"]}
    at_end = [(types[name], np.array(o["final_true"])) for name, o in result["objects"].items()]
    for o in yaml.safe_load((DEMO / "goal.yaml").read_text())["objects"]:
        assert min(np.linalg.norm(p - o["position"]) for kind, p in at_end
                   if kind == o["type"]) < 0.05, (o, result["objects"])
