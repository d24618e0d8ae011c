"""One contract for every command: exit 0 done, 1 negative answer, 2 bad input with one
line on stderr naming the file or flag, and nothing written."""

from __future__ import annotations

import argparse
import json
import sys
import types
from pathlib import Path

import pytest
from conftest import assert_bad_input, run

from drake_symplan.cli import main as cli_main
from drake_symplan.cli.main import NegativeAnswer

BAD_YAML = "objects:\n  - name: o0\n    type: [cube\n  bad: :\n"  # error at line 4, column 6
DOMAIN = """(define (domain d) (:requirements :strips) (:predicates (p ?x) (q ?x))
  (:action a :parameters (?x) :precondition (q ?x) :effect (p ?x)))
"""
UNSOLVABLE = "(define (problem u) (:domain d) (:objects o) (:init) (:goal (p o)))\n"
HELP_COLUMNS = "80"  # argparse wraps help to $COLUMNS, else to the terminal's width


@pytest.fixture
def help_width(monkeypatch):
    """Help pages laid out at one width, whatever terminal runs the tests."""
    monkeypatch.setenv("COLUMNS", HELP_COLUMNS)


def flat(text: str) -> str:
    """Text with every run of whitespace one space: phrases argparse may wrap compare."""
    return " ".join(text.split())


@pytest.mark.parametrize("command", ["act", "perceive"])
def test_invalid_scene_yaml_is_one_line_naming_the_file(command, tmp_path, capsys):
    scene = tmp_path / "scene.yaml"
    scene.write_text(BAD_YAML)
    record = tmp_path / "act.html"
    argv = [command, "--scene", scene]
    if command == "act":
        argv += ["--pick", "o0:center", "--place", "o1:center", "--record", record]
    code, out, err = run(argv, capsys)
    assert_bad_input(code, out, err)
    assert err == f"symplan {command}: error: {scene}: invalid YAML (line 4, column 6)\n"
    assert not record.exists()


def test_invalid_config_yaml_is_one_line_naming_the_file(tmp_path, capsys):
    config = tmp_path / "train.yaml"
    config.write_text("epochs: [3\n")
    code, out, err = run(["train", "--config", config, "--out", tmp_path / "run"], capsys)
    assert_bad_input(code, out, err)
    assert err == f"symplan train: error: {config}: invalid YAML (line 2, column 1)\n"
    config.write_text("epochs: 3\nlearning_rate: 0.1\n")
    code, out, err = run(["train", "--config", config, "--out", tmp_path / "run"], capsys)
    assert_bad_input(code, out, err, f"{config}: unknown keys ['learning_rate']")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("flag, value, must", [
    *[("--workers", v, "a positive integer") for v in ("0", "-3", "two")],
    *[("--time-step", v, "a positive number") for v in ("0", "-0.01", "nan", "inf", "fast")],
    *[("--box-modulus", v, "a positive number") for v in ("0", "inf", "soft")]])
def test_collect_refuses_numbers_out_of_range(flag, value, must, tmp_path, capsys):
    out_dir = tmp_path / "data"
    code, out, err = run(["collect", "--transitions", "10", flag, value, "--out", out_dir],
                         capsys)
    assert_bad_input(code, out, err, f"symplan collect: error: argument {flag}: must be "
                     f"{must}, got '{value}'")
    assert not out_dir.exists()


@pytest.mark.parametrize("options, message", [
    (["--mix", "0.7", "0.5"], "p_random + p_goal must be within [0, 1], got 0.7 + 0.5"),
    (["--members", "1"], "disagreement needs at least 2 ensemble members, got 1"),
    (["--warmup", "150"], "--warmup (150) and --round-size (1000) must be multiples of "
                          "--chunk-size (100)"),
])
def test_active_collection_refuses_bad_settings_and_writes_nothing(options, message, tmp_path,
                                                                   capsys):
    out_dir = tmp_path / "data"
    code, out, err = run(["collect", "--explorer", "active", "--transitions", "300",
                          "--out", out_dir, *options], capsys)
    assert_bad_input(code, out, err, f"symplan collect: error: {message}")
    assert not out_dir.exists()


def test_a_curve_report_with_nothing_evaluated_is_bad_input(tmp_path, capsys):
    code, out, err = run(["curve", "--scale", "small", "--out", tmp_path, "--report"], capsys)
    assert_bad_input(code, out, err, f"symplan curve: error: nothing to report in {tmp_path}: "
                     "no point has been evaluated yet")


def test_malformed_pddl_is_bad_input_naming_the_file(tmp_path, capsys):
    (tmp_path / "d.pddl").write_text(DOMAIN)
    (tmp_path / "p.pddl").write_text("(define (problem u) (:domain d)")
    code, out, err = run(["plan", "--domain", tmp_path / "d.pddl", "--problem",
                          tmp_path / "p.pddl", "--json"], capsys)
    assert_bad_input(code, out, err,
                     f"symplan plan: error: {tmp_path / 'p.pddl'}: malformed PDDL: unbalanced")
    # Balanced but not PDDL the planner reads: named with both files.
    (tmp_path / "p.pddl").write_text(UNSOLVABLE.replace("(p o)", "(zz o)"))
    code, out, err = run(["plan", "--domain", tmp_path / "d.pddl", "--problem",
                          tmp_path / "p.pddl", "--planner", "fd"], capsys)
    assert_bad_input(code, out, err, f"{tmp_path / 'd.pddl'} and {tmp_path / 'p.pddl'}: ")


@pytest.mark.parametrize("planner", ["fd", "pyperplan"])
def test_unsolvable_problem_exits_1_and_prints_its_json(planner, tmp_path, capsys):
    (tmp_path / "d.pddl").write_text(DOMAIN)
    (tmp_path / "p.pddl").write_text(UNSOLVABLE)
    code, out, err = run(["plan", "--domain", tmp_path / "d.pddl", "--problem",
                          tmp_path / "p.pddl", "--planner", planner, "--json"], capsys)
    assert code == 1 and err == ""
    result = json.loads(out)
    assert result["status"] == "unsolvable" and result["plan"] == []


def test_missing_files_are_one_line_naming_them(tmp_path, capsys):
    (tmp_path / "d.pddl").write_text(DOMAIN)
    missing = tmp_path / "missing"
    for argv, expected in [
        (["plan", "--domain", tmp_path / "d.pddl", "--problem", missing],
         f"symplan plan: error: no PDDL file {missing}"),
        (["data", "stats", missing],
         f"symplan data stats: error: data directory {missing} does not exist"),
        (["act", "--scene", missing, "--pick", "o0:center", "--place", "o1:center"],
         f"symplan act: error: scene file {missing} does not exist"),
        (["train", "--config", missing], f"symplan train: error: {missing}: no such file"),
        (["operators", "--symbols", missing, "--out", tmp_path / "ops"],
         f"symplan operators: error: no symbols file {missing}"),
        (["eval", "effects", missing], f"symplan eval effects: error: run directory {missing}"),
    ]:
        code, out, err = run(argv, capsys)
        assert_bad_input(code, out, err, expected)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.pddl"]


def test_negative_answers_exit_1_and_print_like_any_result(monkeypatch, capsys):
    fake = types.ModuleType("fake_cmds")

    def register(subparsers):
        p = subparsers.add_parser("probe")
        p.add_argument("--json", action="store_true")
        p.add_argument("--ok", action="store_true")
        p.set_defaults(func=lambda args: {"status": "ok"} if args.ok
                       else NegativeAnswer(status="infeasible"))

    fake.register = register
    monkeypatch.setitem(sys.modules, "fake_cmds", fake)
    monkeypatch.setattr(cli_main, "COMMAND_MODULES", ["fake_cmds"])
    assert run(["probe", "--json"], capsys) == (1, '{\n  "status": "infeasible"\n}\n', "")
    assert run(["probe", "--json", "--ok"], capsys)[0] == 0
    code, out, err = run(["probe", "--nope"], capsys)
    assert_bad_input(code, out, err, "symplan: error: unrecognized arguments: --nope")


def test_help_says_what_the_tool_does_and_lists_the_pipeline_in_order(help_width, capsys):
    code, out, err = run(["--help"], capsys)
    assert code == 0 and err == ""
    assert flat(out.split("\n\n")[1]).startswith("A UR10 in Drake explores pick/place actions")
    assert "COMMAND_MODULES" not in out and "dispatches" not in out
    lines = out.split("The pipeline, in order:\n")[1].split("\n\n")[0].splitlines()
    names = [line.split("  ")[1].strip() for line in lines]  # two spaces, then the summary
    core = ["scene sample", "act", "perceive", "collect", "data stats", "train",
            "eval effects", "symbols", "operators", "bundle", "plan", "solve"]
    assert [n for n in names if n in core] == core  # the pipeline's order
    assert "eval operators  a model's domain" in out  # the longest name keeps its gap
    for name in names:  # every one is a command
        assert run([*name.split(), "--help"], capsys)[0] == 0


def subcommands(parser, prefix=()):
    """(words, parser) of every command of `parser`, depth first."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from subcommands(sub, (*prefix, name))
    if prefix:
        yield prefix, parser


def test_every_option_has_help_that_tells_its_default_and_the_exit_codes(help_width, capsys):
    parser = cli_main.build_parser()
    for words, sub in subcommands(parser):
        if any(isinstance(a, argparse._SubParsersAction) for a in sub._actions):
            continue  # a group such as `eval`: its commands are checked
        page = sub.format_help()
        assert "Exit status: 0 done, 1 a negative answer" in flat(page), words
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            name = "/".join(action.option_strings) or action.dest
            assert action.help, f"symplan {' '.join(words)} {name} has no help"
            default = action.default
            if action.option_strings and not action.required and default not in (
                    None, False, [], argparse.SUPPRESS):
                assert "default" in sub._get_formatter()._expand_help(action), (words, name)
    code, out, _ = run(["solve", "--help"], capsys)
    assert code == 0 and "symplan problems make" in flat(out) and "(default: fd)" not in flat(out)
    assert "--timeout TIMEOUT CPU seconds per plan" in flat(out) and "(default 10)" in flat(out)
    code, out, _ = run(["plan", "--help"], capsys)  # a planner call, not a solve
    assert "--timeout TIMEOUT planner seconds per call (default 10)" in flat(out)


def test_one_spelling_per_command(capsys):
    code, out, _ = run(["explain", "--help"], capsys)
    assert code == 0 and out.startswith("usage: symplan explain ")


# --- inputs a user found to slip through ------------------------------------------------

DEMO = Path(__file__).resolve().parents[1] / "models" / "demo"
SHIPPED = Path(__file__).resolve().parents[1] / "models" / "learned"


@pytest.mark.parametrize("text, problem", [
    ("[1, 2]", "operators.json holds an array, not an object"),
    ('{"operators": [', "operators.json: invalid JSON (line 1, column 16"),
    ('{"version": 2, "operators": {}}', "operators.json has no operators list"),
])
def test_an_operators_json_that_is_not_one_is_one_line_from_every_reader(
        text, problem, bundle_copy, tiny_dataset, tmp_path, capsys):
    (bundle_copy / "operators.json").write_text(text)
    for argv in (
            ["solve", "--start", DEMO / "start.yaml", "--goal", DEMO / "goal.yaml",
             "--model", bundle_copy, "--record", tmp_path / "rec.html"],
            ["inspect", "--scene", DEMO / "start.yaml", "--model", bundle_copy],
            ["eval", "operators", "--model", bundle_copy, "--data", tiny_dataset],
            ["eval", "rollout", "--model", bundle_copy, "--data", tiny_dataset],
            ["eval", "planning", "--runs", bundle_copy, "--problems", DEMO],
            ["bundle", "--continuous", SHIPPED, "--out", bundle_copy]):
        code, out, err = run(argv, capsys)
        assert_bad_input(code, out, err, f"model directory {bundle_copy}", problem)
    assert not (tmp_path / "rec.html").exists()
    assert not (bundle_copy / "continuous.pt").exists()


def problem_set(tmp_path, **record) -> Path:
    """A problem set of the demo's problem, its problem.json replaced by `record`."""
    folder = tmp_path / "set" / "p000"
    folder.mkdir(parents=True)
    for name in ("start.yaml", "goal.yaml"):
        (folder / name).write_text((DEMO / name).read_text())
    (folder / "problem.json").write_text(json.dumps(record))
    return folder


def test_the_oracle_on_a_problem_without_recorded_actions_is_one_line(tmp_path, capsys):
    folder = problem_set(tmp_path, k=2, n_objects=4)
    code, out, err = run(["eval", "planning", "--runs", SHIPPED, "--problems", tmp_path / "set",
                          "--planning", "oracle", "--monitor", "off"], capsys)
    assert_bad_input(code, out, err, "symplan eval planning: error: "
                     f"{folder / 'problem.json'} records no actions")
    (folder / "problem.json").write_text('{"k": 2, "n_objects": 4, "actions": ["fly(o0)"]}')
    code, out, err = run(["eval", "planning", "--runs", SHIPPED, "--problems", tmp_path / "set",
                          "--planning", "oracle"], capsys)
    assert_bad_input(code, out, err, f"{folder / 'problem.json'}: 'fly(o0)' is not an action")
    (folder / "problem.json").write_text('{"k": 2, "n_objects": 4, "actions": [}')
    code, out, err = run(["eval", "planning", "--runs", SHIPPED, "--problems", tmp_path / "set"],
                         capsys)
    assert_bad_input(code, out, err, f"{folder / 'problem.json'}: invalid JSON (line 1")
    (folder / "problem.json").write_text('{"n_objects": 4}')
    code, out, err = run(["eval", "planning", "--runs", SHIPPED, "--problems", tmp_path / "set"],
                         capsys)
    assert_bad_input(code, out, err, f"{folder / 'problem.json'}: no k (an integer each)")


def a_record(folder: Path) -> dict:
    """The record of a solve of `folder`'s problem by the shipped model, open loop."""
    return {"run": "models/learned", "problem": str(folder), "monitor": False,
            "status": "success", "failure_cause": None, "success_true": True, "n_objects": 4,
            "k": 2, "plan_length": 2, "replans": 0, "seconds": {"plan": 0.2, "total": 9.0},
            "error_cm": {"o0": 1.0}}


@pytest.mark.parametrize("lines, problem", [
    (["[1,2]"], "line 1: not an evaluation record (an array, not an object)"),
    (["RECORD", '{"a": 1}'], "line 2: not an evaluation record (it lacks ['run', "),
    (["RECORD", "", "{nope"], "line 3: invalid JSON (line 1, column 2"),
])
def test_a_records_file_of_lines_that_are_not_records_is_one_line(lines, problem, tmp_path,
                                                                  capsys):
    folder = problem_set(tmp_path, k=2, n_objects=4)
    records = tmp_path / "records.jsonl"
    text = "\n".join(json.dumps(a_record(folder)) if x == "RECORD" else x for x in lines)
    records.write_text(text + "\n{cut")  # a cut last line too: the file is left as it is
    code, out, err = run(["eval", "planning", "--runs", SHIPPED, "--problems", tmp_path / "set",
                          "--records", records, "--monitor", "off"], capsys)
    assert_bad_input(code, out, err, f"symplan eval planning: error: {records}, {problem}")
    assert records.read_text() == text + "\n{cut"


def test_a_records_file_whose_last_line_was_cut_says_it_dropped_it(tmp_path, capsys):
    folder = problem_set(tmp_path, k=2, n_objects=4, actions=[])
    records = tmp_path / "records.jsonl"
    whole = json.dumps(a_record(folder)) + "\n"
    records.write_text(whole + '{"run": "models/lea')
    # Everything was solved: the resume solves nothing, and says what it dropped.
    code, out, err = run(["eval", "planning", "--runs", SHIPPED, "--problems", tmp_path / "set",
                          "--records", records, "--monitor", "off", "--json"], capsys)
    assert code == 0 and json.loads(out)["runs"]["models/learned"]["open_loop"]["success"] == 1
    assert err == (f"symplan eval planning: warning: {records}: its incomplete last line (a "
                   "solve cut off while it was written) was dropped; resuming after its 1 "
                   "record(s)\n")
    assert records.read_text() == whole


@pytest.mark.parametrize("argv", [
    ["problems", "make", "--objects", "2", "--k", "1", "--count", "1"],
    ["collect", "--transitions", "10"],
])
def test_an_out_directory_that_is_a_file_is_one_line(argv, tmp_path, capsys):
    file = tmp_path / "taken"
    file.write_text("mine\n")
    code, out, err = run([*argv, "--out", file], capsys)
    assert_bad_input(code, out, err, f"error: --out {file} is a file, not a directory")
    code, out, err = run([*argv, "--out", file / "sub"], capsys)
    assert_bad_input(code, out, err, f"error: --out {file / 'sub'} cannot be made (in {file}")
    assert file.read_text() == "mine\n" and sorted(tmp_path.iterdir()) == [file]


    from drake_symplan.data.collect import CollectConfig

    with pytest.raises(ValueError, match="time_step must be a positive number"):
        CollectConfig(time_step=0.0)


@pytest.mark.parametrize("flags", [[], ["--json"]])
def test_a_reader_that_closes_stdout_early_ends_the_command_quietly(flags, tiny_dataset):
    import os
    import subprocess

    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    proc = subprocess.Popen([sys.executable, "-m", "drake_symplan.cli.main", "data", "stats",
                             str(tiny_dataset), *flags], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env)
    proc.stdout.close()  # `| head -1` gone before the command prints
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == cli_main.EXIT_CLOSED_STDOUT and err == ""
    done = subprocess.run([sys.executable, "-m", "drake_symplan.cli.main", "data", "stats",
                           str(tiny_dataset), *flags], capture_output=True, text=True, env=env,
                          timeout=300)
    assert done.returncode == 0 and f"{tiny_dataset}" in done.stdout and done.stderr == ""


def test_a_broken_pipe_that_is_not_stdout_is_not_hidden(monkeypatch):
    def broken(*args):
        raise BrokenPipeError("a worker's pipe")

    monkeypatch.setattr(cli_main, "run_command", broken)
    monkeypatch.setattr(cli_main, "stdout_closed", lambda: False)
    with pytest.raises(BrokenPipeError):
        cli_main.main([])


def test_record_and_out_files_that_are_directories_are_told_before_anything_runs(tmp_path,
                                                                                  capsys):
    scene = DEMO / "start.yaml"
    for argv, flag in [
            (["solve", "--start", scene, "--goal", DEMO / "goal.yaml"], "--record"),
            (["inspect", "--scene", scene], "--record"),
            (["act", "--scene", scene, "--pick", "o1:center", "--place", "o3:left"], "--record"),
            (["act", "--scene", scene, "--pick", "o1:center", "--place", "o3:left"], "--out"),
            (["scene", "sample", "--objects", "2"], "--out"),
            (["eval", "planning", "--runs", SHIPPED, "--problems", DEMO], "--records")]:
        code, out, err = run([*argv, flag, tmp_path], capsys)
        assert_bad_input(code, out, err, f"error: {flag} {tmp_path} is a directory, not a file")
    assert list(tmp_path.iterdir()) == []


def test_a_familiar_data_file_is_told_it_is_not_a_directory(tiny_dataset, tmp_path, capsys):
    file = tmp_path / "train.npz"
    file.write_text("")
    code, out, err = run(["eval", "operators", "--data", tiny_dataset, "--familiar-data", file],
                         capsys)
    assert_bad_input(code, out, err, f"error: --familiar-data {file} is not a directory")
    code, out, err = run(["eval", "operators", "--data", file], capsys)
    assert_bad_input(code, out, err, f"error: --data {file} is not a directory")
    code, out, err = run(["data", "stats", file], capsys)
    assert_bad_input(code, out, err, f"error: data directory {file} is not a directory")


def test_malformed_json_files_are_named(tiny_dataset, capsys):
    manifest = tiny_dataset / "manifest.json"
    manifest.write_text('{"schema_version": 1,}')
    code, out, err = run(["data", "stats", tiny_dataset], capsys)
    assert_bad_input(code, out, err, f"error: {manifest}: invalid JSON (line 1, column 22")
    manifest.write_bytes(b'{"schema_version": "\xff"}')
    code, out, err = run(["data", "stats", tiny_dataset], capsys)
    assert_bad_input(code, out, err, f"error: {manifest}: not UTF-8 text")
    manifest.write_text("[]")
    code, out, err = run(["data", "stats", tiny_dataset], capsys)
    assert_bad_input(code, out, err, f"error: {manifest}: expected an object, got an array")


def test_scene_sample_says_what_it_wrote(tmp_path, capsys):
    from drake_symplan.world.scenes import load_scene

    path = tmp_path / "scene.yaml"
    code, out, err = run(["scene", "sample", "--objects", "3", "--seed", "4", "--out", path],
                         capsys)
    types = ", ".join(f"{o.name} {o.type}" for o in load_scene(path).objects)
    assert code == 0 and err == "" and out == f"wrote {path}: 3 objects ({types})\n"
    code, out, err = run(["scene", "sample", "--objects", "3", "--out", path, "--json"], capsys)
    assert code == 0 and json.loads(out) == {"out": str(path), "objects": ["o0", "o1", "o2"]}
