"""Benchmark: the continuous search's throughput, predictions per CPU second, on the
perceived scenes of a problem set, with torch on one thread (as the agent plans) and on
torch's default threads, in the same run.

    python tools/bench_search.py --problems DIR [--count 10] [--budget 2] [--json]
                                 [--model DIR] [--relations] [--out bench_search.json]

Per problem: perceive the start and the goal once, then run the weighted best-first search
of abstraction/refiner.py (Refiner.search) from the start to the goal positions (with
--relations: to the problem's goal of relations, as the agent plans it) until it finds a
plan or spends --budget CPU seconds, once per thread setting. The rate is the
model's predictions over the CPU seconds the search took (this process; both settings
count every thread's time, which is what a CPU-second planning budget pays for).
Medians over the problems, and the one-thread rate as a multiple of the default's.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from functools import partial
from pathlib import Path


def search_rate(refiner_for, start, goal, budget_s: float) -> dict:
    """One search: predictions, CPU seconds, whether it reached the goal."""
    from drake_symplan.planning.budget import Budget
    from drake_symplan.planning.planners import WALL_FACTOR

    refiner = refiner_for()
    t = time.process_time()
    found, _ = refiner.search(start, goal.where(), Budget(budget_s, WALL_FACTOR * budget_s))
    cpu = time.process_time() - t
    return {"predictions": refiner.predictions, "cpu_s": round(cpu, 4),
            "per_cpu_s": round(refiner.predictions / max(cpu, 1e-9), 1),
            "found": found is not None}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--problems", type=Path, required=True,
                        help="a `symplan problems make` set (problems at any depth)")
    parser.add_argument("--model", type=Path, default=None,
                        help="model bundle directory (default: the shipped one)")
    parser.add_argument("--count", type=int, default=10)
    parser.add_argument("--budget", type=float, default=2.0,
                        help="CPU seconds per search at most (default 2)")
    parser.add_argument("--relations", action="store_true",
                        help="search for each problem's goal of relations (its spec)")
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)

    import torch

    from drake_symplan.abstraction.continuous import Boxes, ContinuousModel
    from drake_symplan.abstraction.refiner import Refiner
    from drake_symplan.agent.solve import Agent
    from drake_symplan.cli.options import load_bundle
    from drake_symplan.goals.problems import load_problems
    from drake_symplan.relations import parse
    from drake_symplan.world.scenes import load_scene

    bundle = load_bundle(args.model)
    model = ContinuousModel(bundle.continuous)

    def refiner_for(relations=()):
        refiner = Refiner(bundle.operators, model)
        refiner.relations = relations
        return refiner

    agent = Agent("arm")
    cpus = torch.get_num_threads()  # torch's default
    settings = {"one thread": 1, "default threads": cpus}
    rows = []
    for problem in load_problems(args.problems)[:args.count]:
        folder = Path(problem["dir"])
        if args.relations and "spec" not in problem:
            print(f"bench_search: {folder}: no goal of relations (spec) to search for",
                  file=sys.stderr)
            return 2
        start = Boxes.of(agent.look(load_scene(folder / "start.yaml")).scene)
        goal = Boxes.of(agent.look(load_scene(folder / "goal.yaml")).scene)
        relations = tuple(parse(problem["spec"])) if args.relations else ()
        row = {"problem": str(folder), "n_objects": len(start.names)}
        for name, threads in settings.items():
            torch.set_num_threads(threads)
            row[name] = search_rate(partial(refiner_for, relations), start, goal, args.budget)
        rows.append(row)
    medians = {name: statistics.median(r[name]["per_cpu_s"] for r in rows)
               for name in settings}
    result = {"host": {"machine": platform.machine(), "python": platform.python_version(),
                       "torch_default_threads": cpus},
              "model": str(args.model or "shipped"), "budget_cpu_s": args.budget,
              "goal": "relations" if args.relations else "positions",
              "threads": settings, "median_predictions_per_cpu_s": medians,
              "one_thread_vs_default": round(medians["one thread"]
                                             / max(medians["default threads"], 1e-9), 2),
              "problems": rows}
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.write_text(text + "\n")
    if args.json:
        print(text)
    else:
        for name, rate in medians.items():
            print(f"{name}: {rate:.0f} predictions per CPU second (median of {len(rows)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
