"""Effect-prediction error: the loss, the per-object error in cm, Table I aggregation.

The error of one real object is the mean absolute error over its EFFECT_DIM effect
components, in centimetres; padded slots are excluded everywhere (the peer
implementation averaged over them, which flatters scenes with few objects). A run's
error is the mean over all real objects of its test split; by object count groups
transitions by their number of real objects; by role groups objects by their part in
the action (source, target, or another object, which only relations reach); by outcome
groups them by their transition's outcome class where the data set records one. Across
runs of one model we report mean +- sample standard deviation (0 for a single run).
`evaluate_runs` does all of it for trained run directories (`symplan eval effects`).
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np
import torch

from drake_symplan.actions import IS_SOURCE, IS_TARGET
from drake_symplan.atomic import save_figure
from drake_symplan.learning.checkpoint import load_run
from drake_symplan.learning.dataset import TensorSet, split_by_episode
from drake_symplan.learning.models import MODELS
from drake_symplan.shards import fingerprint, load_extra, load_transitions

CM_PER_M = 100.0
ROLES = ("source", "target", "other")
GROUPINGS = ("by_count", "by_role", "by_outcome")


def effect_loss(pred: torch.Tensor, effect: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Squared error summed over effect components and real objects, mean over the batch."""
    return (((pred - effect) ** 2).sum(-1) * mask).sum(-1).mean()


@torch.no_grad()
def predict(model: torch.nn.Module, data: TensorSet, batch_size: int = 4096) -> torch.Tensor:
    """Eval-mode (deterministic) effect predictions [T, N, EFFECT_DIM] for `data`."""
    was_training = model.training
    model.eval()
    try:
        out = [model(s, a, m) for s, a, _, m in data.batches(batch_size)]
    finally:
        model.train(was_training)
    if not out:
        return data.effect.new_zeros(data.effect.shape)
    return torch.cat(out)


def object_errors_cm(pred: torch.Tensor, effect: torch.Tensor, mask: torch.Tensor) -> np.ndarray:
    """[T, N] mean absolute effect error of every slot in cm, NaN on padded slots."""
    err = (pred - effect).abs().mean(-1) * CM_PER_M
    return torch.where(mask, err, torch.full_like(err, float("nan"))).numpy()


@torch.no_grad()
def evaluate_loss(model: torch.nn.Module, data: TensorSet, batch_size: int = 4096) -> float:
    """Eval-mode `effect_loss` over the whole set (mean over transitions)."""
    pred = predict(model, data, batch_size)
    return float(effect_loss(pred, data.effect, data.mask.to(pred.dtype)))


def object_roles(action: torch.Tensor | np.ndarray) -> np.ndarray:
    """[T, N] index into ROLES of every slot, from the action encoding (actions.py)."""
    a = np.asarray(action)
    return np.where(a[..., IS_SOURCE] > 0.5, 0, np.where(a[..., IS_TARGET] > 0.5, 1, 2))


def group_errors(errors: np.ndarray, labels: np.ndarray, names: tuple[str, ...]) -> dict:
    """Mean error over the real objects labelled k, for every names[k] that occurs.

    `labels` is per slot [T, N] or per transition [T] (then every object of a transition
    shares its label).
    """
    if labels.ndim == 1:
        labels = np.broadcast_to(labels[:, None], errors.shape)
    real = ~np.isnan(errors)
    groups = {}
    for k, name in enumerate(names):
        rows = real & (labels == k)
        if rows.any():
            groups[name] = {"error_cm": float(errors[rows].mean()), "objects": int(rows.sum())}
    return groups


def summarize_errors(errors: np.ndarray) -> dict:
    """Mean error over real objects, overall and by the transition's object count."""
    real = ~np.isnan(errors)
    counts = real.sum(axis=1)
    by_count = {}
    for n in np.unique(counts):
        rows = counts == n
        by_count[str(int(n))] = {
            "error_cm": float(np.nanmean(errors[rows])),
            "transitions": int(rows.sum()),
        }
    return {
        "error_cm": float(np.nanmean(errors)) if real.any() else float("nan"),
        "transitions": int(len(errors)),
        "objects": int(real.sum()),
        "by_count": by_count,
    }


def effect_metrics(
    model: torch.nn.Module,
    data: TensorSet,
    outcome: np.ndarray | None = None,
    outcome_names: tuple[str, ...] = (),
    batch_size: int = 4096,
) -> dict:
    """`summarize_errors` of the eval-mode predictions on `data`, by role, and its loss.

    With `outcome` (index into `outcome_names` per transition of `data`) also by outcome.
    """
    pred = predict(model, data, batch_size)
    errors = object_errors_cm(pred, data.effect, data.mask)
    summary = summarize_errors(errors)
    summary["by_role"] = group_errors(errors, object_roles(data.action), ROLES)
    if outcome is not None:
        if len(outcome) != len(errors):
            raise ValueError(f"{len(outcome)} outcome labels for {len(errors)} transitions")
        summary["by_outcome"] = group_errors(errors, np.asarray(outcome), outcome_names)
    summary["loss"] = float(effect_loss(pred, data.effect, data.mask.to(pred.dtype)))
    return summary


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
