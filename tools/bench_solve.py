"""Benchmark: the closed loop's plan overhead per problem, before the robot moves.

    python tools/bench_solve.py --json [--model DIR] [--problems DIR] [--count 20]
                                [--planner fd] [--out bench_solve.json]

Per problem: perceive the goal scene and the start scene (depth cameras, box fitting,
naming after the scene files), read both scenes' symbols with the model bundle, write the
PDDL problem and plan (the bundle's `plan`, as the agent does). The overhead is their sum; putting a scene on the table and
letting physics settle it (the simulator's part, `show`) is reported apart. Medians over
the problems; the target is a median overhead <= 0.5 s (issue 22), reported, not asserted.

Problems come from --problems (a `symplan problems make` set, any depth), or, without it,
--count problems of --objects objects (k = 1-3) are made with the arm in a temporary
directory first (about 3 s each).
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

from drake_symplan.cli.options import add_planner_arguments

TARGET_S = 0.5
PHASES = ("perceive", "symbols", "plan")


def bench_problem(agent, abstraction, folder: Path, planner: str, timeout: float) -> dict:
    from drake_symplan.world.scenes import load_scene

    start, goal = load_scene(folder / "start.yaml"), load_scene(folder / "goal.yaml")
    seconds = dict.fromkeys(("show", *PHASES), 0.0)
    scenes = {}
    for key, scene in (("goal", goal), ("start", start)):
        t = time.perf_counter()
        agent.robot.reset(scene)
        seconds["show"] += time.perf_counter() - t
        t = time.perf_counter()
        scenes[key] = agent.see(scene)
        seconds["perceive"] += time.perf_counter() - t
    t = time.perf_counter()
    readings = {k: abstraction.read_scene(s.scene) for k, s in scenes.items()}
    seconds["symbols"] = time.perf_counter() - t
    found = abstraction.plan(readings["start"], readings["goal"], planner, timeout)
    seconds["plan"] = found.seconds
    lost = scenes["goal"].lost + scenes["start"].lost
    return {"problem": str(folder), "status": found.status, "plan_length": len(found.steps),
            "lost": lost, "seconds": seconds,
            "overhead": sum(seconds[p] for p in PHASES)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", type=Path, default=None,
                        help="model bundle directory (default: the shipped one)")
    parser.add_argument("--problems", type=Path, default=None)
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--objects", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    add_planner_arguments(parser)
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)

    from drake_symplan.abstraction.abstraction import Abstraction
    from drake_symplan.agent.problems import load_problems, make_problems
    from drake_symplan.agent.solve import Agent
    from drake_symplan.cli.agent_cmds import load_bundle

    bundle = load_bundle(args.model)
    abstraction = Abstraction(bundle)
    t = time.perf_counter()
    agent = Agent("arm")
    setup = time.perf_counter() - t
    with tempfile.TemporaryDirectory(prefix="bench-solve-") as tmp:
        problems_dir = args.problems
        if problems_dir is None:
            problems_dir = Path(tmp)
            make_problems(problems_dir, args.objects, [1, 2, 3], args.count, args.seed,
                          agent=agent)
        problems = load_problems(problems_dir)[:args.count]
        bench_problem(agent, abstraction, Path(problems[0]["dir"]), args.planner,
                      args.timeout)  # warm-up: imports, the renderer, the page cache
        rows = [bench_problem(agent, abstraction, Path(p["dir"]), args.planner, args.timeout)
                for p in problems]
    overhead = [r["overhead"] for r in rows]
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    result = {
        "host": {"machine": platform.machine(), "python": platform.python_version(),
                 "processor": platform.processor()},
        "model": str(bundle.path), "planner": args.planner, "problems": len(rows),
        "station_build_s": round(setup, 3),
        "overhead_median_s": round(statistics.median(overhead), 4),
        "overhead_p90_s": round(float(np.percentile(overhead, 90)), 4),
        "target_s": TARGET_S,
        "meets_target": statistics.median(overhead) <= TARGET_S,
        "median_s": {p: round(statistics.median(r["seconds"][p] for r in rows), 4)
                     for p in ("show", *PHASES)},
        "statuses": statuses,
        "rows": rows,
    }
    text = json.dumps(result, indent=2)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)  # --out may name a new folder
        args.out.write_text(text + "\n")
    if args.json:
        print(text)
    else:
        print(f"plan overhead: median {result['overhead_median_s']:.3f} s over {len(rows)} "
              f"problems (target {TARGET_S} s); per phase {result['median_s']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
