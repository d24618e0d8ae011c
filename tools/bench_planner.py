"""Benchmark: one Fast Downward call on a model's tasks, grounded here (the agent's way,
planning/grounding.py) against FD's own translator on the PDDL text, one after the other
on the same tasks.

    python tools/bench_planner.py --model DIR --data DIR --json [--count 4] [--timeout 5]
                                  [--out bench_planner.json]

The tasks are `eval operators`' own: k = 1-5 action chains of the held-out data set
(`--data`, read out by the bundle's model), --count per object count and k. Per task:
each way's status, plan cost and seconds (wall, the whole call: grounding or
translation, then search) under the same CPU budget (--timeout CPU seconds). Reported:
medians by the translator's status, and how many tasks got a different status or plan
cost (the two must agree: both are A* with LM-cut on the same task).
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
from functools import partial
from pathlib import Path

from drake_symplan.abstraction.abstraction import plan_task, problem_text
from drake_symplan.evaluation.operators import EvalConfig, heldout_problems, readout_scenes
from drake_symplan.planning.planners import WALL_FACTOR, plan_pddl
from drake_symplan.symbolic.bundle import ModelBundle
from drake_symplan.symbolic.structs import parse_step


def cost(result, by_name) -> int:
    return sum(parse_step(s, by_name).operator.cost for s in result.plan)


def bench(bundle: ModelBundle, data: Path, count: int, timeout: float) -> dict:
    _, scenes = readout_scenes(bundle.model, data, bundle.margin)
    problems = heldout_problems(scenes, bundle.semantics,
                             EvalConfig(max_problems=count, ks=(1, 2, 3, 4, 5)))
    rows = []
    for p in problems:
        n = len(p.task.objects)
        grounded = plan_task(bundle.planned, partial(bundle.domain_for, n), p.task, "fd",
                             WALL_FACTOR * timeout, cpu_seconds=timeout)
        translated = plan_pddl(bundle.domain_for(n), problem_text(p.task, costs=True), "fd",
                               WALL_FACTOR * timeout, cpu_seconds=timeout)
        rows.append({"objects": n, "k": p.k,
                     **{f"{way}_{key}": value for way, r in (("grounded", grounded),
                                                             ("translated", translated))
                        for key, value in (("status", r.status),
                                           ("cost", cost(r, bundle.by_name)),
                                           ("s", round(r.seconds, 4)))}})
        print(rows[-1], file=sys.stderr, flush=True)
    by_status = {}
    for status in sorted({r["translated_status"] for r in rows}):
        cell = [r for r in rows if r["translated_status"] == status]
        grounded = statistics.median(r["grounded_s"] for r in cell)
        translated = statistics.median(r["translated_s"] for r in cell)
        by_status[status] = {"tasks": len(cell), "grounded_median_s": round(grounded, 4),
                             "translated_median_s": round(translated, 4),
                             "speedup": round(translated / max(grounded, 1e-9), 1)}
    differ = [r for r in rows if (r["grounded_status"], r["grounded_cost"])
              != (r["translated_status"], r["translated_cost"])]
    return {"host": {"machine": platform.machine(), "python": platform.python_version()},
            "model": str(bundle.path), "data": str(data), "timeout_cpu_s": timeout,
            "tasks": len(rows), "differ": len(differ), "by_status": by_status, "rows": rows}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", type=Path, required=True, help="model bundle directory")
    p.add_argument("--data", type=Path, required=True, help="held-out data set directory")
    p.add_argument("--count", type=int, default=4, help="tasks per object count and k")
    p.add_argument("--timeout", type=float, default=5.0, help="CPU seconds per call")
    p.add_argument("--out", type=Path, help="write the JSON here too")
    p.add_argument("--json", action="store_true", help="print the JSON report")
    args = p.parse_args(argv)
    report = bench(ModelBundle.load(args.model), args.data, args.count, args.timeout)
    text = json.dumps(report, indent=1)
    if args.out:
        args.out.write_text(text + "\n")
    print(text if args.json else json.dumps(report["by_status"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
