"""Benchmark: perception accuracy and speed against the simulator's ground truth.

    python tools/bench_perception.py --json [--scenes 200] [--transitions 100] [--out FILE]
        [--camera-noise none|realsense|heavy ...] [--problems DIR]

Scenes of 2-8 objects built from arrangement units (single boxes with yaw jitter, towers,
cubes on one or both ends of a long block, bridges, touching pairs, blocks that tip), each
settled by physics before it is perceived. Identity association is measured on pick/place
transitions executed by the arm on perceived beliefs. `--camera-noise` picks the depth
sensor's model (world/depth_sensor.py; its calibration error is drawn from --seed); given
several (`--camera-noise none realsense`), each is benchmarked on the same scenes and
`cost_over_none` says what perception costs under each against none (median wall and CPU
time, on a shared machine CPU time the steadier; and both without the sensing, the cost of
perceiving a real camera's frames). Each scene is perceived under every model in turn, so
that a shared machine's load weighs on all alike.
`perceive_ms` splits each perception into its stages: sensing (the station's frames: the
rendering and the sensor model, a simulator's cost), clouds (the depth filter: what a real
camera's frames cost too) and fitting.
`--problems DIR` perceives the start and goal scenes of a problem set (`symplan problems
make`) instead of sampled ones: tall towers of blocks and cubes, as the solves see them.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from drake_symplan.actions import OFFSETS, Action
from drake_symplan.evaluation.perception import compare, match_to_truth
from drake_symplan.perception.association import associate
from drake_symplan.perception.perceive import Perceiver, station_views
from drake_symplan.perception.segmentation import CROP_X, CROP_Y
from drake_symplan.skills.pick_place import PickPlaceMotions, pick_place
from drake_symplan.world.cameras import DepthNoise, default_cameras
from drake_symplan.world.depth_sensor import CAMERA_NOISE
from drake_symplan.world.scenes import load_scene, sample_structured_scene
from drake_symplan.world.station import Station, StationConfig


def bench_scenes(models: dict, n_scenes: int, seed: int, noise: DepthNoise,
                 scenes: list | None = None) -> dict:
    """Each sensor model's (`models`: name -> (station, perceiver)) benchmark on the same
    scenes, perceived side by side (every scene under each model in turn, so that a shared
    machine's load weighs on all alike); `scenes`, where given, instead of `n_scenes`
    sampled ones."""
    rng = np.random.default_rng(seed)  # the scenes
    noise_rng = {name: np.random.default_rng(seed + 2) for name in models}  # `noise`'s draws
    tallies = {name: _Tally() for name in models}
    n_scenes = len(scenes) if scenes else n_scenes
    for i in tqdm(range(n_scenes), desc="scenes"):
        scene = scenes[i] if scenes else sample_structured_scene(rng, 2 + i % 7)
        for name, (station, perceiver) in models.items():
            station.reset(scene)
            station.settle(0.8)
            # Perceiver.perceive, its sensing (the simulator's) timed apart.
            t, c = time.perf_counter(), time.process_time()
            views = station_views(station, perceiver.depth_filter.frames)
            sensed = time.perf_counter() - t, time.process_time() - c
            perceived = perceiver.perceive_views(views, noise, noise_rng[name])
            tallies[name].add(i, scene, (time.perf_counter() - t, time.process_time() - c),
                              sensed, perceiver.stage_seconds,
                              compare(perceived, station.object_states(), station.contact_graph()))
    return {name: tally.result() for name, tally in tallies.items()}


class _Tally:
    """One sensor model's scenes: errors, counts, failures and times."""

    def __init__(self):
        self.pos, self.yaw, self.type_ok, self.count_ok, self.contacts_ok = [], [], [], [], []
        self.wall, self.cpu, self.stages, self.failures = [], [], {}, []
        self.without_sensing_cpu = []
        self.invented = self.missed = 0

    def add(self, i: int, scene, took: tuple, sensed: tuple, stages: dict, r: dict) -> None:
        """Scene i's perception: `took` and `sensed` (its sensing) as (wall, CPU) seconds,
        `stages` (Perceiver.stage_seconds), `r` (evaluation.perception.compare)."""
        self.wall.append(took[0])
        self.cpu.append(took[1])
        # Without the sensing: what perceiving a real camera's frames costs.
        for stage, seconds in {"sensing": sensed[0], **stages,
                               "without_sensing": took[0] - sensed[0]}.items():
            self.stages.setdefault(stage, []).append(seconds)
        self.without_sensing_cpu.append(took[1] - sensed[1])
        for e in r["errors"].values():
            self.pos.append(e["position_mm"])
            self.yaw.append(e["yaw_deg"])
            self.type_ok.append(e["type_ok"])
        self.count_ok.append(r["count_ok"])
        self.contacts_ok.append(r["contacts_ok"])
        self.invented += r["invented"]
        self.missed += r["missed"]
        if not (r["count_ok"] and r["contacts_ok"]):
            self.failures.append({"scene": i, "names": [f"{o.name}:{o.type}" for o in scene.objects],
                                  "count_ok": r["count_ok"], "contacts_ok": r["contacts_ok"]})

    def result(self) -> dict:
        pos, yaw = self.pos, self.yaw
        return {
            "scenes": len(self.wall),
            "objects": len(pos),
            "position_error_mm": {"median": float(np.median(pos)),
                                  "p95": float(np.percentile(pos, 95))},
            "yaw_error_deg": {"median": float(np.median(yaw)),
                              "p95": float(np.percentile(yaw, 95))},
            "type_accuracy": float(np.mean(self.type_ok)),
            "count_exact_fraction": float(np.mean(self.count_ok)),
            "contact_graph_exact_fraction": float(np.mean(self.contacts_ok)),
            "invented_objects": self.invented,
            "missed_objects": self.missed,
            "perceive_ms": {"median_wall": 1000 * statistics.median(self.wall),
                            "median_cpu": 1000 * statistics.median(self.cpu),
                            "median_without_sensing_cpu":
                                1000 * statistics.median(self.without_sensing_cpu),
                            **{f"median_{k}_wall": 1000 * statistics.median(v)
                               for k, v in self.stages.items()}},
            "failures": self.failures[:20],
        }


def bench_association(station, perceiver, n: int, seed: int) -> dict:
    """Identity association on arm-executed transitions, checked against ground truth."""
    rng = np.random.default_rng(seed + 1)
    planner = PickPlaceMotions()
    correct, total, skipped, left_view = 0, 0, 0, 0
    failures = []
    with tqdm(total=n, desc="transitions") as bar:
        while total < n:
            scene = sample_structured_scene(rng, int(rng.integers(2, 5)))
            station.reset(scene)
            station.settle(0.8)
            before = perceiver.perceive(station)
            truth_before = match_to_truth(before, station.object_states())
            if len(before.objects) < 2:
                skipped += 1
                continue
            src, tgt = rng.choice(before.names, size=2, replace=False)
            action = Action(str(src), str(rng.choice(OFFSETS)), str(tgt),
                            str(rng.choice(OFFSETS)))
            out = pick_place(station, planner, action, before.object_states())
            if out.status != "ok":
                skipped += 1
                continue
            truth = station.object_states()
            if any(not _in_view(s.position) for s in truth.values()):
                left_view += 1  # an object left the workspace: nothing to associate it with
                continue
            after = perceiver.perceive(station, prior=before)  # tracked, as in use
            truth_after = match_to_truth(after, truth)
            mapping = associate(before, after, action)
            ok = all(truth_after.get(mapping.get(b)) == g for b, g in truth_before.items())
            correct += ok
            if not ok:
                failures.append({
                    "action": str(action),
                    "before": {o.name: [o.type, *np.round(o.position, 3).tolist()]
                               for o in before.objects},
                    "after": {o.name: [o.type, *np.round(o.position, 3).tolist()]
                              for o in after.objects},
                    "mapping": mapping, "truth_before": truth_before,
                    "truth_after": truth_after})
            total += 1
            bar.update(1)
    return {"transitions": total, "correct_fraction": correct / total,
            "skipped_infeasible": skipped, "object_left_workspace": left_view,
            "failures": failures}


def _in_view(p) -> bool:
    return CROP_X[0] < p[0] < CROP_X[1] and CROP_Y[0] < p[1] < CROP_Y[1] and p[2] > -0.01


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=200)
    parser.add_argument("--transitions", type=int, default=100)
    parser.add_argument("--noise", type=float, default=0.0)
    parser.add_argument("--dropout", type=float, default=0.0)
    parser.add_argument("--camera-noise", choices=tuple(CAMERA_NOISE), nargs="+",
                        default=["none"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", default="bench_perception.json")
    parser.add_argument("--problems", help="perceive this problem set's start and goal scenes")
    args = parser.parse_args()
    problems = [load_scene(f) for d in sorted(Path(args.problems).rglob("problem.json"))
                for f in (d.parent / "start.yaml", d.parent / "goal.yaml")] \
        if args.problems else None
    runs = bench_all(args, problems)
    result = {
        "benchmark": "perception",
        "cameras": [c.name for c in default_cameras()],
        "noise": {"sigma": args.noise, "dropout": args.dropout},
        "camera_noise": args.camera_noise[0] if len(runs) == 1 else args.camera_noise,
        "cpu_threads_env": os.environ.get("LP_NUM_THREADS"),
    }
    if len(runs) == 1:
        result.update(runs[args.camera_noise[0]])
    else:
        result["by_camera_noise"] = runs
        if "none" in runs and args.scenes:
            clean = runs["none"]["scenes"]["perceive_ms"]
            result["cost_over_none"] = {
                name: {k: round(r["scenes"]["perceive_ms"][f"median_{k}"] / clean[f"median_{k}"], 2)
                       for k in ("wall", "cpu", "without_sensing_wall", "without_sensing_cpu")}
                for name, r in runs.items()}
    with open(args.out, "w") as f:
        json.dump(result, f, indent=2)
    print(json.dumps(result, indent=2) if args.json else json.dumps(summary(result)))


def bench_all(args, problems) -> dict:
    """The scenes' benchmark under every sensor model, side by side, then each one's
    association's."""
    models = {}
    for name in args.camera_noise:
        station = Station(StationConfig(cameras=default_cameras(), camera_noise=name,
                                        camera_seed=args.seed))
        perceiver = Perceiver()
        station.reset(sample_structured_scene(np.random.default_rng(0), 2))
        perceiver.perceive(station)  # renderer start-up is not per-state cost
        models[name] = station, perceiver
    runs = {name: {} for name in models}
    if args.scenes:
        scenes = bench_scenes(models, args.scenes, args.seed,
                              DepthNoise(args.noise, args.dropout), problems)
        for name in models:
            runs[name]["scenes"] = scenes[name]
    if args.transitions:
        for name, (station, perceiver) in models.items():
            runs[name]["association"] = bench_association(station, perceiver,
                                                          args.transitions, args.seed)
    return runs


def summary(result: dict) -> dict:
    """The result without its failures (one run's, or each sensor model's)."""
    def brief(run: dict) -> dict:
        return {part: {k: v for k, v in run[part].items() if k != "failures"}
                for part in ("scenes", "association") if part in run}

    if "by_camera_noise" not in result:
        return brief(result)
    return {"by_camera_noise": {n: brief(r) for n, r in result["by_camera_noise"].items()},
            "cost_over_none": result.get("cost_over_none")}

if __name__ == "__main__":
    main()
