"""--camera-noise on every command that perceives: a bad value is bad input, the setting
reaches the robot's station, and the data set, problem set and evaluation records say which
sensor model made them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import assert_bad_input, collect_args, run

DEMO = Path(__file__).resolve().parents[1] / "models" / "demo"
SHIPPED = Path(__file__).resolve().parents[1] / "models" / "learned"


def perceiving_commands(tmp_path, record: bool = True) -> dict[str, list]:
    """Each command that perceives, with the output it would write under `tmp_path`;
    `record`: solve, inspect and demo write a Meshcat recording (and start Meshcat)."""
    scenes = ["--start", DEMO / "start.yaml", "--goal", DEMO / "goal.yaml"]
    recorded = (lambda name: ["--record", tmp_path / name]) if record else (lambda name: [])
    return {
        "collect": collect_args(0, 4, tmp_path / "data", 4),
        "solve": ["solve", *scenes, "--backend", "hand", *recorded("solve.html")],
        "problems make": ["problems", "make", "--out", tmp_path / "set", "--objects", "2",
                          "--k", "1", "--count", "1", "--backend", "hand"],
        "eval planning": ["eval", "planning", "--runs", SHIPPED, "--problems", DEMO,
                          "--backend", "hand", "--records", tmp_path / "records.jsonl"],
        "inspect": ["inspect", "--scene", DEMO / "start.yaml", *recorded("inspect.html")],
        "demo": ["demo", *scenes, "--out", tmp_path / "demo.html",
                 *([] if record else ["--no-record"])],
    }


@pytest.mark.parametrize("command", ["collect", "solve", "problems make", "eval planning",
                                     "inspect", "demo"])
def test_a_bad_camera_noise_is_one_line_and_writes_nothing(command, tmp_path, capsys):
    argv = perceiving_commands(tmp_path)[command]
    code, out, err = run([*argv, "--camera-noise", "loud"], capsys)
    assert_bad_input(code, out, err, f"symplan {command}: error: argument --camera-noise: "
                     "invalid choice: 'loud' (choose from 'none', 'realsense', 'heavy')")
    assert list(tmp_path.iterdir()) == []


class Built(Exception):
    """Raised by the spy in place of building a station: the test has what it asked."""


@pytest.mark.parametrize("command", ["solve", "problems make", "eval planning", "inspect",
                                     "demo"])
@pytest.mark.parametrize("noise", ["none", "heavy"])
def test_the_agent_s_station_gets_the_sensor_model(command, noise, tmp_path, capsys,
                                                   monkeypatch):
    from drake_symplan.agent import solve

    built = []

    def spy(robot, **kwargs):
        built.append(kwargs["camera_noise"])
        raise Built("station not built in this test")

    monkeypatch.setattr(solve, "make_backend", spy)
    argv = perceiving_commands(tmp_path, record=False)[command]
    if noise != "none":
        argv = [*argv, "--camera-noise", noise]
    with pytest.raises(Built):
        run(argv, capsys)
    assert built == [noise]


@pytest.mark.slow
def test_collect_records_the_sensor_model_and_runs_with_it(tmp_path, capsys, monkeypatch):
    from drake_symplan.data import collect as collect_module
    from drake_symplan.data.storage import load_transitions, read_manifest
    from drake_symplan.world.depth_sensor import CAMERA_NOISE

    sensors = []
    make_backend = collect_module.make_backend

    def spy(name, **kwargs):
        backend = make_backend(name, **kwargs)
        sensors.append((name, backend.station.sensor))
        return backend

    monkeypatch.setattr(collect_module, "make_backend", spy)
    plain, noisy = tmp_path / "plain", tmp_path / "noisy"
    assert run([*collect_args(0, 4, plain, 4), "--workers", "1"], capsys)[0] == 0
    code, out, err = run([*collect_args(0, 4, noisy, 4), "--workers", "1",
                          "--camera-noise", "realsense"], capsys)
    assert code == 0, err
    assert json.loads(out)["config"]["camera_noise"] == "realsense"
    assert read_manifest(plain)["config"]["camera_noise"] == "none"
    assert read_manifest(noisy)["config"]["camera_noise"] == "realsense"
    assert [s for _, s in sensors] == [CAMERA_NOISE["none"], CAMERA_NOISE["realsense"]]
    assert {name for name, _ in sensors} == {"hand"}
    assert len(load_transitions(noisy)) == 4
    # The same collection under another sensor is another data set, not one to extend.
    code, out, err = run([*collect_args(0, 4, noisy, 8), "--workers", "1"], capsys)
    assert_bad_input(code, out, err, "holds a collection with a different configuration")


def test_a_manifest_from_before_the_sensor_model_extends_as_none(tmp_path):
    import dataclasses as dc

    from drake_symplan.data import storage
    from drake_symplan.data.collect import CollectConfig, _prepare

    old = dc.asdict(CollectConfig(transitions=4, chunk_size=2))
    del old["camera_noise"]
    storage.write_manifest(tmp_path, {"config": old, "seed": 0, "status": "done"})
    with pytest.raises(ValueError, match="different configuration"):
        _prepare(tmp_path, CollectConfig(transitions=6, chunk_size=2, camera_noise="heavy"))
    manifest, todo, _ = _prepare(tmp_path, CollectConfig(transitions=6, chunk_size=2))
    assert todo == [0, 1, 2] and manifest["config"]["camera_noise"] == "none"
    with pytest.raises(ValueError, match="unknown camera noise 'loud'"):
        CollectConfig(camera_noise="loud")


def test_a_problem_set_keeps_its_sensor_model(tmp_path):
    from drake_symplan.goals.problems import make_problems

    # A finished set made before the sensor model was recorded: made without noise.
    settings = {"n_objects": 2, "k": [1], "seed": 0, "backend": "hand"}
    (tmp_path / "problems.json").write_text(json.dumps(
        {"settings": settings, "kept": 1, "attempts": 1, "rejected": {}}))
    (tmp_path / "p000").mkdir()
    (tmp_path / "p000" / "problem.json").write_text('{"k": 1, "seed": 0, "n_objects": 2}')
    # Nothing left to make (no station built): the stored settings are only checked.
    assert make_problems(tmp_path, 2, [1], 1, 0, "hand")["kept"] == 1
    with pytest.raises(ValueError, match="'camera_noise': 'realsense'"):
        make_problems(tmp_path, 2, [1], 1, 0, "hand", camera_noise="realsense")


def test_problems_make_records_the_sensor_model(tmp_path, capsys):
    argv = ["problems", "make", "--out", tmp_path, "--objects", "2", "--k", "1", "--count",
            "1", "--backend", "hand", "--seed", "5", "--json"]
    code, out, err = run(argv, capsys)
    assert code == 0, err
    assert json.loads(out)["settings"]["camera_noise"] == "none"
    assert json.loads((tmp_path / "p000" / "problem.json").read_text())["camera_noise"] == "none"
    code, out, err = run([*argv, "--count", "2", "--camera-noise", "realsense"], capsys)
    assert_bad_input(code, out, err, "'camera_noise': 'none'", "'camera_noise': 'realsense'")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p000", "problems.json"]


def test_eval_planning_records_the_sensor_model_and_keeps_a_records_file_to_one(tmp_path):
    from test_agent_loop import FakeBackend, OracleAbstraction, fake_problem_set

    from drake_symplan.agent.config import SolveConfig
    from drake_symplan.agent.solve import Agent
    from drake_symplan.evaluation.planning import evaluate_planning

    fake_problem_set(tmp_path)
    records = tmp_path / "records.jsonl"
    kwargs = dict(agent=Agent(FakeBackend()), load=lambda run: OracleAbstraction(),
                  records_path=records, monitor=(True,))
    config = SolveConfig(planning="symbolic")
    result = evaluate_planning([tmp_path / "oracle"], tmp_path / "set", config, **kwargs)
    assert result["settings"]["camera_noise"] == "none"
    assert [r["camera_noise"] for r in result["records"]] == ["none"]
    assert json.loads(records.read_text())["camera_noise"] == "none"
    with pytest.raises(ValueError, match=r"holds solves with camera noise \['none'\], not "
                       "'realsense'"):
        evaluate_planning([tmp_path / "oracle"], tmp_path / "set", config,
                          camera_noise="realsense", **kwargs)
    other = tmp_path / "realsense.jsonl"
    noisy = evaluate_planning([tmp_path / "oracle"], tmp_path / "set", config,
                              camera_noise="realsense", **{**kwargs, "records_path": other})
    assert [r["camera_noise"] for r in noisy["records"]] == ["realsense"]
    assert noisy["settings"]["camera_noise"] == "realsense"


@pytest.mark.parametrize("noise", ["none", "realsense"])
def test_the_hand_perceives_again_after_a_miss_only_with_a_noisy_sensor(noise):
    from drake_symplan.actions import Action
    from drake_symplan.robot.backends import make_backend
    from drake_symplan.world.scenes import ObjectSpec, Scene

    hand = make_backend("hand", camera_noise=noise)
    hand.reset(Scene([ObjectSpec("o0", "cube", [0.6, 0.2, 0.025], 0.0),
                      ObjectSpec("o1", "cube", [0.7, 0.0, 0.025], 0.0)]))
    before = hand.perceive()
    # Offset to the right of a lone cube: the hand closes on nothing (test_data_collect).
    o0, o1 = (min(before.objects, key=lambda o: abs(o.position[0] - x)).name
              for x in (0.6, 0.7))
    seen = hand.perception_seconds
    done = hand.execute(Action(o0, "right", o1, "center"), before)
    assert done.status == "ok" and hand.station.held is None
    # A real camera's next frames differ even when nothing moved: it looks again.
    assert (done.after is before) == (noise == "none")
    assert (hand.perception_seconds > seen) == (noise != "none")


@pytest.mark.parametrize("noise", ["none", "realsense"])
def test_perceive_prints_what_it_saw_with_and_without_a_sensor_model(noise, capsys):
    code, out, err = run(["perceive", "--scene", DEMO / "start.yaml", "--camera-noise", noise],
                         capsys)
    assert code == 0, err
    lines = out.splitlines()
    assert sum(" -> o" in ln for ln in lines) == 4  # the demo's four boxes, each matched
    assert sum(ln.startswith("camera ") for ln in lines) == (3 if noise == "realsense" else 0)
    assert lines[-1].startswith("contacts:")
