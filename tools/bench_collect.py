"""Collection benchmark: transitions/s of the `hand` and `arm` back-ends, and their parity.

For each back-end, `--runs` fresh collections of `--transitions` transitions on
`--objects`-object scenes with `--workers` workers (perception included); reports the
median end-to-end rate (worker start-up included) and the median steady rate (transitions
per second of worker time, times the workers), and where the worker time goes: seconds per
transition in physics, perception and the rest, and the rate the workers would reach if
they only simulated (`physics_only_rate_per_s`: the ceiling for any speed-up outside the
physics). `--parity-pairs N` also runs N identical (scene, action) pairs on both back-ends
(data/parity.py), agreement also apart for the pairs that carry something
(`--parity-structured`: on stacks, bridges and touching pairs, where sources carry;
`--parity-played`: on the states random play reaches; `--parity-no-twin`: the hand without
its arm twin, skills/arm_twin.py).

`--ray` compares the engines instead: per back-end, `--runs` rounds, each one collection
with the local worker processes and one with Ray worker actors on this machine (same
workers, same seed, order alternating between rounds); reports the median end-to-end rates
(worker start-up included), their ratio, the median start-up (until every worker has its
station) of each engine, and apart from those the seconds `ray.init()` took to start Ray.

    python tools/bench_collect.py --json [--out FILE] [--parity-pairs 300]
    python tools/bench_collect.py --ray --json [--backends hand] [--runs 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path


def bench_backend(backend: str, transitions: int, workers: int, objects: int, runs: int,
                  seed: int) -> dict:
    from drake_symplan.data.collect import CollectConfig, collect

    rates, steady, rows, phases = [], [], [], []
    for r in range(runs):
        with tempfile.TemporaryDirectory() as tmp:
            config = CollectConfig(backend=backend, transitions=transitions, seed=seed + r,
                                   min_objects=objects, max_objects=objects,
                                   chunk_size=max(1, transitions // (2 * workers)))
            summary = collect(Path(tmp) / "data", config, workers=workers, progress=False)
        run = summary["this_run"]
        rates.append(run["rate_per_s"])
        steady.append(transitions / (summary["worker_seconds"] / workers))
        phases.append({k: v / transitions
                       for k, v in summary["worker_seconds_by_phase"].items()})
        rows.append({"rate_per_s": run["rate_per_s"], "wall_seconds": run["wall_seconds"],
                     "steady_rate_per_s": round(steady[-1], 3),
                     "seconds_per_transition": {k: round(v, 4) for k, v in phases[-1].items()},
                     "no_effect_fraction": summary["no_effect_fraction"],
                     "dropped_fraction": summary["dropped_fraction"],
                     "dropped_reasons": summary["dropped_reasons"],
                     "outcome_fractions": summary["outcome_fractions"]})
    return {"backend": backend, "workers": workers, "objects": objects,
            "transitions_per_run": transitions, "runs": rows,
            "median_rate_per_s": round(statistics.median(rates), 3),
            "median_steady_rate_per_s": round(statistics.median(steady), 3),
            "median_seconds_per_transition": {
                k: round(statistics.median(p[k] for p in phases), 4) for k in phases[0]},
            "physics_only_rate_per_s": round(
                workers / statistics.median(p["physics"] for p in phases), 3)}


def bench_engines(backend: str, transitions: int, workers: int, objects: int, runs: int,
                  seed: int) -> dict:
    """Local worker processes against Ray actors (Ray already initialised), interleaved."""
    from drake_symplan.data.collect import CollectConfig, collect

    rows = {"local": [], "ray": []}
    for r in range(runs):
        config = CollectConfig(backend=backend, transitions=transitions, seed=seed + r,
                               min_objects=objects, max_objects=objects,
                               chunk_size=max(1, transitions // (2 * workers)))
        for engine in ("local", "ray") if r % 2 == 0 else ("ray", "local"):
            with tempfile.TemporaryDirectory() as tmp:
                run = collect(Path(tmp) / "data", config, workers=workers, progress=False,
                              ray_address="" if engine == "ray" else None)["this_run"]
            rows[engine].append({k: run[k] for k in ("rate_per_s", "wall_seconds",
                                                     "startup_seconds")})
    med = {e: {k: round(statistics.median(row[k] for row in rs), 3) for k in rs[0]}
           for e, rs in rows.items()}
    return {"backend": backend, "workers": workers, "objects": objects,
            "transitions_per_run": transitions, "rounds": rows,
            "median_local_rate_per_s": med["local"]["rate_per_s"],
            "median_ray_rate_per_s": med["ray"]["rate_per_s"],
            "ray_over_local": round(med["ray"]["rate_per_s"] / med["local"]["rate_per_s"], 3),
            "median_local_startup_seconds": med["local"]["startup_seconds"],
            "median_ray_startup_seconds": med["ray"]["startup_seconds"]}


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--objects", type=int, default=4)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--hand-transitions", type=int, default=200)
    parser.add_argument("--arm-transitions", type=int, default=40)
    parser.add_argument("--backends", default="hand,arm")
    parser.add_argument("--parity-pairs", type=int, default=0)
    parser.add_argument("--parity-structured", action="store_true",
                        help="parity on structured scenes of 3-5 objects (stacks, bridges), "
                             "where sources carry something")
    parser.add_argument("--parity-played", action="store_true",
                        help="parity on the states random play reaches (data/parity.py)")
    parser.add_argument("--parity-no-twin", action="store_true",
                        help="the hand without its arm twin (as before skills/arm_twin.py)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--ray", action="store_true",
                        help="compare Ray actors with the local workers on this machine")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", help="also write the JSON result here")
    return parser.parse_args(argv)


def run_benchmarks(args: argparse.Namespace) -> dict:
    """Each back-end's rate (local workers, or local against Ray with --ray), and parity."""
    result: dict = {"backends": {}}
    sizes = {"hand": args.hand_transitions, "arm": args.arm_transitions}
    bench = bench_backend
    if args.ray:
        import ray

        t0 = time.perf_counter()
        # Ray's workers run at nice 15 by default; at 0, as the local workers, both engines
        # get the same share of a host that other jobs use too.
        ray.init(num_cpus=args.workers, include_dashboard=False, log_to_driver=False,
                 _system_config={"worker_niceness": 0})
        result["ray_init_seconds"] = round(time.perf_counter() - t0, 2)
        result["ray_worker_niceness"] = 0
        bench = bench_engines
    for backend in [b for b in args.backends.split(",") if b]:
        result["backends"][backend] = bench(
            backend, sizes[backend], args.workers, args.objects, args.runs, args.seed)
    if args.parity_pairs > 0:
        from drake_symplan.data.parity import measure_parity

        t0 = time.perf_counter()
        parity = measure_parity(args.parity_pairs, seed=args.seed, progress=not args.json,
                                played=args.parity_played, arm_twin=not args.parity_no_twin,
                                **({"structured": True, "objects": (3, 5)}
                                   if args.parity_structured else {}))
        parity.pop("rows")
        parity["seconds"] = round(time.perf_counter() - t0, 1)
        result["parity"] = parity
    return result


def print_summary(result: dict, ray: bool) -> None:
    for name, b in result["backends"].items():
        if ray:
            print(f"{name}: local {b['median_local_rate_per_s']}/s, Ray "
                  f"{b['median_ray_rate_per_s']}/s (x{b['ray_over_local']}); start-up "
                  f"{b['median_local_startup_seconds']} s / "
                  f"{b['median_ray_startup_seconds']} s ({b['workers']} workers)")
        else:
            print(f"{name}: {b['median_rate_per_s']}/s end to end, "
                  f"{b['median_steady_rate_per_s']}/s steady ({b['workers']} workers)")
    if "parity" in result:
        p = result["parity"]
        print(f"parity: {p['pairs']} pairs, class agreement {p['class_agreement']} "
              f"(carrying something: {p['carrying']['class_agreement']} on "
              f"{p['carrying']['pairs']}, the rest: {p['not_carrying']['class_agreement']}), "
              f"effect diff median {p['effect_diff_median_m']} m")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    result = run_benchmarks(args)
    text = json.dumps(result, indent=2)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)  # --out may name a new folder
        Path(args.out).write_text(text)
    if args.json:
        print(text)
    else:
        print_summary(result, args.ray)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
