"""Deterministic symbol read-out: unary p_j(o_i) and relational r_k(o_i, o_j) bits.

A bit is the sign of its logit (the model's eval mode), flagged `uncertain` when the
logit's magnitude is under a margin (see `gumbel.read_bits`). One forward pass per
state replaces the peer implementation's 100 stochastic passes. Padded slots read
as 0 and are never uncertain. Models without relations (the baselines) give K = 0.

`readout_dataset` returns the `SymbolDataset` (datasets.py) that `symplan symbols` saves
as symbols.npz: unary [T, N, P] uint8, relational [T, K, N, N] uint8 with
relational[t, k, i, j] = r_k(o_i, o_j), next_unary / next_relational (from next_state),
action [T, N, 8] float32, mask [T, N] bool, and a bool `*_uncertain` array beside each
bit array.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from drake_symplan.boxes import CONTACT_TOLERANCE
from drake_symplan.datasets import SceneSymbols, SymbolDataset, TransitionArrays
from drake_symplan.features import touching
from drake_symplan.learning.checkpoint import load_run
from drake_symplan.learning.gumbel import DEFAULT_MARGIN, read_bits
from drake_symplan.learning.models import EffectModel
from drake_symplan.shards import load_extra, load_transitions, relevance_radius

READOUT_BATCH = 8192


def _symbols_batch(model: EffectModel, state: torch.Tensor, mask: torch.Tensor, margin: float):
    """Bits and uncertainty of a [B, N, d_o] batch as torch tensors (no grad, eval)."""
    b, n, _ = state.shape
    unary, unary_unc = read_bits(model.unary_logits(state), margin)
    real = mask.unsqueeze(-1)
    unary, unary_unc = unary * real, unary_unc & real
    rel_logits = model.relation_logits(state, mask)
    if rel_logits is None:
        rel = torch.zeros(b, 0, n, n, dtype=torch.uint8)
        return unary, unary_unc, rel, rel.bool()
    rel, rel_unc = read_bits(rel_logits, margin)
    pair = (mask.unsqueeze(-1) & mask.unsqueeze(-2)).unsqueeze(1)
    return unary, unary_unc, rel * pair, rel_unc & pair


def read_symbols(
    model: EffectModel, state, mask=None, margin: float = DEFAULT_MARGIN
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(unary, unary_uncertain, relational, relational_uncertain) of one or more states.

    `state` is [N, d_o] (one perceived scene) or [B, N, d_o]; `mask` [N] / [B, N]
    (default: every slot real). Outputs are [N, P] and [K, N, N] (with a leading B
    for batched input), bits as uint8, flags as bool.
    """
    state = torch.as_tensor(np.asarray(state, dtype=np.float32))
    single = state.dim() == 2
    if single:
        state = state.unsqueeze(0)
    if state.dim() != 3 or state.shape[-1] != model.state_dim:
        raise ValueError(f"state must be [N, {model.state_dim}] or [B, N, {model.state_dim}], "
                         f"got {tuple(state.shape)}")
    if mask is None:
        mask = torch.ones(state.shape[:2], dtype=torch.bool)
    else:
        mask = torch.as_tensor(np.asarray(mask, dtype=bool)).reshape(state.shape[:2])
    was_training = model.training
    model.eval()
    try:
        with torch.inference_mode():
            out = _symbols_batch(model, state, mask, margin)
    finally:
        model.train(was_training)
    arrays = tuple(t.numpy() for t in out)
    return tuple(a[0] for a in arrays) if single else arrays


def read_symbols_batched(
    model: EffectModel, state: np.ndarray, mask: np.ndarray, margin: float = DEFAULT_MARGIN,
    batch_size: int = READOUT_BATCH,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`read_symbols` over [T, N, d_o] in chunks of `batch_size`, concatenated."""
    t = state.shape[0]
    parts = [read_symbols(model, state[i:i + batch_size], mask[i:i + batch_size], margin)
             for i in range(0, max(t, 1), batch_size)]
    if t == 0:
        return tuple(p[:0] for p in parts[0])
    return tuple(np.concatenate(chunks) for chunks in zip(*parts, strict=True))


def readout_dataset(
    run_dir: str | Path | EffectModel,
    data: str | Path | TransitionArrays,
    margin: float = DEFAULT_MARGIN,
    batch_size: int = READOUT_BATCH,
) -> SymbolDataset:
    """Symbols before and after every transition of `data` (a directory or arrays).

    `run_dir` is a run directory (its best checkpoint) or an already loaded model.
    """
    model = run_dir if isinstance(run_dir, EffectModel) else load_run(run_dir)[0]
    arrays = data if isinstance(data, TransitionArrays) else load_transitions(data)
    if arrays.next_state is None:
        raise ValueError("symbol read-out needs next_state in the data set")
    if arrays.state.shape[2] != model.state_dim:
        raise ValueError(f"the data has {arrays.state.shape[2]} features per object, the "
                         f"model expects {model.state_dim}")
    mask = arrays.mask.astype(bool)
    result = {}
    for prefix, state in (("", arrays.state), ("next_", arrays.next_state)):
        unary, unary_unc, rel, rel_unc = read_symbols_batched(
            model, state, mask, margin, batch_size)
        result[f"{prefix}unary"] = unary
        result[f"{prefix}relational"] = rel
        result[f"{prefix}unary_uncertain"] = unary_unc
        result[f"{prefix}relational_uncertain"] = rel_unc
    return SymbolDataset(action=arrays.action.astype(np.float32, copy=False), mask=mask,
                         **result)


SCENE_KEYS = ("scene_state", "scene_next_state", "scene_mask", "scene_contacts",
              "scene_next_contacts", "scene_slots", "chain", "step")


def has_scenes(data_dir: str | Path) -> bool:
    """Whether the data set stores whole scenes beside its transitions (data/exploration.py)."""
    return load_extra(data_dir, "scene_slots") is not None


def readout_scenes(
    model: EffectModel, data_dir: str | Path, margin: float = DEFAULT_MARGIN,
    batch_size: int = READOUT_BATCH,
) -> tuple[SymbolDataset, SceneSymbols]:
    """Symbols read from the whole perceived scenes of a data set.

    Returns (the relevant objects' symbols, with the perceived contacts among them, as a
    SymbolDataset; the whole scenes' symbols). Reading the whole scene, not the relevant
    objects alone, gives an object the symbols a planner reads in a perceived scene:
    relations come from attention over every object in view."""
    def bits(state, mask, contacts):
        if state.shape[2] != model.state_dim:
            raise ValueError(f"the data has {state.shape[2]} features per object, "
                             f"the model expects {model.state_dim}")
        return read_symbols_batched(model, state, mask, margin, batch_size)

    return scenes_symbols(data_dir, bits)


def scenes_symbols(data_dir: str | Path, bits) -> tuple[SymbolDataset, SceneSymbols]:
    """`readout_scenes` with the symbols of each whole scene from `bits(state [T, M, D],
    mask [T, M], contacts [T, M, M]) -> (unary, unary_uncertain, relational,
    relational_uncertain)`: a trained model's, or learning/handmade.py's reference_bits."""
    arrays = load_transitions(data_dir)
    extra = {k: load_extra(data_dir, k, pad_value=-1 if k == "scene_slots" else None)
             for k in SCENE_KEYS}
    missing = [k for k, v in extra.items() if v is None]
    if missing:
        raise ValueError(f"data set {data_dir} stores no whole scenes (lacks {missing}); "
                         "collect it with the current code")
    mask = extra["scene_mask"].astype(bool)
    read = {}
    for prefix, key, contacts in (("", "scene_state", "scene_contacts"),
                                  ("next_", "scene_next_state", "scene_next_contacts")):
        unary, unary_unc, rel, rel_unc = bits(extra[key], mask, extra[contacts].astype(bool))
        read.update({f"{prefix}unary": unary, f"{prefix}relational": rel,
                     f"{prefix}unary_uncertain": unary_unc,
                     f"{prefix}relational_uncertain": rel_unc})
    wider = relevance_radius(data_dir) > CONTACT_TOLERANCE
    scenes = SceneSymbols(**read, mask=mask, contacts=extra["scene_contacts"].astype(bool),
                          next_contacts=extra["scene_next_contacts"].astype(bool),
                          episode=arrays.episode, step=extra["step"].astype(np.int64),
                          chain=extra["chain"].astype(np.int64),
                          touching=touching(extra["scene_state"], mask) if wider else None,
                          next_touching=touching(extra["scene_next_state"], mask)
                          if wider else None)
    slots = extra["scene_slots"].astype(np.int64)
    rel_mask = arrays.mask.astype(bool)
    return _gather(scenes, slots, rel_mask, arrays.action), scenes


def _gather(scenes: SceneSymbols, slots: np.ndarray, mask: np.ndarray,
            action: np.ndarray) -> SymbolDataset:
    """The relevant objects' rows of the scene read-out ([T, N] scene slots, -1 padding)."""
    t = np.arange(len(slots))[:, None]
    s = np.where(mask, slots, 0)
    real = mask[:, :, None]
    pair = (mask[:, :, None] & mask[:, None, :])
    out = {}
    for prefix in ("", "next_"):
        for suffix in ("", "_uncertain"):
            u = getattr(scenes, f"{prefix}unary{suffix}")[t, s]
            r = getattr(scenes, f"{prefix}relational{suffix}")
            r = r[t[:, :, None], :, s[:, :, None], s[:, None, :]].transpose(0, 3, 1, 2)
            out[f"{prefix}unary{suffix}"] = u * real if suffix == "" else u & real
            out[f"{prefix}relational{suffix}"] = (r * pair[:, None] if suffix == ""
                                                 else r & pair[:, None])
    for prefix in ("", "next_"):
        whole = getattr(scenes, f"{prefix}contacts")
        c = whole[t[:, :, None], s[:, :, None], s[:, None, :]]
        out[f"{prefix}contacts"] = c & pair
        touch = getattr(scenes, f"{prefix}touching")
        touch = whole if touch is None else touch
        out[f"{prefix}degree"] = (touch.sum(-1)[t, s] * mask).astype(np.int8)
    return SymbolDataset(action=action.astype(np.float32, copy=False), mask=mask, **out)


def uncertainty_counts(symbols: SymbolDataset) -> dict[str, int]:
    """Number of uncertain bits (and of bits read) per array of a read-out."""
    counts = {}
    for key in ("unary", "relational", "next_unary", "next_relational"):
        flags = getattr(symbols, f"{key}_uncertain")
        counts[f"{key}_uncertain"] = 0 if flags is None else int(flags.sum())
    mask = symbols.mask
    n_real = int(mask.sum())
    n_pairs = int((mask.sum(axis=1) ** 2).sum())
    counts["unary_bits"] = n_real * symbols.n_unary
    counts["relational_bits"] = n_pairs * symbols.n_relations
    return counts
