"""The demo's `--from-scratch`: a model learned within a budget of minutes (hand collection
with whole scenes, an invariant RelationalDeepSym trained until the budget's share runs
out, effect-first operators), each step a `symplan` command run by the StageRunner in
WORK/seed<S> (its logs in WORK/seed<S>/logs). A re-run with the same WORK and seed reuses
the model, or the data set collected before."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

from drake_symplan.pipelines.stages import Stage, StageRunner

# Shares of the budget by which collection and training must end.
COLLECT_SHARE, TRAIN_SHARE = 0.4, 0.85
FIRST_ROUND = 100  # transitions collected first, to measure the rate
MIN_BUDGET_MINUTES = 2.0


def learn_from_scratch(work: Path, seed: int, budget_minutes: float, say):
    """Collects, trains and bundles within the budget; returns the loaded ModelBundle.
    StageFailed (a RuntimeError) when a command fails, BundleError (a ValueError) when
    the bundle holds no operators."""
    from drake_symplan.symbolic.bundle import ModelBundle

    budget, t0 = budget_minutes * 60, time.perf_counter()
    work = Path(work) / f"seed{seed}"
    data, run, out = work / "data", work / "run", work / "bundle"
    try:
        bundle = ModelBundle.load(out)
        say(f"from scratch: reusing the model learned before in {out}")
        return bundle
    except (ValueError, OSError):
        pass
    workers = max(1, min(2, os.cpu_count() or 1))
    say(f"from scratch in {work}, {budget_minutes:g} min: collect, train, operators")
    runner = StageRunner(work, jobs=1, say=say, announce="  $ {command}")

    def collect(name, n):
        runner.run(Stage(name, ["collect", "--backend", "hand", "--transitions", n,
                                 "--workers", workers, "--out", data, "--seed", seed,
                                 "--objects", "2-4", "--no-progress"], None))

    manifest = data / "manifest.json"
    if manifest.is_file():  # a re-run: the data set collected before, as it is
        total = int(json.loads(manifest.read_text())["config"]["transitions"])
    else:
        collect("collect first", FIRST_ROUND)
        rate = FIRST_ROUND / (time.perf_counter() - t0)
        total = max(FIRST_ROUND, int(rate * COLLECT_SHARE * budget))
        if total > FIRST_ROUND:
            collect("collect", total)
    say(f"  data set: {total} transitions ({time.perf_counter() - t0:.0f} s)")
    left = TRAIN_SHARE * budget - (time.perf_counter() - t0)
    runner.run(Stage("train", ["train", "--model", "relational", "--data", data, "--out", run,
                                "--seed", seed, "--model-option", "invariant=true",
                                "--threads", workers, "--epochs", 300, "--no-progress"],
                      None, partial=run / "last.pt", resume=("--resume",),
                      timeout=max(left, 30)))
    # Operators need support: with a small data set, fewer transitions per operator.
    min_count = max(3, min(10, total // 500))
    runner.run(Stage("bundle", ["bundle", "--run", run, "--data", data, "--out", out,
                                 "--min-count", min_count], None))
    say(f"  model ready in {time.perf_counter() - t0:.0f} s")
    bundle = ModelBundle.load(out)  # BundleError (a ValueError) when it holds no operators
    say(f"  {len(bundle.operators)} operators from {total} transitions")
    return bundle
