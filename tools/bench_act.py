"""Benchmark: seconds per full-physics pick/place (IK + simulation), 4- and 8-object scenes,
and where the moved box lands (the physics' placement accuracy, from the simulator).

    python tools/bench_act.py --json [--actions 20] [--rounds 3] [--out bench_act.json]

Per action: wall and CPU seconds, simulated seconds, and for the boxes that land on their
target (centre within LANDED_CM of the intended height) the horizontal distance from where
the action put its grasp point over the target's release point. Medians over all rounds.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time

import numpy as np

from drake_symplan.actions import OFFSET_METRES, OFFSETS, Action
from drake_symplan.datasets import ObjectState
from drake_symplan.skills.geometry import action_geometry
from drake_symplan.skills.pick_place import PickPlaceMotions, pick_place
from drake_symplan.world.scenes import sample_scene
from drake_symplan.world.station import Station

LANDED_CM = 1.0


def placement(action: Action, beliefs: dict, end: dict) -> tuple[bool, float]:
    """(landed on the target, horizontal placement error in cm) of the moved box."""
    g = action_geometry(action, beliefs)
    aim = g.release[:2] - np.array([0.0, OFFSET_METRES[action.grasp]])
    z_aim = g.release[2] - 0.004  # RELEASE_CLEARANCE: the box's centre rests that much lower
    got = end[action.source].position
    landed = abs(got[2] - z_aim) * 100 <= LANDED_CM
    return landed, float(np.linalg.norm(got[:2] - aim) * 100)


def bench(num_objects: int, actions: int, seed: int) -> dict:
    station, planner = Station(), PickPlaceMotions()
    rng = np.random.default_rng(seed)
    seconds, cpu_seconds, sim_seconds, statuses, errors = [], [], [], {}, []
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
            landed, error = placement(action, beliefs, station.object_states())
            if landed:
                errors.append(error)
    return {
        "objects": num_objects,
        "actions": len(seconds),
        "median_s": statistics.median(seconds),
        "p90_s": float(np.percentile(seconds, 90)),
        "median_cpu_s": statistics.median(cpu_seconds),
        "median_simulated_s": statistics.median(sim_seconds),
        "statuses": statuses,
        "landed": len(errors),
        "placement_errors_cm": [round(e, 3) for e in errors],
    }


def combine(rounds: list[dict]) -> dict:
    """Medians over rounds' medians; placements pooled."""
    errors = [e for r in rounds for e in r["placement_errors_cm"]]
    return {
        "objects": rounds[0]["objects"],
        "rounds": len(rounds),
        "median_s": statistics.median(r["median_s"] for r in rounds),
        "median_cpu_s": statistics.median(r["median_cpu_s"] for r in rounds),
        "round_cpu_s": [round(r["median_cpu_s"], 4) for r in rounds],
        "median_simulated_s": statistics.median(r["median_simulated_s"] for r in rounds),
        "ok": sum(r["actions"] for r in rounds),
        "landed": len(errors),
        "median_placement_error_cm": statistics.median(errors) if errors else None,
        "p90_placement_error_cm": float(np.percentile(errors, 90)) if errors else None,
        "placement_errors_cm": errors,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--actions", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rounds", type=int, default=1,
                        help="rounds of 4 then 8 objects, each on seed + round")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", default="bench_act.json")
    args = parser.parse_args()
    result = {
        "benchmark": "act",
        "machine": platform.processor() or platform.machine(),
        "peer_pybullet_s_per_action": 1.0,
    }
    rounds = {4: [], 8: []}
    for r in range(args.rounds):
        for n in rounds:
            rounds[n].append(bench(n, args.actions, args.seed + r))
    result["results"] = [combine(rounds[n]) for n in rounds]
    with open(args.out, "w") as f:
        json.dump(result, f, indent=2)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for r in result["results"]:
            print(f"{r['objects']} objects: {r['median_s']:.3f} s, {r['median_cpu_s']:.3f} s CPU "
                  f"median over {r['ok']}; placement {r['median_placement_error_cm']} cm "
                  f"median over {r['landed']} landed")


if __name__ == "__main__":
    main()
