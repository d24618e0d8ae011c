"""Benchmark: operator learning on 50k symbolic transitions, and planner seconds per
4-object problem on the domain learned from them.

    python tools/bench_operators.py --json [--transitions 50000] [--out bench_operators.json]

The transitions come from the toy symbolic blocks world (drake_symplan.symbolic.synthetic:
1 unary bit, K = 3 relations, 2-4 objects per scene, relevant objects only), or, with
`--symbols symbols.npz` (from `symplan symbols RUN --data DIR`), from a trained model's
read-out of real perceived transitions; problems are then that data's own 4-object
transitions (start: the state before, goal: the state after, all relation atoms), those
whose goal does not already hold. Learning
time is the median of --runs runs (>= 3); planning time is the median over --problems
(>= 10) non-trivial 4-object problems, per call, for Fast Downward (subprocess, its own
temporary directory) and pyperplan (forked child), both optimal A* with LM-cut.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from drake_symplan.planning.planners import plan
from drake_symplan.symbolic import synthetic
from drake_symplan.symbolic.operators import LearnConfig, learn_operators
from drake_symplan.symbolic.pddl import domain_pddl, problem_pddl


def bench_learning(data: dict, runs: int, min_count: int) -> tuple[dict, object]:
    seconds, ops = [], None
    for _ in range(runs):
        t = time.perf_counter()
        ops = learn_operators(data, LearnConfig(min_count=min_count))
        seconds.append(time.perf_counter() - t)
    return {
        "runs": runs,
        "median_s": statistics.median(seconds),
        "all_s": seconds,
        **{k: v for k, v in ops.summary().items() if k not in ("seconds",)},
    }, ops


def bench_effect_learning(data, runs: int, min_count: int) -> dict:
    """The effect-first learner (symbolic/effect_operators.py) on the same data."""
    from drake_symplan.symbolic.effect_operators import EffectLearnConfig, learn_effect_operators

    seconds, result = [], None
    for _ in range(runs):
        t = time.perf_counter()
        result = learn_effect_operators(data, EffectLearnConfig(min_count=min_count))
        seconds.append(time.perf_counter() - t)
    summary = result.summary()
    return {"runs": runs, "median_s": statistics.median(seconds), "all_s": seconds,
            "operators": summary["operators"], "groups": summary["groups"],
            "mean_reliability": summary["mean_reliability"], "timings": summary["timings"]}


def bench_planning(ops, problems: int, objects: int, seed: int, timeout: float) -> dict:
    rng = np.random.default_rng(seed)
    out = {}
    with tempfile.TemporaryDirectory(prefix="bench-ops-") as tmp:
        domain = Path(tmp) / "domain.pddl"
        domain.write_text(domain_pddl(ops.operators, ops.n_unary, ops.n_relations))
        files = []
        for i in range(problems):
            start, goal, contacts = synthetic.random_problem(objects, int(rng.integers(2, 5)), rng)
            files.append(Path(tmp) / f"p{i}.pddl")
            files[-1].write_text(problem_pddl(start, goal, contacts, name=f"p{i}"))
        for name in ("fd", "pyperplan"):
            plan(domain, files[0], name, timeout)  # warm-up: imports, page cache
            results = [plan(domain, f, name, timeout) for f in files]
            seconds = [r.seconds for r in results]
            statuses: dict[str, int] = {}
            for r in results:
                statuses[r.status] = statuses.get(r.status, 0) + 1
            out[name] = {
                "problems": len(results),
                "median_s": statistics.median(seconds),
                "p90_s": float(np.percentile(seconds, 90)),
                "statuses": statuses,
                "plan_lengths": [len(r.plan) for r in results],
            }
    lengths_equal = out["fd"]["plan_lengths"] == out["pyperplan"]["plan_lengths"]
    return {"objects": objects, "operators": len(ops.operators),
            "plan_lengths_equal": lengths_equal, **out}


def bench_planning_real(ops, data: dict, problems: int, objects: int, timeout: float) -> dict:
    from drake_symplan.symbolic.states import SymbolicState

    rows = np.flatnonzero(data["mask"].sum(axis=1) == objects)
    out = {}
    with tempfile.TemporaryDirectory(prefix="bench-ops-") as tmp:
        domain = Path(tmp) / "domain.pddl"
        domain.write_text(domain_pddl(ops.operators, ops.n_unary, ops.n_relations))
        files = []
        for t in rows:
            start = SymbolicState.from_arrays(data["unary"][t], data["relational"][t],
                                              data["mask"][t])
            goal = SymbolicState.from_arrays(data["next_unary"][t], data["next_relational"][t],
                                             data["mask"][t])
            if set(start.facts()) == set(goal.facts()):
                continue  # trivially satisfied goals are not planning successes
            files.append(Path(tmp) / f"p{len(files)}.pddl")
            files[-1].write_text(problem_pddl(start, goal, None, name=f"p{len(files)}"))
            if len(files) == problems:
                break
        if not files:
            raise SystemExit(f"no non-trivial {objects}-object transitions in the symbols")
        for name in ("fd", "pyperplan"):
            plan(domain, files[0], name, timeout)
            results = [plan(domain, f, name, timeout) for f in files]
            statuses: dict[str, int] = {}
            for r in results:
                statuses[r.status] = statuses.get(r.status, 0) + 1
            out[name] = {"problems": len(results),
                         "median_s": statistics.median(r.seconds for r in results),
                         "statuses": statuses,
                         "plan_lengths": [len(r.plan) for r in results]}
    return {"objects": objects, "operators": len(ops.operators),
            "plan_lengths_equal": out["fd"]["plan_lengths"] == out["pyperplan"]["plan_lengths"],
            **out}


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--transitions", type=int, default=50_000)
    parser.add_argument("--symbols", type=Path,
                        help="learn from this read-out (symbols.npz) instead of synthetic data")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--problems", type=int, default=10)
    parser.add_argument("--objects", type=int, default=4)
    parser.add_argument("--min-count", type=int, default=50)
    parser.add_argument("--effect-min-count", type=int, default=10,
                        help="the effect-first learner's minimum count (default 10)")
    parser.add_argument("--timeout", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    args = parser.parse_args()
    if args.runs < 3 or args.problems < 10:
        parser.error("use --runs >= 3 and --problems >= 10 for medians worth reporting")
    return args


def load_data(args: argparse.Namespace):
    """(the symbolic transitions, the seconds to load or generate them); --symbols sets
    args.transitions to the read-out's count."""
    t = time.perf_counter()
    if args.symbols:
        from drake_symplan.symbolic.operators import load_symbols

        data = load_symbols(args.symbols)
        args.transitions = int(data["mask"].shape[0])
    else:
        data = synthetic.random_transitions(args.transitions, seed=args.seed)
    return data, time.perf_counter() - t


def run_benchmark(args: argparse.Namespace) -> dict:
    """Learning both ways and planning on the data `args` names: the result's JSON."""
    data, generate_s = load_data(args)
    learning, ops = bench_learning(data, args.runs, args.min_count)
    effect = (bench_effect_learning(data, args.runs, args.effect_min_count)
              if data.contacts is not None else None)
    if args.symbols:
        planning = bench_planning_real(ops, data, args.problems, args.objects, args.timeout)
    else:
        planning = bench_planning(ops, args.problems, args.objects, args.seed + 1,
                                  args.timeout)
    return {
        "benchmark": "operators",
        "source": str(args.symbols) if args.symbols else "synthetic",
        "transitions": args.transitions,
        "generate_s": generate_s,
        "learning": learning,
        "effect_learning": effect,
        "planning": planning,
        "targets": {
            "learning_median_s_max": 30.0,
            "fd_median_s_max": 0.5,
            "learning_ok": learning["median_s"] <= 30.0,
            "effect_learning_ok": effect is None or effect["median_s"] <= 30.0,
            "fd_ok": planning["fd"]["median_s"] <= 0.5,
        },
        "machine": {"python": platform.python_version(), "processor": platform.processor(),
                    "platform": platform.platform()},
    }


def main() -> int:
    args = parse_args()
    result = run_benchmark(args)
    learning, planning = result["learning"], result["planning"]
    text = json.dumps(result, indent=2)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)  # --out may name a new folder
        args.out.write_text(text + "\n")
    if args.json:
        print(text)
    else:
        print(f"learning: {learning['median_s']:.2f} s median for {args.transitions} "
              f"transitions -> {learning['n_operators']} operators; FD "
              f"{planning['fd']['median_s']:.3f} s, pyperplan "
              f"{planning['pyperplan']['median_s']:.3f} s per {args.objects}-object problem")
    return 0


if __name__ == "__main__":
    sys.exit(main())
