"""tools/run_demo.py and `symplan demo`: bad input in one line (exit 2) before any station
is built, --from-scratch's stages, and, slow, the whole demo on a small scene: a goal made
by the arm, a plan, its execution, the result JSON of `symplan solve --json` and one HTML
recording with the goal drawn in it."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import bundle_for_tests, recorded_paths

REPO = Path(__file__).resolve().parents[1]
DEMO = REPO / "tools" / "run_demo.py"


def load_demo():
    spec = importlib.util.spec_from_file_location("run_demo", DEMO)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_main(argv, capsys):
    code = load_demo().main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_bad_input(code, out, err, text):
    assert code == 2 and out == "", (code, out, err)
    assert err.count("\n") == 1 and err.startswith("run_demo.py: error: "), err
    assert text in err, err


def test_a_missing_default_model_is_told_in_one_line(tmp_path, monkeypatch, capsys):
    import drake_symplan.symbolic.bundle as bundle

    monkeypatch.setattr(bundle, "default_bundle_dir", lambda: tmp_path / "learned")
    code, out, err = run_main([], capsys)
    assert_bad_input(code, out, err, f"no model at {tmp_path / 'learned'} (the default model "
                     "is not shipped yet; give --model DIR)")


def test_other_bad_input(tmp_path, capsys):
    code, out, err = run_main(["--model", tmp_path / "none"], capsys)
    assert_bad_input(code, out, err, "no model at")
    code, out, err = run_main(["--start", tmp_path / "s.yaml"], capsys)
    assert_bad_input(code, out, err, "give --start and --goal together")
    code, out, err = run_main(["--seed", "0", "--objects", "1"], capsys)
    assert_bad_input(code, out, err, "--objects must be in [2, ")
    code, out, err = run_main(["--seed", "0", "--start", DEMO, "--goal", DEMO], capsys)
    assert_bad_input(code, out, err, "give --seed (a sampled problem) or --start/--goal")
    code, out, err = run_main(["--timeout", "0"], capsys)
    assert_bad_input(code, out, err, "argument --timeout: must be a positive number")
    code, out, err = run_main(["--start", tmp_path / "s.yaml", "--goal", tmp_path / "g.yaml"],
                              capsys)
    assert_bad_input(code, out, err, "s.yaml")
    (tmp_path / "m").mkdir()
    code, out, err = run_main(["--model", tmp_path / "m"], capsys)
    assert_bad_input(code, out, err, "has no model.pt")


@pytest.mark.slow
def test_the_demo_solves_a_small_random_goal_and_records_it(tmp_path):
    out = tmp_path / "demo.html"
    proc = subprocess.run([sys.executable, str(DEMO), "--model", str(bundle_for_tests()),
                           "--objects", "2", "--seed", "1", "--json", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode in (0, 1), proc.stderr
    result = json.loads(proc.stdout)
    for key in ("status", "plan", "executed", "replans", "objects", "seconds", "recording",
                "demo"):
        assert key in result, result
    assert (proc.returncode == 0) == (result["status"] == "success"), result
    assert sorted(result["objects"]) == ["o0", "o1"]
    for o in result["objects"].values():
        assert {"goal", "final", "final_true", "error_cm"} <= set(o)
    demo = result["demo"]
    assert demo["k"] in (2, 3) and len(demo["actions"]) == demo["k"] and demo["moved_cm"] > 5
    assert len(demo["plan_readable"]) == len(result["plan"])
    assert all(s.startswith("pick o") for s in demo["plan_readable"])
    assert Path(demo["scenes"]["start"]).is_file() and Path(demo["scenes"]["goal"]).is_file()
    # The readable plan and the verdict went to stderr; stdout held only the JSON.
    assert "plan (" in proc.stderr and "verdict: " in proc.stderr
    assert result["recording"] == str(out)
    page = out.read_text()
    assert {"/symplan/goal/boxes/o0", "/symplan/goal/boxes/o1"} <= recorded_paths(page)
    assert 'id="symplan-panel"' in page and f"Verdict: {result['status']}" in page


@pytest.mark.parametrize("argv, text", [
    (["--seed", "-1"], "argument --seed: must be a non-negative integer, got '-1'"),
    (["--seed", "abc"], "argument --seed: must be a non-negative integer, got 'abc'"),
    (["--planning", "foo"], "argument --planning: invalid choice: 'foo'"),
])
def test_bad_seeds_and_choices_are_one_line_from_the_script_and_symplan(argv, text, capsys):
    proc = subprocess.run([sys.executable, "tools/run_demo.py", *argv], cwd=REPO,
                          capture_output=True, text=True, timeout=120)
    assert_bad_input(proc.returncode, proc.stdout, proc.stderr, text)
    assert proc.stderr.rstrip().endswith("(see run_demo.py --help)"), proc.stderr
    from drake_symplan.cli.main import main as symplan

    code = symplan(["demo", *argv])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1, (code, out, err)
    assert err.startswith(f"symplan demo: error: {text}"), err


def test_symplan_demo_help_tells_the_demo_and_its_options(capsys):
    from drake_symplan.cli.main import main as symplan

    assert symplan(["demo", "--help"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and out.startswith("usage: symplan demo ")
    assert "The demo: the robot solves a goal" in out and "Exit status: 0 done" in out
    for option in ("--model", "--seed", "--objects", "--k", "--start", "--goal", "--out",
                   "--no-record", "--planner", "--timeout", "--planning", "--meshcat",
                   "--json", "--from-scratch", "--budget-minutes", "--work"):
        assert f"  {option}" in out, option
    code, script, _ = run_main(["--help"], capsys)
    assert code == 0 and script.startswith("usage: run_demo.py ")
    assert script.split("options:")[1] == out.split("options:")[1]  # the same options


def test_symplan_demo_tells_bad_input_like_the_script(tmp_path, capsys):
    from drake_symplan.cli.main import main as symplan

    code = symplan(["demo", "--start", str(tmp_path / "s.yaml")])
    out, err = capsys.readouterr()
    assert (code, out) == (2, "") and err == ("symplan demo: error: give --start and --goal "
                                              "together\n")


def test_from_scratch_stages_announce_their_command_and_stop_at_the_budget(tmp_path):
    from drake_symplan.pipelines.stages import Stage, StageFailed, StageRunner

    said = []
    runner = StageRunner(tmp_path, jobs=1, say=said.append, announce="  $ {command}")
    runner.run(Stage("slow", ["--help"], None, timeout=0.001))  # stopped before it starts
    assert said == ["  $ symplan --help", "    stopped at the budget"]
    assert runner.log[0]["stopped"] is True
    runner.run(Stage("help", ["--help"], None))  # no `done` file: it runs whenever asked
    assert runner.log[-1]["command"] == "symplan --help" and "seconds" in runner.log[-1]
    with pytest.raises(StageFailed, match="bad failed \\(exit 2; log "):
        runner.run(Stage("bad", ["no-such-command"], None))


def test_from_scratch_bad_input(tmp_path, capsys):
    code, out, err = run_main(["--from-scratch", "--model", tmp_path], capsys)
    assert_bad_input(code, out, err, "give --model or --from-scratch, not both")
    code, out, err = run_main(["--from-scratch", "--budget-minutes", "1"], capsys)
    assert_bad_input(code, out, err, "--budget-minutes must be at least 2")


def demo_lines(text: str) -> list[str]:
    """The lines of the demo's output that must not change between machines: the problem,
    the plan (its time and predicted distance left out) and its steps, and the verdict."""
    keep = [line for line in text.splitlines()
            if re.match(r"^\s+\d+\. ", line) or line.startswith(("problem: ", "plan (", "verdict: "))]
    return [re.sub(r" within [\d.]+ cm", " within", re.sub(r", [\d.]+ s(?=[,)])", "", line))
            for line in keep]


def test_demo_lines_leave_out_what_varies():
    assert demo_lines("model x\nplan (2 step(s), reliability 49%, 0.5 s):\n  1. pick a\n"
                      "  o1: 0.28 cm\nverdict: success (...)\nrecording written") == [
        "plan (2 step(s), reliability 49%):", "  1. pick a", "verdict: success (...)"]
    assert demo_lines("plan (1 step(s), every box predicted within 1.8 cm of its goal, 0.9 s, "
                      "bilevel):") == ["plan (1 step(s), every box predicted within of its "
                                       "goal, bilevel):"]


@pytest.mark.slow
def test_the_readme_demo_command_prints_the_readme_plan_and_verdict():
    readme = (REPO / "README.md").read_text()
    printed = readme.split("```text\n", 1)[1].split("```", 1)[0]  # the quick start's output
    assert "python tools/run_demo.py" in readme.split("```text\n", 1)[0]
    proc = subprocess.run([sys.executable, "tools/run_demo.py"], cwd=REPO, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert demo_lines(proc.stdout) == demo_lines(printed), proc.stdout
    assert len(demo_lines(printed)) >= 5  # problem, plan, two steps, verdict
