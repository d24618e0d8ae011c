"""One contract for every command: exit 0 done, 1 negative answer, 2 bad input with one
line on stderr naming the file or flag, and nothing written."""

from __future__ import annotations

import argparse
import json
import sys
import types

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


@pytest.mark.parametrize("workers", ["0", "-3", "two"])
def test_collect_refuses_workers_below_one(workers, tmp_path, capsys):
    out_dir = tmp_path / "data"
    code, out, err = run(["collect", "--transitions", "10", "--workers", workers,
                          "--out", out_dir], capsys)
    assert_bad_input(code, out, err, "symplan collect: error: argument --workers: must be a "
                     f"positive integer, got '{workers}'")
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
        (["data", "stats", missing], f"symplan data stats: error: {missing}"),
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
