"""`symplan reproduce`: every table and figure of the results from nothing, in one resumable run.

Each stage is a `symplan` child process whose command line is recorded: collect a training
and a held-out data set (the scale's data recipe, two seeds), train Table I's three models,
learn operators for every RelationalDeepSym and Attentive run (effect-first; the paper's
learner beside it on RelationalDeepSym, the baseline row), evaluate the effects (Table I),
the operators and the continuous model's rollouts on the held-out episodes, make arm
problems and solve them with every bundle monitored, then with the first seed's Relational
bundle in the other planning modes, the oracle and open loop. The scales are
configs/scales.yaml (pipelines/scales.py). A stage whose output is there is skipped, so
the same command resumes an interrupted run. OUT/results.md holds the tables, the JSON and PNG files
lie beside it, OUT/provenance.json records commands, seeds, data fingerprints, package
versions and the host.
"""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

# `symplan` imports this module to build its parser, so the stages' code (results tables,
# collection: Drake and torch) is imported inside the functions that need it.
from drake_symplan.agent.config import DEFAULT_SOLVE, SolveConfig
from drake_symplan.agent.planning_modes import PLANNING_MODES
from drake_symplan.atomic import write_atomic
from drake_symplan.json_files import read_json
from drake_symplan.pipelines.scales import Scale, load_scale
from drake_symplan.pipelines.stages import Stage, StageFailed, StageRunner
from drake_symplan.shards import fingerprint

__all__ = ["Reproduction", "Scale", "Stage", "StageFailed"]


MODELS = {  # Table I's three models; RelationalDeepSym in its permutation-invariant form
    "relational": ["--model", "relational", "--model-option", "invariant=true"],
    "attentive": ["--model", "attentive"],
    "deepsym": ["--model", "deepsym"],
}
LEARNERS = {"relational": ("effect", "paper"), "attentive": ("effect",)}
MODE_ROWS = tuple(n for n, m in PLANNING_MODES.items() if m.reproduced)  # on seed 0's problems


class Reproduction(StageRunner):
    """The stages of one scale in `out` (a name in configs/scales.yaml, or a Scale);
    `run()` runs what is not done yet."""

    def __init__(self, scale: str | Scale, out: Path, jobs: int = 2, ray: str | None = None,
                 say=print, solve: SolveConfig = DEFAULT_SOLVE, device: str = "auto",
                 camera_noise: str = "none"):
        self.name, self.scale = load_scale("reproduce", scale)  # first: a bad name makes nothing
        super().__init__(out, jobs, say)
        self.ray, self.solve, self.device = ray, solve, device  # device: the train stages'
        # The depth sensor every perceiving stage runs with (world/depth_sensor.py).
        self.camera_noise = camera_noise
        self.train_data, self.heldout_data = self.out / "data/train", self.out / "data/heldout"
        self.results = self.out / "results"

    # --- the stages -------------------------------------------------------------

    def _ray(self) -> list[str]:
        return [] if self.ray is None else ["--ray", self.ray] if self.ray else ["--ray"]

    def _sensor(self) -> list[str]:
        """The perceiving stages' --camera-noise (none: no flag, as before the option)."""
        return [] if self.camera_noise == "none" else ["--camera-noise", self.camera_noise]

    def collect_stages(self) -> list[Stage]:
        s = self.scale

        def collect(name, data, n, seed):  # the scale's data recipe (configs/recipes.yaml)
            argv = ["collect", "--recipe", s.recipe, "--transitions", n,
                    "--out", data, "--seed", seed, "--objects", s.objects, "--no-progress",
                    "--json",
                    *self._sensor(), *(self._ray() or ["--workers", self.jobs])]
            return Stage(name, argv, data / "collected.json", stdout=data / "collected.json")

        return [collect("collect train", self.train_data, s.train, s.train_seed),
                collect("collect held-out", self.heldout_data, s.heldout, s.heldout_seed)]

    def run_dir(self, model: str, seed: int) -> Path:
        return self.out / "runs" / f"{model}_s{seed}"

    def train_stages(self) -> list[Stage]:
        s = self.scale
        stages = []
        for model, options in MODELS.items():
            for seed in s.seeds:
                run = self.run_dir(model, seed)
                argv = ["train", *options, "--data", self.train_data, "--out", run,
                        "--seed", seed, "--epochs", s.epochs, "--patience", s.patience,
                        "--threads", 1, "--device", self.device, "--no-progress"]
                stages.append(Stage(f"train {run.name}", argv, run / "metrics.json",
                                    partial=run / "last.pt", resume=("--resume",)))
        return stages

    def bundles(self) -> dict[tuple[str, int, str], Path]:
        return {(m, seed, learner): self.run_dir(m, seed) / f"bundle_{learner}"
                for m, learners in LEARNERS.items() for seed in self.scale.seeds
                for learner in learners}

    def operator_stages(self) -> list[Stage]:
        s = self.scale
        stages = []
        for (_, _, learner), bundle in self.bundles().items():
            count = s.paper_min_count if learner == "paper" else s.min_count
            make = Stage(f"bundle {bundle.parent.name}/{bundle.name}",
                         ["bundle", "--run", bundle.parent, "--data", self.train_data,
                          "--out", bundle, "--learner", learner, "--min-count", count],
                         bundle / "operators.json")
            evaluate = Stage(f"eval operators {bundle.parent.name}/{bundle.name}",
                             ["eval", "operators", "--model", bundle, "--data",
                              self.heldout_data, "--max-problems", s.operator_problems,
                              "--familiar-data", self.train_data,
                              "--out", bundle / "eval.json"], bundle / "eval.json")
            stages.append((make, evaluate))
        return stages

    def effects_stage(self) -> Stage:
        runs = [self.run_dir(m, seed) for m in MODELS for seed in self.scale.seeds]
        return Stage("eval effects", ["eval", "effects", *runs, "--json", "--plot",
                                      self.results / "effects.png"],
                     self.results / "effects.json", stdout=self.results / "effects.json")

    def rollout_stages(self) -> list[Stage]:
        """The continuous model's position error after k actions rolled forward on the
        held-out episodes, for each Relational bundle (what bilevel planning rolls)."""
        return [Stage(f"eval rollout {bundle.parent.name}",
                      ["eval", "rollout", "--model", bundle, "--data", self.heldout_data,
                       "--json"], out, stdout=out)
                for bundle in self.planning_runs() if bundle.parent.name.startswith("relational")
                for out in [self.results / f"rollout_{bundle.parent.name}.json"]]

    def problem_stages(self) -> list[Stage]:
        s = self.scale
        stages = []
        for n in s.planning_objects:
            folder = self.out / "problems" / f"o{n}"
            stages.append(Stage(f"problems {n} objects",
                                ["problems", "make", "--out", folder, "--objects", n,
                                 "--k", *s.planning_k, "--count", s.planning_problems,
                                 "--seed", s.problem_seed + n, "--backend", "arm", "--json",
                                 *self._sensor()],
                                folder / "done.json", stdout=folder / "done.json"))
        return stages

    def planning_runs(self) -> list[Path]:
        """The bundles the arm problems are solved with, seed by seed (relational, then
        attentive), so that an unfinished evaluation has whole seeds of both."""
        return [self.bundles()[(m, seed, "effect")] for seed in self.scale.planning_seeds
                for m in ("relational", "attentive")]

    def _workers(self) -> list[str]:
        """A planning stage's engine: Ray where asked, else `jobs` local processes."""
        return self._ray() or ["--workers", self.jobs]

    def planning_stage(self) -> Stage:
        """The headline: every planning bundle on every problem, monitored."""
        runs = self.planning_runs()
        return Stage("eval planning",
                     ["eval", "planning", "--runs", *runs, "--problems", self.out / "problems",
                      "--records", self.results / "planning.jsonl", "--plot",
                      self.results / "planning.png", "--json", *self.solve.flags(),
                      "--monitor", "on", *self._sensor(), *self._workers()],
                     self.results / "planning.json", stdout=self.results / "planning.json")

    def mode_stages(self) -> list[Stage]:
        """The comparison rows on the same problems, with the first seed's Relational
        bundle: the other planning modes monitored, the oracle (the problems' own actions
        replayed open loop, the ceiling exact replay reaches) and, last, the main mode
        open loop (as the paper executes)."""
        run = self.planning_runs()[0]
        stages = []
        for mode in MODE_ROWS:
            main = mode == self.solve.planning
            out = self.results / ("planning_open_loop" if main else f"planning_{mode}")
            stages.append(Stage(
                f"eval planning {mode}" + (" open loop" if main else ""),
                ["eval", "planning", "--runs", run, "--problems", self.out / "problems",
                 "--records", out.with_suffix(".jsonl"), "--json",
                 *self.solve.replace(planning=mode).flags(),
                 "--monitor", "off" if main or PLANNING_MODES[mode].open_loop_only else "on",
                 *self._sensor(), *self._workers()],
                out.with_suffix(".json"), stdout=out.with_suffix(".json")))
        return sorted(stages, key=lambda st: st.name.endswith("open loop"))

    # --- running ----------------------------------------------------------------

    def run(self) -> Path:
        """Runs every stage not done yet; writes results.md and provenance.json."""
        from drake_symplan.pipelines.results_tables import write_results  # Drake, torch: see top

        t0 = time.perf_counter()
        self.results.mkdir(parents=True, exist_ok=True)
        self.say(f"reproduce --scale {self.name} in {self.out}")
        for stage in self.collect_stages():
            self._run(stage)
        self._parallel(self.train_stages())
        self._run(self.effects_stage())
        self._parallel(self.operator_stages())
        self._parallel(self.rollout_stages())
        for stage in self.problem_stages():
            self._run(stage)
        self._run(self.planning_stage())
        for stage in self.mode_stages():
            self._run(stage)
        path = write_results(self)
        self._write_provenance(time.perf_counter() - t0)
        self.say(f"done in {time.perf_counter() - t0:.0f} s: {path}")
        return path

    def report(self) -> Path:
        """results.md from the stages done so far (an unfinished planning evaluation:
        the runs and modes it has finished), without running anything."""
        from drake_symplan.pipelines.results_tables import write_results  # Drake, torch: see top

        return write_results(self)

    def _write_provenance(self, seconds: float) -> None:
        path = self.out / "provenance.json"
        earlier = read_json(path) if path.exists() else {}
        sittings = earlier.get("sittings", []) + [{
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "seconds": round(seconds, 1),
            "stages": self.log}]
        record = {
            "command": f"symplan reproduce --scale {self.name} --out {self.out}"
                       + (f" --ray {self.ray}" if self.ray is not None else "")
                       + (f" --device {self.device}" if self.device != "auto" else "")
                       + "".join(f" {a}" for a in self._sensor()),
            "scale": self.scale.settings("reproduce"),
            "data": {name: {"dir": str(d), "fingerprint": fingerprint(d)}
                     for name, d in (("train", self.train_data), ("heldout", self.heldout_data))},
            "versions": _versions(),
            "host": {"machine": platform.machine(), "system": platform.platform(),
                     "python": platform.python_version(), "cpus": os.cpu_count()},
            "sittings": sittings,
        }
        write_atomic(path, json.dumps(record, indent=1, default=str))


def _versions() -> dict:
    from drake_symplan.data.collect import code_version  # Drake: see the imports at the top

    return code_version(("drake_symplan", "drake", "torch", "numpy", "up-fast-downward",
                         "pyperplan", "ray"))
