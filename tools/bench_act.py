"""Benchmark: wall seconds per full-physics pick/place (IK + simulation), 4- and 8-object scenes.

    python tools/bench_act.py --json [--actions 20] [--out bench_act.json]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time

import numpy as np

from drake_symplan.skills.pick_place import PickPlacePlanner, pick_place
from drake_symplan.structs import OFFSETS, Action, ObjectState
from drake_symplan.world.scenes import sample_scene
from drake_symplan.world.station import Station


def bench(num_objects: int, actions: int, seed: int) -> dict:
    station, planner = Station(), PickPlacePlanner()
    rng = np.random.default_rng(seed)
    seconds, cpu_seconds, sim_seconds, statuses = [], [], [], {}
    # One warm-up action: first-call costs (hydroelastic meshes, SNOPT setup) are not per-action.
    for i in range(actions + 1):
        scene = sample_scene(rng, num_objects)
        station.reset(scene)
        src, tgt = rng.choice(scene.names, size=2, replace=False)
        action = Action(str(src), str(rng.choice(OFFSETS)), str(tgt), str(rng.choice(OFFSETS)))
        # The sampled scene is the caller's belief (perception is benchmarked separately).
        beliefs = {o.name: ObjectState(o.name, o.type, np.array(o.position), o.yaw)
                   for o in scene.objects}
        t, c = time.perf_counter(), time.process_time()
        out = pick_place(station, planner, action, beliefs)
        dt, dc = time.perf_counter() - t, time.process_time() - c
        if i == 0:
            continue
        statuses[out.status] = statuses.get(out.status, 0) + 1
        if out.status == "ok":
            seconds.append(dt)
            cpu_seconds.append(dc)
            sim_seconds.append(station.context.get_time())
    return {
        "objects": num_objects,
        "actions": len(seconds),
        "median_s": statistics.median(seconds),
        "p90_s": float(np.percentile(seconds, 90)),
        "median_cpu_s": statistics.median(cpu_seconds),
        "median_simulated_s": statistics.median(sim_seconds),
        "statuses": statuses,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--actions", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", default="bench_act.json")
    args = parser.parse_args()
    result = {
        "benchmark": "act",
        "machine": platform.processor() or platform.machine(),
        "peer_pybullet_s_per_action": 1.0,
        "results": [bench(n, args.actions, args.seed) for n in (4, 8)],
    }
    with open(args.out, "w") as f:
        json.dump(result, f, indent=2)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for r in result["results"]:
            print(f"{r['objects']} objects: {r['median_s']:.3f} s median over {r['actions']}")


if __name__ == "__main__":
    main()
