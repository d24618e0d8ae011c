"""Benchmark: does what rides on a carried box stay on it? The carry suite, on both back-ends.

    python tools/bench_carry.py --json [--yaws 0,90,rand] [--scenes NAME,..] [--onto rider]
        [--belief truth|none|realsense|heavy] [--out bench_carry.json]

Five scenes, each a base box with riders beside a target long block: a cube on a long
block at -9, 0 and +9 cm along its length, a two-cube tower, two cubes on a long block
(`--scenes` may also name the harder `hanging` and `tall_p9`, evaluation/carry.HARD).
Every scene is also run yawed as a whole about the midpoint between base and target
(`--yaws`: degrees, `rand` a seeded random yaw in [-30, 30]). Each scene runs the nine
actions pick(base, grasp) place(target, release) on the `hand` and on the `arm`, planned
from the scene itself (`--belief truth`, the default) or from the scene as the depth cameras
perceive it with a sensor model (`--belief realsense`: what the arm plans from in the
closed loop; each row's `belief_error_mm` is the worst box's), and judges from
the simulator's poses after the action (ground truth: this is a benchmark) whether every
rider still rests on the base (`kept`). `--onto rider` places the base on its own first
rider instead: the stack shifted sideways by the offsets (the careful carry lowers it to
the table), an action random play picks often. Per scene: actions whose grasp lifted the base,
the kept counts per back-end, and the share of actions where hand and arm agree.
"""

from __future__ import annotations

import argparse
import json
import platform

import numpy as np

from drake_symplan.evaluation.carry import ONTO, SCENES, SUITE, Runner, bench_scene
from drake_symplan.world.depth_sensor import CAMERA_NOISE


def _yaws(text: str, seed: int) -> list[float]:
    rng = np.random.default_rng(seed)
    return [float(rng.uniform(-30.0, 30.0)) if y == "rand" else float(y) for y in text.split(",")]


def totals(results: list[dict]) -> dict:
    """Kept and agreeing actions over every scene, per yaw and in all."""
    out = {}
    for key in sorted({r["yaw_deg"] for r in results}) + ["all"]:
        rs = [r for r in results if key == "all" or r["yaw_deg"] == key]
        n = sum(r["actions"] for r in rs)
        out[str(key)] = {"actions": n,
                         "hand_kept": sum(r["kept"]["hand"] for r in rs),
                         "arm_kept": sum(r["kept"]["arm"] for r in rs),
                         "agree": sum(round(r["agreement"] * r["actions"]) for r in rs)}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--yaws", default="0,90,rand",
                        help="comma-separated scene yaws in degrees; 'rand': a seeded random one")
    parser.add_argument("--scenes", default=",".join(SUITE),
                        help=f"comma-separated scenes of {sorted(SCENES)}")
    parser.add_argument("--onto", choices=sorted(ONTO), default="target",
                        help="place the base on the target block, or on its first rider "
                             "(the stack shifted by the offsets)")
    parser.add_argument("--belief", choices=["truth", *CAMERA_NOISE], default="truth",
                        help="plan from the scene as built, or as perceived with this sensor")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", default="bench_carry.json")
    args = parser.parse_args()
    runner = Runner(args.belief, camera_seed=args.seed)
    results = []
    for yaw in _yaws(args.yaws, args.seed):
        for name in args.scenes.split(","):
            r = bench_scene(runner, name, yaw, args.onto)
            results.append(r)
            if not args.json:
                print(f"{name:10s} yaw {yaw:6.1f}: kept hand {r['kept']['hand']}/9 "
                      f"arm {r['kept']['arm']}/9, agree {r['agreement']:.2f}, "
                      f"arm {r['arm_cpu_s']} s CPU/action", flush=True)
    out = {"benchmark": "carry", "machine": platform.processor() or platform.machine(),
           "belief": args.belief, "seed": args.seed,
           "totals": totals(results), "results": results}
    with open(args.out, "w") as f:
        json.dump(out, f, indent=2)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(json.dumps(out["totals"], indent=2))


if __name__ == "__main__":
    main()
