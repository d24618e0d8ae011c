"""Planner back-ends: results on solvable, unsolvable, malformed and too-hard tasks,
missing planners, the `plan` / `operators` commands, and FD vs pyperplan on learned
domains."""

import json
import multiprocessing
import os
from pathlib import Path

import numpy as np
import pytest
from pddl_reader import check_plan

from drake_symplan.cli import main as cli_main
from drake_symplan.planning.planners import PLANNERS, PlanResult, fast_downward, plan, plan_pddl
from drake_symplan.symbolic import synthetic
from drake_symplan.symbolic.operators import LearnConfig, learn_operators
from drake_symplan.symbolic.pddl import domain_pddl, problem_pddl
from drake_symplan.symbolic.structs import parse_step

HANOI = """
(define (domain hanoi)
  (:requirements :strips)
  (:predicates (clear ?x) (on ?x ?y) (smaller ?x ?y))
  (:action move
    :parameters (?disc ?from ?to)
    :precondition (and (smaller ?to ?disc) (on ?disc ?from) (clear ?disc) (clear ?to))
    :effect (and (clear ?from) (on ?disc ?to) (not (on ?disc ?from)) (not (clear ?to)))))
"""


def hanoi_problem(n: int, goal_extra: str = "") -> str:
    discs = [f"d{i}" for i in range(1, n + 1)]  # d1 smallest
    pegs = ["p1", "p2", "p3"]
    smaller = [f"(smaller {p} {d})" for p in pegs for d in discs]
    smaller += [f"(smaller {b} {a})" for i, a in enumerate(discs) for b in discs[i + 1:]]
    tower = [f"(on {discs[i]} {discs[i + 1]})" for i in range(n - 1)] + [f"(on {discs[-1]} p1)"]
    goal = [f"(on {discs[i]} {discs[i + 1]})" for i in range(n - 1)] + [f"(on {discs[-1]} p3)"]
    return (f"(define (problem hanoi{n}) (:domain hanoi) (:objects {' '.join(pegs + discs)})"
            f" (:init {' '.join(smaller + tower)} (clear d1) (clear p2) (clear p3))"
            f" (:goal (and {' '.join(goal)} {goal_extra})))")


# Relaxed-reachable but unreachable: both a and b need the single token.
TOKEN = """
(define (domain token) (:requirements :strips) (:predicates (free) (a) (b))
  (:action get-a :parameters () :precondition (free) :effect (and (a) (not (free))))
  (:action get-b :parameters () :precondition (free) :effect (and (b) (not (free)))))
"""
TOKEN_PROBLEM = "(define (problem t) (:domain token) (:init (free)) (:goal (and (a) (b))))"


GRIPPER = """
(define (domain gripper) (:requirements :strips)
  (:predicates (room ?r) (ball ?b) (gripper ?g) (at-robby ?r) (at ?b ?r) (free ?g) (carry ?o ?g))
  (:action move :parameters (?from ?to) :precondition (and (room ?from) (room ?to) (at-robby ?from))
    :effect (and (at-robby ?to) (not (at-robby ?from))))
  (:action pick :parameters (?o ?r ?g)
    :precondition (and (ball ?o) (room ?r) (gripper ?g) (at ?o ?r) (at-robby ?r) (free ?g))
    :effect (and (carry ?o ?g) (not (at ?o ?r)) (not (free ?g))))
  (:action drop :parameters (?o ?r ?g)
    :precondition (and (ball ?o) (room ?r) (gripper ?g) (carry ?o ?g) (at-robby ?r))
    :effect (and (at ?o ?r) (free ?g) (not (carry ?o ?g)))))
"""


def gripper_problem(n: int) -> str:
    """n balls from room a to room b with two grippers: 3n - 1 steps at best, and a
    plateau that A* with LM-cut needs many seconds to close at n = 20."""
    balls = [f"b{i}" for i in range(n)]
    init = " ".join(f"(ball {b}) (at {b} ra)" for b in balls)
    return (f"(define (problem g{n}) (:domain gripper) (:objects ra rb left right "
            f"{' '.join(balls)}) (:init (room ra) (room rb) (gripper left) (gripper right) "
            f"(at-robby ra) (free left) (free right) {init}) "
            f"(:goal (and {' '.join(f'(at {b} rb)' for b in balls)})))")


@pytest.fixture(scope="module")
def hanoi_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("hanoi")
    (d / "domain.pddl").write_text(HANOI)
    (d / "p3.pddl").write_text(hanoi_problem(3))
    (d / "p16.pddl").write_text(hanoi_problem(16))
    return d


@pytest.mark.parametrize("backend", sorted(PLANNERS))
def test_solves_any_positive_strips_domain_optimally(backend, hanoi_files):
    result = plan(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl", backend)
    assert result.status == "solved", result.message
    assert len(result.plan) == 7 and result.plan[0].startswith("(move ")
    assert check_plan(HANOI, hanoi_problem(3), result.plan) is None


@pytest.mark.parametrize("backend", sorted(PLANNERS))
def test_unsolvable(backend):
    for problem in (TOKEN_PROBLEM, TOKEN_PROBLEM.replace("(b)))", "(c)))")):
        result = plan_pddl(TOKEN, problem, backend)
        assert result.status in ("unsolvable", "error")
        if "(c)" not in problem:
            assert result.status == "unsolvable" and result.plan == []


@pytest.mark.parametrize("backend", sorted(PLANNERS))
def test_malformed_pddl_is_an_error_with_the_planners_message(backend):
    result = plan_pddl(HANOI[:-3], hanoi_problem(3), backend)
    assert result.status == "error"
    assert "pars" in result.message.lower() or "parenthes" in result.message.lower()
    result = plan_pddl(HANOI, hanoi_problem(3).replace("(on d3 p3)", "(on d3 p9)"), backend)
    assert result.status in ("error", "unsolvable")  # pyperplan does not check objects
    if backend == "fd":
        assert "Undefined object" in result.message and "p9" in result.message
    # Not positive STRIPS: FD reads it, pyperplan says what it cannot read.
    adl = HANOI.replace("(clear ?disc) (clear ?to))", "(clear ?disc) (clear ?to) (not (= ?from ?to)))")
    result = plan_pddl(adl, hanoi_problem(3), backend)
    assert result.status == ("solved" if backend == "fd" else "error"), result


def _processes_mentioning(text: str) -> list[int]:
    pids = []
    for proc in Path("/proc").iterdir():
        try:
            if text in (proc / "cmdline").read_bytes().decode(errors="ignore"):
                pids.append(int(proc.name))
        except (OSError, ValueError):
            continue
    return pids


@pytest.mark.parametrize("backend", sorted(PLANNERS))
def test_timeout_stops_the_planner(backend, hanoi_files):
    result = plan(hanoi_files / "domain.pddl", hanoi_files / "p16.pddl", backend,
                  wall_seconds=1.0, **({"search": "astar(blind())"} if backend == "fd" else {}))
    assert result.status == "timeout", result
    assert result.seconds < 5.0
    assert multiprocessing.active_children() == []
    assert _processes_mentioning(str(hanoi_files / "p16.pddl")) == []


def test_fast_downward_falls_back_to_a_weighted_search_when_a_star_runs_out(tmp_path):
    (tmp_path / "domain.pddl").write_text(GRIPPER)
    (tmp_path / "p.pddl").write_text(gripper_problem(20))
    files = tmp_path / "domain.pddl", tmp_path / "p.pddl"
    optimal_only = fast_downward(*files, wall_seconds=6.0, cpu_seconds=2.0, fallback=None)
    assert optimal_only.status == "timeout", optimal_only
    found = fast_downward(*files, wall_seconds=6.0, cpu_seconds=2.0)
    assert found.status == "solved", found
    assert len(found.plan) >= 59
    assert check_plan(GRIPPER, gripper_problem(20), found.plan) is None


def test_fast_downwards_expanded_states_are_tallied(hanoi_files):
    from drake_symplan.planning.nodes import EXPANDED, fd_expanded

    assert fd_expanded("[t=0.1s] g=15, 52 evaluated, 45 expanded\n"
                       "[t=0.1s] Expanded 46 state(s).\n") == 46
    # stopped at its limits: no closing count, the last progress line's
    assert fd_expanded("f = 501, 16748 evaluated, 16689 expanded, 51 reopened\n"
                       "Time limit reached. Abort search.\n") == 16689
    assert fd_expanded("") == fd_expanded(None) == 0
    before = EXPANDED.total
    found = fast_downward(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl")
    assert found.solved and EXPANDED.total - before == 14  # A* with LM-cut, three discs


def test_fast_downward_through_its_driver_finds_the_same_plan(hanoi_files, monkeypatch):
    from drake_symplan.planning import planners

    direct = fast_downward(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl")
    monkeypatch.setattr(planners, "_fd_components", lambda driver: None)
    driven = fast_downward(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl")
    assert direct.status == driven.status == "solved"
    assert direct.plan == driven.plan and len(direct.plan) == 7


def test_missing_fast_downward_is_a_clear_error(hanoi_files, monkeypatch):
    result = fast_downward(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl",
                           driver="/nonexistent/fast-downward.py")
    assert result.status == "error" and "not found" in result.message
    monkeypatch.setenv("SYMPLAN_FAST_DOWNWARD", "/nonexistent/fast-downward.py")
    result = plan(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl", "fd")
    assert result.status == "error" and "SYMPLAN_FAST_DOWNWARD" in result.message


def test_missing_pyperplan_is_a_clear_error(hanoi_files, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "pyperplan" else real(name, *a))
    result = plan(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl", "pyperplan")
    assert result.status == "error" and "not installed" in result.message


def test_bad_arguments_raise_value_errors(hanoi_files):
    with pytest.raises(ValueError, match="unknown planner"):
        plan(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl", "ff")
    with pytest.raises(FileNotFoundError):
        plan(hanoi_files / "nope.pddl", hanoi_files / "p3.pddl")
    with pytest.raises(ValueError):
        PlanResult("maybe")
    result = plan(hanoi_files / "domain.pddl", hanoi_files / "p3.pddl", "pyperplan",
                  heuristic="nope")
    assert result.status == "error" and "unknown pyperplan heuristic" in result.message


def run_cli(argv, monkeypatch, capsys):
    monkeypatch.setattr(cli_main, "COMMAND_MODULES", ["drake_symplan.cli.planning_cmds"])
    code = cli_main.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("backend", sorted(PLANNERS))
def test_plan_command_prints_json(backend, hanoi_files, monkeypatch, capsys):
    code, out, _ = run_cli(["plan", "--domain", str(hanoi_files / "domain.pddl"),
                            "--problem", str(hanoi_files / "p3.pddl"), "--planner", backend,
                            "--timeout", "5", "--json"], monkeypatch, capsys)
    assert code == 0
    result = json.loads(out)
    assert set(result) >= {"status", "plan", "seconds", "message"}
    assert result["status"] == "solved" and len(result["plan"]) == 7


def test_plan_command_errors_are_one_line(hanoi_files, tmp_path, monkeypatch, capsys):
    code, _, err = run_cli(["plan", "--domain", str(tmp_path / "none.pddl"),
                            "--problem", str(hanoi_files / "p3.pddl")], monkeypatch, capsys)
    assert code == 2 and err.count("\n") == 1 and "no PDDL file" in err
    (tmp_path / "bad.pddl").write_text("(define (domain")
    code, out, err = run_cli(["plan", "--domain", str(tmp_path / "bad.pddl"),
                              "--problem", str(hanoi_files / "p3.pddl"), "--json"],
                             monkeypatch, capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert f"{tmp_path / 'bad.pddl'}: malformed PDDL" in err


def test_operators_command_from_saved_symbols(tmp_path, monkeypatch, capsys):
    data = synthetic.random_transitions(3000, seed=7)
    data.save(tmp_path / "symbols.npz")
    out_dir = tmp_path / "ops"
    code, out, _ = run_cli(["operators", "--symbols", str(tmp_path / "symbols.npz"),
                            "--out", str(out_dir), "--min-count", "20", "--json"],
                           monkeypatch, capsys)
    assert code == 0
    result = json.loads(out)
    assert result["n_transitions"] == 3000 and result["threshold"] == 20
    assert result["n_operators"] == len(json.loads((out_dir / "operators.json").read_text())[
        "operators"])
    assert result["n_operators"] > 0
    assert (out_dir / "domain.pddl").read_text().count("(:action ") == result["n_operators"]
    report = (out_dir / "report.md").read_text()
    assert "## Operators by frequency" in report and "- example: transition" in report
    code, _, err = run_cli(["operators", "--out", str(out_dir)], monkeypatch, capsys)
    assert code == 2 and "--symbols" in err


@pytest.fixture(scope="module")
def learned_domain():
    data = synthetic.random_transitions(20000, seed=0)
    ops = learn_operators(data, LearnConfig(min_count=20))
    return (domain_pddl(ops.operators, synthetic.N_UNARY, synthetic.N_RELATIONS),
            {op.name: op for op in ops.operators})


def test_both_planners_accept_learned_domains_and_agree_on_plan_length(learned_domain):
    learned_domain, operators = learned_domain
    rng = np.random.default_rng(0)
    solved = 0
    for _ in range(20):
        start, goal, contacts = synthetic.random_problem(4, int(rng.integers(2, 5)), rng)
        problem = problem_pddl(start, goal, contacts)
        fd = plan_pddl(learned_domain, problem, "fd")
        pp = plan_pddl(learned_domain, problem, "pyperplan")
        assert fd.status in ("solved", "unsolvable") and fd.status == pp.status, (fd, pp)
        assert len(fd.plan) == len(pp.plan)
        for result in (fd, pp) if fd.solved else ():
            assert check_plan(learned_domain, problem, result.plan) is None
            for step in result.plan:
                action = parse_step(step, operators).action
                assert action.source in start.objects and action.target in start.objects
        solved += fd.solved
    assert solved >= 15


def test_pyperplan_child_is_gone_after_each_call(learned_domain):
    learned_domain, _ = learned_domain
    rng = np.random.default_rng(1)
    start, goal, contacts = synthetic.random_problem(3, 2, rng)
    before = os.getpid()
    result = plan_pddl(learned_domain, problem_pddl(start, goal, contacts), "pyperplan")
    assert result.status in ("solved", "unsolvable")
    assert os.getpid() == before and multiprocessing.active_children() == []


def test_operators_command_reads_symbols_out_of_a_run(tmp_path, monkeypatch, capsys):
    # The read-out needs a trained model; a stand-in module checks the wiring only.
    import sys
    import types

    data = synthetic.random_transitions(1000, seed=8)
    calls = []
    fake = types.ModuleType("drake_symplan.learning.readout")
    fake.readout_dataset = lambda run, data_dir: calls.append((run, data_dir)) or data
    monkeypatch.setitem(sys.modules, "drake_symplan.learning.readout", fake)
    (tmp_path / "run").mkdir()
    (tmp_path / "data").mkdir()
    code, out, _ = run_cli(["operators", str(tmp_path / "run"), "--data", str(tmp_path / "data"),
                            "--out", str(tmp_path / "ops"), "--min-fraction", "0.01", "--json"],
                           monkeypatch, capsys)
    assert code == 0 and calls == [(tmp_path / "run", tmp_path / "data")]
    result = json.loads(out)
    assert result["threshold"] == 10 and result["n_transitions"] == 1000
    saved = np.load(tmp_path / "ops" / "symbols.npz")
    assert np.array_equal(saved["relational"], data.relational)


@pytest.mark.parametrize("planner", ["fd", "pyperplan"])
def test_a_cpu_budget_stops_the_planner_before_its_wall_clock_cap(planner):
    import time

    from drake_symplan.symbolic.bundle import ModelBundle
    from drake_symplan.symbolic.pddl import problem_from_atoms

    bundle = ModelBundle.load()  # the shipped domain: ten objects ground a large task
    objects = [f"o{i}" for i in range(10)]
    init = [("touching0", o) for o in objects] + [("not_p0", o) for o in objects]
    costs = planner == "fd"
    problem = problem_from_atoms(objects, init, [("touching3", "o0"), ("p0", "o1")],
                                 costs=costs)
    t0 = time.perf_counter()
    result = plan_pddl(bundle.domain if costs else bundle.domain_strips, problem, planner,
                       wall_seconds=60.0, cpu_seconds=1.0)
    assert result.status == "timeout", result
    assert time.perf_counter() - t0 < 20.0  # far inside the wall-clock cap
