"""Table I: the effect error of trained runs on their test splits (`symplan eval effects`),
mean +- sample standard deviation over the runs of each model, by object count, role and
outcome (the per-object error itself: learning/effect_error.py)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from drake_symplan.atomic import save_figure
from drake_symplan.learning.checkpoint import load_run
from drake_symplan.learning.dataset import TensorSet, split_by_episode
from drake_symplan.learning.effect_error import GROUPINGS, effect_metrics
from drake_symplan.learning.models import MODELS
from drake_symplan.shards import fingerprint, load_extra, load_transitions


def _mean_std(values: list[float]) -> dict:
    arr = np.asarray(values, dtype=np.float64)
    std = float(arr.std(ddof=1)) if len(arr) > 1 else 0.0
    return {"mean": float(arr.mean()), "std": std, "runs": len(arr)}


def aggregate_runs(per_run: list[dict]) -> dict:
    """Group run results {"run", "model", "error_cm", "by_count"[, "by_role", "by_outcome"]}
    by model (in Table I's order): mean +- std overall and per group of every grouping the
    runs report."""
    groups: dict[str, list[dict]] = defaultdict(list)
    for result in per_run:
        groups[result["model"]].append(result)
    rank = {name: i for i, name in enumerate(MODELS)}  # Table I's order, then by name
    models = {}
    for name, results in sorted(groups.items(), key=lambda g: (rank.get(g[0], len(rank)), g[0])):
        models[name] = {"error_cm": _mean_std([r["error_cm"] for r in results])}
        for grouping in GROUPINGS:
            reported = [r[grouping] for r in results if grouping in r]
            labels = list(dict.fromkeys(k for g in reported for k in g))
            if grouping == "by_count":
                labels.sort(key=int)
            if reported:
                models[name][grouping] = {
                    k: _mean_std([g[k]["error_cm"] for g in reported if k in g]) for k in labels
                }
        models[name]["runs"] = [r["run"] for r in results]
    return models


def evaluate_runs(
    runs: list[str | Path], data_dir: str | Path | None = None,
    outcome_names: tuple[str, ...] = (),
) -> dict:
    """Test-set `effect_metrics` of every run directory and their `aggregate_runs`.

    Each run is evaluated on the test split of its own seed, on the data set it was
    trained on, or on `data_dir` (a data set that moved), which must have the run's
    fingerprint. With `outcome_names` (the data set's outcome classes, by index) and a
    data set that records an "outcome" per transition, also by outcome.
    """
    cache: dict[str, tuple] = {}
    per_run = []
    for run in runs:
        model, config = load_run(run)
        train_cfg = config["train_config"]
        data = str(Path(data_dir or train_cfg["data"]).resolve())
        if data not in cache:
            outcome = load_extra(data, "outcome") if outcome_names else None
            cache[data] = (load_transitions(data), fingerprint(data), outcome)
        arrays, fp, outcome = cache[data]
        if fp != config["data_fingerprint"]:
            raise ValueError(f"run {run} was trained on other data than {data} "
                             "(fingerprints differ)")
        test = split_by_episode(arrays.episode, train_cfg["seed"])["test"]
        metrics = effect_metrics(model, TensorSet.from_arrays(arrays, test),
                                 None if outcome is None else outcome[test], outcome_names)
        per_run.append({"run": str(run), "model": config["model"], "epoch": config["epoch"],
                        **metrics})
    return {"runs": per_run, "models": aggregate_runs(per_run)}


def format_summary(models: dict) -> list[str]:
    """One line per model of `aggregate_runs`: error mean +- std, runs, and by role."""
    lines = []
    for name, stats in models.items():
        e = stats["error_cm"]
        roles = ", ".join(f"{k} {v['mean']:.2f}" for k, v in stats.get("by_role", {}).items())
        lines.append(f"{name}: {e['mean']:.2f} +- {e['std']:.2f} cm over {e['runs']} run(s) "
                     f"({roles})")
    return lines


def plot_errors(models: dict, out: str | Path) -> Path:
    """Bar charts of the error (mean +- std over runs) per model: overall and by object
    count on the left, by role (and by outcome, where the runs report it) beside it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(models)
    panels = [("by_count", ["all"] + sorted(
        {c for m in models.values() for c in m["by_count"]}, key=int))]
    for grouping in ("by_role", "by_outcome"):
        labels = list(dict.fromkeys(k for m in models.values() for k in m.get(grouping, {})))
        if labels:
            panels.append((grouping, labels))
    width = 0.8 / max(1, len(names))
    fig, axes = plt.subplots(1, len(panels), squeeze=False, figsize=(
        sum(1.6 + 1.1 * len(labels) for _, labels in panels), 3.4))
    for ax, (grouping, labels) in zip(axes[0], panels, strict=True):
        for k, name in enumerate(names):
            groups = models[name].get(grouping, {})
            stats = [models[name]["error_cm"] if g == "all"
                     else groups.get(g, {"mean": np.nan, "std": 0.0}) for g in labels]
            x = np.arange(len(labels)) + (k - (len(names) - 1) / 2) * width
            ax.bar(x, [s["mean"] for s in stats], width, yerr=[s["std"] for s in stats],
                   capsize=3, label=name)
        ax.set_xticks(np.arange(len(labels)))
        ax.set_xticklabels([f"{g} obj." if g.isdigit() else g.replace("_", " ")
                            for g in labels], rotation=20)
        ax.set_title(grouping.replace("_", " ").replace("count", "object count"))
    axes[0][0].set_ylabel("effect error (cm, MAE per object)")
    axes[0][0].legend()
    fig.tight_layout()
    return save_figure(fig, out)
