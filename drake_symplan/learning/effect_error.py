"""Effect-prediction error: the loss, the per-object error in cm, Table I aggregation.

The error of one real object is the mean absolute error over its EFFECT_DIM effect
components, in centimetres; padded slots are excluded everywhere (the peer
implementation averaged over them, which flatters scenes with few objects). A run's
error is the mean over all real objects of its test split; by object count groups
transitions by their number of real objects; by role groups objects by their part in
the action (source, target, or another object, which only relations reach); by outcome
groups them by their transition's outcome class where the data set records one. Across
runs of one model we report mean +- sample standard deviation (0 for a single run).
Over trained run directories (`symplan eval effects`): evaluation/effects.py.
"""

from __future__ import annotations

import numpy as np
import torch

from drake_symplan.actions import IS_SOURCE, IS_TARGET
from drake_symplan.learning.dataset import TensorSet
from drake_symplan.learning.device import model_device

CM_PER_M = 100.0
ROLES = ("source", "target", "other")
GROUPINGS = ("by_count", "by_role", "by_outcome")


def effect_loss(pred: torch.Tensor, effect: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Squared error summed over effect components and real objects, mean over the batch."""
    return (((pred - effect) ** 2).sum(-1) * mask).sum(-1).mean()


@torch.no_grad()
def predict(model: torch.nn.Module, data: TensorSet, batch_size: int = 4096) -> torch.Tensor:
    """Eval-mode (deterministic) effect predictions [T, N, EFFECT_DIM] for `data`, on the
    CPU; the model runs on its own device (the batches are moved there)."""
    device = model_device(model)
    was_training = model.training
    model.eval()
    try:
        out = [model(s.to(device), a.to(device), m.to(device)).cpu()
               for s, a, _, m in data.batches(batch_size)]
    finally:
        model.train(was_training)
    if not out:
        return data.effect.new_zeros(data.effect.shape).cpu()
    return torch.cat(out)


def object_errors_cm(pred: torch.Tensor, effect: torch.Tensor, mask: torch.Tensor) -> np.ndarray:
    """[T, N] mean absolute effect error of every slot in cm, NaN on padded slots."""
    err = (pred - effect).abs().mean(-1) * CM_PER_M
    return torch.where(mask, err, torch.full_like(err, float("nan"))).numpy()


@torch.no_grad()
def evaluate_loss(model: torch.nn.Module, data: TensorSet, batch_size: int = 4096) -> float:
    """Eval-mode `effect_loss` over the whole set (mean over transitions)."""
    pred = predict(model, data, batch_size)
    data = data.to("cpu")
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
    data = data.to("cpu")
    errors = object_errors_cm(pred, data.effect, data.mask)
    summary = summarize_errors(errors)
    summary["by_role"] = group_errors(errors, object_roles(data.action), ROLES)
    if outcome is not None:
        if len(outcome) != len(errors):
            raise ValueError(f"{len(outcome)} outcome labels for {len(errors)} transitions")
        summary["by_outcome"] = group_errors(errors, np.asarray(outcome), outcome_names)
    summary["loss"] = float(effect_loss(pred, data.effect, data.mask.to(pred.dtype)))
    return summary
