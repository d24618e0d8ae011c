"""`symplan curve`: random against active exploration by data size, on one held-out set.

Each explorer's training set is one collection (the scale's data recipe, seed 12) extended
size by size, so a point at N is the first N transitions of it (a view of its first shards,
data/storage.link_head): active at 5k is exactly the first 5k of active at 50k. Every
point is trained with the same settings (Relational DeepSym, invariant), gets effect-first
operators, and is evaluated on the same random held-out set (seed 97): coverage,
precision, solved k = 1-3 at the symbolic level. Optionally the arm: one size of active
against one of random on the same problems (2, 3 and 4 objects, k = 1-3). Writes
OUT/results/curve.md, curve.json and curve.png; resumable like `symplan reproduce`.
"""

from __future__ import annotations

import json
from pathlib import Path

from drake_symplan.atomic import write_atomic
from drake_symplan.json_files import read_json
from drake_symplan.pipelines.scales import Scale, load_scale
from drake_symplan.pipelines.stages import Stage, StageRunner

EXPLORERS = ("random", "active")
MODEL = ["--model", "relational", "--model-option", "invariant=true"]


class LearningCurve(StageRunner):
    """The stages of one scale in `out` (a name in configs/scales.yaml, or a Scale);
    `run()` runs what is not done yet."""

    def __init__(self, scale: str | Scale, out: Path, jobs: int = 2, ray: str | None = None,
                 say=print, device: str = "auto"):
        self.name, self.scale = load_scale("curve", scale)  # first: a bad name makes nothing
        super().__init__(out, jobs, say)
        self.ray = ray
        self.device = device  # where the train stages and the active rounds train
        self.heldout_data, self.results = self.out / "data/heldout", self.out / "results"

    def data(self, explorer: str) -> Path:
        return self.out / "data" / explorer

    def sizes(self, explorer: str) -> tuple[int, ...]:
        s = self.scale
        return tuple(sorted(s.sizes + (s.random_only if explorer == "random" else ())))

    def seeds(self, size: int) -> tuple[int, ...]:
        return self.scale.seeds if size in self.scale.multi_seed else self.scale.seeds[:1]

    def run_dir(self, explorer: str, size: int, seed: int) -> Path:
        return self.out / "runs" / f"{explorer}_{size}_s{seed}"

    # --- the stages -------------------------------------------------------------

    def collect_stage(self, explorer: str | None, size: int) -> Stage:
        """Collects (extends) an explorer's set to `size`; None: the held-out set."""
        s = self.scale
        data = self.heldout_data if explorer is None else self.data(explorer)
        seed = s.heldout_seed if explorer is None else s.train_seed
        workers = ["--ray", *([self.ray] if self.ray else [])] if self.ray is not None \
            else ["--workers", self.jobs]
        options = [*s.active, "--device", self.device] if explorer == "active" else []
        argv = ["collect", "--recipe", s.recipe, "--transitions", size, "--out", data,
                "--seed", seed, "--objects", s.objects, "--chunk-size", s.chunk_size,
                *(["--explorer", "active", *options] if explorer == "active" else []),
                "--no-progress", "--json", *workers]
        done = data / f"collected_{size}.json"
        return Stage(f"collect {explorer or 'held-out'} {size}", argv, done, stdout=done)

    def point_stages(self, explorer: str, size: int, seed: int) -> tuple[Stage, ...]:
        """Train, learn operators, evaluate them on the held-out set: one point."""
        s, run = self.scale, self.run_dir(explorer, size, seed)
        view, bundle = run / "data", run / "bundle_effect"
        return (
            Stage(f"train {run.name}", ["train", *MODEL, "--data", view, "--out", run,
                                        "--seed", seed, "--epochs", s.epochs, "--patience",
                                        s.patience, "--threads", 1, "--device",
                                        self.device, "--no-progress"],
                  run / "metrics.json", partial=run / "last.pt", resume=("--resume",)),
            Stage(f"bundle {run.name}", ["bundle", "--run", run, "--data", view, "--out",
                                         bundle, "--min-count", s.min_count],
                  bundle / "operators.json"),
            Stage(f"eval operators {run.name}",
                  ["eval", "operators", "--model", bundle, "--data", self.heldout_data,
                   "--max-problems", s.operator_problems, "--familiar-data", view,
                   "--out", bundle / "eval.json"],
                  bundle / "eval.json"))

    def arm_stages(self) -> list[Stage]:
        """Problems of 2, 3, 4 objects, k = 1-3, solved with both compared sizes' bundles;
        reproducible goals only, so that every failure is the model's (docs/planning.md)."""
        s = self.scale
        if s.arm is None:
            return []
        stages = []
        for n in (2, 3, 4):
            folder = self.out / "problems" / f"o{n}"
            stages.append(Stage(f"problems {n} objects",
                                ["problems", "make", "--out", folder, "--objects", n, "--k",
                                 1, 2, 3, "--count", s.arm_problems, "--seed",
                                 s.problem_seed + n, "--backend", "arm", "--reproducible",
                                 "--json"],
                                folder / "done.json", stdout=folder / "done.json"))
        runs = [self.run_dir(e, size, seed) / "bundle_effect"
                for e, size in zip(EXPLORERS[::-1], s.arm, strict=True)
                for seed in self.seeds(size)]
        ray = [] if self.ray is None else ["--ray", *([self.ray] if self.ray else [])]
        out = self.results / "planning"
        stages.append(Stage("eval planning", [
            "eval", "planning", "--runs", *runs, "--problems", self.out / "problems",
            "--records", out.with_suffix(".jsonl"), "--monitor", "on", "--json", *ray],
            out.with_suffix(".json"), stdout=out.with_suffix(".json")))
        return stages

    # --- running ----------------------------------------------------------------

    def run(self) -> Path:
        """Runs every stage not done yet, point by point as data grows; writes the table."""
        from drake_symplan.data.storage import link_head

        self.results.mkdir(parents=True, exist_ok=True)
        self.say(f"curve --scale {self.name} in {self.out}")
        self._run(self.collect_stage(None, self.scale.heldout))
        sizes = sorted(set(self.sizes("random")) | set(self.sizes("active")))
        for size in sizes:  # both explorers' points, size by size
            for explorer in (e for e in EXPLORERS if size in self.sizes(e)):
                if self._collected(explorer) < size:
                    self._run(self.collect_stage(explorer, size))
                points = []
                for seed in self.seeds(size):
                    link_head(self.data(explorer), self.run_dir(explorer, size, seed) / "data",
                              size)
                    points.append(self.point_stages(explorer, size, seed))
                self._parallel(points)
        for stage in self.arm_stages():
            self._run(stage)
        return self.report()

    def _collected(self, explorer: str) -> int:
        """Transitions an explorer's finished collection holds (0: none yet): a smaller
        point is a view of a larger set, never a collection of its own."""
        from drake_symplan.data.storage import MANIFEST, read_manifest

        if not (self.data(explorer) / MANIFEST).is_file():
            return 0
        manifest = read_manifest(self.data(explorer))
        return manifest["config"]["transitions"] if manifest.get("status") == "complete" \
            else 0

    def report(self) -> Path:
        """curve.json, curve.md and curve.png from the points evaluated so far."""
        from drake_symplan.pipelines.results_tables import (
            collect_operator_reports,
            operators_markdown,
            planning_markdown,
            summarise_operators,
            summarise_planning,
        )

        table = summarise_operators(collect_operator_reports(self.out / "runs"))
        points = sorted((EXPLORERS.index(name.split("_")[0]), int(name.split("_")[1]), entry)
                        for name, entry in ((n.split("/")[0], e) for n, e in table.items()))
        table = {f"{EXPLORERS[e]} {size}": entry for e, size, entry in points}
        rows = {f"{EXPLORERS[e]}_{size}": entry for e, size, entry in points}
        planning = self.results / "planning.json"
        arm = summarise_planning(read_json(planning)) \
            if planning.is_file() else None
        write_atomic(self.results / "curve.json", json.dumps(
            {"scale": self.scale.settings("curve"), "points": rows, "arm": arm}, indent=1))
        text = [f"# Learning curve ({self.name})", "",
                "Held-out set: random, seed "
                f"{self.scale.heldout_seed}, {self.scale.heldout} transitions. Rows: "
                "explorer and transitions (mean ± std over seeds, %).", "",
                operators_markdown(table).replace("model / operators", "explorer, size")]
        if arm is not None:
            text += ["", "## In the arm", "", planning_markdown(arm)]
        path = write_atomic(self.results / "curve.md", "\n".join(text) + "\n")
        if rows:
            plot_curve(rows, self.results / "curve.png")
        return path


def plot_curve(rows: dict, path: Path) -> None:
    """Coverage, precision and solved k = 1-3 against transitions, one line per explorer."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = [("coverage", "coverage"), ("precision", "precision")]
    metrics += [(f"solved_k{k}", f"solved, k={k}") for k in (1, 2, 3)]
    fig, axes = plt.subplots(1, len(metrics), figsize=(4 * len(metrics), 3.2))
    for explorer in EXPLORERS:
        points = sorted((int(name.split("_")[1]), e) for name, e in rows.items()
                        if name.split("_")[0] == explorer)
        if not points:
            continue
        sizes = [n for n, _ in points]
        for ax, (key, title) in zip(axes, metrics, strict=True):
            if key not in points[0][1]:
                continue
            mean = [100 * e[key]["mean"] for _, e in points]
            std = [100 * e[key]["std"] for _, e in points]
            ax.errorbar(sizes, mean, yerr=std, marker="o", capsize=3, label=explorer)
            ax.set_xscale("log")
            ax.set_title(title)
            ax.set_xlabel("transitions")
    axes[0].set_ylabel("%")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
