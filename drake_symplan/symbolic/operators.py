"""Lifted operators from symbolic transitions (paper III-C).

Transitions are grouped by (grasp, release, number of objects, precondition bits in
the canonical object order of `canonical.py`): `?o0` is the source, `?o1` the target,
`?o2`... the other relevant objects (all real objects of a transition: the data set
stores only the action arguments plus the objects in contact with them). Each group's
lifted effect is its most frequent next state in canonical order; equally frequent
effects go to the smaller encoding, so the result does not depend on the order of the
transitions. Groups seen fewer than `min_count` times (50, as in the paper) are
dropped; `threshold_report` says what other absolute or relative thresholds would keep.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from drake_symplan.actions import IS_SOURCE, IS_TARGET, OFFSETS, Action
from drake_symplan.datasets import SymbolDataset
from drake_symplan.symbolic.canonical import canonical_orders, encode, permute
from drake_symplan.symbolic.states import bit_atoms
from drake_symplan.symbolic.structs import LiftedOperator

# Relative thresholds reported next to the absolute one (fractions of the data size).
# The paper's 50 of 160k training samples is about 3.1e-4.
REPORT_FRACTIONS = (1e-4, 2.5e-4, 5e-4, 1e-3, 2.5e-3, 5e-3)


@dataclass(frozen=True)
class LearnConfig:
    """min_count: groups seen fewer times are dropped. min_fraction: if given, the
    threshold is ceil(min_fraction * number of transitions) instead. self_relations:
    keep r_k(o, o) bits as `(rK ?x ?x)` literals (default: ignore them).
    drop_uncertain: leave out transitions with any uncertain bit among real objects."""

    min_count: int = 50
    min_fraction: float | None = None
    self_relations: bool = False
    drop_uncertain: bool = False

    def threshold(self, n_transitions: int) -> int:
        if self.min_fraction is not None:
            if not 0.0 <= self.min_fraction <= 1.0:
                raise ValueError(f"min_fraction must be in [0, 1], got {self.min_fraction}")
            return max(1, math.ceil(self.min_fraction * n_transitions))
        if self.min_count < 1:
            raise ValueError(f"min_count must be >= 1, got {self.min_count}")
        return self.min_count


def paper_operator(index: int, grasp: str, release: str, count: int, pre: tuple,
                   post: tuple, self_relations: bool = False, **stats) -> LiftedOperator:
    """The operator of a group whose canonical state before is `pre` and whose most
    frequent state after is `post` ((unary, relational) each): the bits that differ
    become its effects, in positive-STRIPS form (a bit turning on adds `(pJ ..)` and
    deletes `(not_pJ ..)`)."""
    # The closed-world atoms of each canonical state over parameter slots.
    before = bit_atoms(*pre, self_relations=self_relations)[0]
    after = bit_atoms(*post, self_relations=self_relations)[0]
    changed = [(a, b) for a, b in zip(before, after, strict=True) if a != b]
    return LiftedOperator(index, grasp, release, pre[0].shape[0], before,
                          [b for _, b in changed], [a for a, _ in changed], count, **stats)


@dataclass
class OperatorSet:
    """The result of operator learning."""

    operators: list[LiftedOperator]  # kept groups, most frequent first
    n_unary: int
    n_relations: int
    self_relations: bool
    n_transitions: int  # transitions grouped (after dropping uncertain ones)
    n_dropped_uncertain: int
    threshold: int
    group_counts: np.ndarray  # count of every group, kept or not, descending
    seconds: float = 0.0
    timings: dict = field(default_factory=dict)

    @property
    def n_groups(self) -> int:
        return len(self.group_counts)

    def threshold_report(self) -> list[dict]:
        """What absolute and relative thresholds would keep: operators and the
        fraction of transitions their groups cover."""
        counts = self.group_counts
        total = max(self.n_transitions, 1)
        rows = []
        thresholds = sorted({1, 5, 10, 20, 50, 100, 200, self.threshold})
        for frac in REPORT_FRACTIONS:
            rows.append(("fraction", frac, max(1, math.ceil(frac * self.n_transitions))))
        rows = [("count", t / total, t) for t in thresholds] + rows
        out = []
        for kind, frac, t in rows:
            kept = counts >= t
            out.append({
                "by": kind,
                "threshold": int(t),
                "fraction": float(frac),
                "operators": int(kept.sum()),
                "coverage": float(counts[kept].sum() / total),
            })
        return out

    def summary(self) -> dict:
        kept = int(sum(op.count for op in self.operators))
        return {
            "n_transitions": self.n_transitions,
            "n_dropped_uncertain": self.n_dropped_uncertain,
            "n_groups": self.n_groups,
            "threshold": self.threshold,
            "n_operators": len(self.operators),
            "coverage": kept / max(self.n_transitions, 1),
            "n_unary": self.n_unary,
            "n_relations": self.n_relations,
            "self_relations": self.self_relations,
            "seconds": self.seconds,
            "timings": self.timings,
        }


# ---------------------------------------------------------------- input checks


def action_roles(action: np.ndarray, mask: np.ndarray):
    """Source, target, grasp and release index per transition; ValueError on rows
    without exactly one source and one target among the real objects."""
    a = action > 0.5
    is_src = a[:, :, IS_SOURCE] & mask
    is_tgt = a[:, :, IS_TARGET] & mask
    bad = (is_src.sum(1) != 1) | (is_tgt.sum(1) != 1) | (is_src & is_tgt).any(1)
    if bad.any():
        rows = np.flatnonzero(bad)
        raise ValueError(
            f"{len(rows)} transitions do not have exactly one source and one distinct "
            f"target among their real objects (first: {rows[:5].tolist()})"
        )
    ar = np.arange(len(action))
    src = is_src.argmax(1)
    tgt = is_tgt.argmax(1)
    grasp_bits = a[ar, src, IS_SOURCE + 1:IS_SOURCE + 4]
    release_bits = a[ar, tgt, IS_TARGET + 1:IS_TARGET + 4]
    if (grasp_bits.sum(1) != 1).any() or (release_bits.sum(1) != 1).any():
        raise ValueError("some transitions do not have exactly one grasp and one release offset")
    return src, tgt, grasp_bits.argmax(1), release_bits.argmax(1)


def _byte_ids(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(id, count) of each distinct uint8 row; ids are ranks in byte order."""
    rows = np.ascontiguousarray(rows, dtype=np.uint8)
    void = rows.view(np.dtype((np.void, rows.shape[1]))).reshape(-1)
    _, inverse, counts = np.unique(void, return_inverse=True, return_counts=True)
    return inverse.reshape(-1), counts


# ---------------------------------------------------------------- learning


def _clean(data: SymbolDataset, config: LearnConfig):
    """Boolean arrays with padding and (optionally) self-relations zeroed, and the
    indices of the transitions kept."""
    mask = data.mask.astype(bool)
    keep = np.arange(len(mask))
    if config.drop_uncertain:
        bad = np.zeros(len(mask), dtype=bool)
        n = mask.shape[1]
        pair = mask[:, :, None] & mask[:, None, :]
        if not config.self_relations:
            pair &= ~np.eye(n, dtype=bool)[None]
        for unc in (data.unary_uncertain, data.next_unary_uncertain):
            if unc is not None:
                bad |= (unc.astype(bool) & mask[:, :, None]).any((1, 2))
        for unc in (data.relational_uncertain, data.next_relational_uncertain):
            if unc is not None:
                bad |= (unc.astype(bool) & pair[:, None]).any((1, 2, 3))
        keep = np.flatnonzero(~bad)
    mask = mask[keep]
    n = mask.shape[1]
    pair = mask[:, None, :, None] & mask[:, None, None, :]
    if not config.self_relations:
        pair = pair & ~np.eye(n, dtype=bool)[None, None]
    out = {
        "unary": data.unary[keep].astype(bool) & mask[:, :, None],
        "next_unary": data.next_unary[keep].astype(bool) & mask[:, :, None],
        "relational": data.relational[keep].astype(bool) & pair,
        "next_relational": data.next_relational[keep].astype(bool) & pair,
        "action": data.action[keep],
        "mask": mask,
    }
    return out, keep


def _group_effects(group: np.ndarray, effect: np.ndarray, n_groups: int):
    """Per group: its most frequent effect id (the smallest encoding among equally
    frequent ones), how many transitions had it, and how many distinct effects it has."""
    n_effect_ids = int(effect.max()) + 1
    pair_ids, pair_counts = np.unique(group * n_effect_ids + effect, return_counts=True)
    pair_group, pair_effect = pair_ids // n_effect_ids, pair_ids % n_effect_ids
    by = np.lexsort((pair_effect, -pair_counts, pair_group))
    first = np.ones(len(by), dtype=bool)
    first[1:] = pair_group[by][1:] != pair_group[by][:-1]
    best_effect = np.empty(n_groups, dtype=np.int64)
    best_count = np.empty(n_groups, dtype=np.int64)
    best_effect[pair_group[by][first]] = pair_effect[by][first]
    best_count[pair_group[by][first]] = pair_counts[by][first]
    return best_effect, best_count, np.bincount(pair_group, minlength=n_groups)


def learn_operators(data: SymbolDataset, config: LearnConfig | None = None) -> OperatorSet:
    """Groups the transitions of a symbolic data set into lifted operators."""
    if not isinstance(data, SymbolDataset):
        raise TypeError(f"learn_operators takes a SymbolDataset, got {type(data).__name__}")
    config = config or LearnConfig()
    t0 = time.perf_counter()
    n_unary, n_rel = data.n_unary, data.n_relations
    d, keep = _clean(data, config)
    mask = d["mask"]
    t, n = mask.shape
    if t == 0:
        raise ValueError("no transitions to learn operators from")
    src, tgt, grasp, release = action_roles(d["action"], mask)
    t1 = time.perf_counter()

    order, n_permuted = canonical_orders(
        d["unary"], d["relational"], d["next_unary"], d["next_relational"], mask, src, tgt,
        config.self_relations,
    )
    u, r = permute(d["unary"], d["relational"], order)
    nu, nr = permute(d["next_unary"], d["next_relational"], order)
    n_obj = mask.sum(1)
    t2 = time.perf_counter()

    head = np.stack([grasp, release, n_obj], axis=1).astype(np.uint8)
    pre_bits = np.packbits(encode(u, r), axis=1)
    post_bits = np.packbits(encode(nu, nr), axis=1)
    group, group_counts = _byte_ids(np.concatenate([head, pre_bits], axis=1))
    effect, _ = _byte_ids(post_bits)
    best_effect, best_count, n_effects = _group_effects(group, effect, len(group_counts))
    t3 = time.perf_counter()

    threshold = config.threshold(t)
    kept_groups = np.flatnonzero(group_counts >= threshold)
    # Most frequent first; equal counts by group id (the rank of the key bytes).
    kept_groups = kept_groups[np.lexsort((kept_groups, -group_counts[kept_groups]))]
    # One example per group: the first transition with the chosen effect.
    chosen = effect == best_effect[group]
    example = np.full(len(group_counts), t, dtype=np.int64)
    idx = np.flatnonzero(chosen)
    np.minimum.at(example, group[idx], idx)
    operators = []
    for rank, g in enumerate(kept_groups):
        e = int(example[g])
        m = int(n_obj[e])
        operators.append(paper_operator(
            rank, OFFSETS[grasp[e]], OFFSETS[release[e]], int(group_counts[g]),
            (u[e, :m], r[e, :, :m, :m]), (nu[e, :m], nr[e, :, :m, :m]), config.self_relations,
            effect_count=int(best_count[g]), outcomes=int(n_effects[g]), example=int(keep[e]),
            example_slots=tuple(int(x) for x in order[e, :m])))
    t4 = time.perf_counter()
    return OperatorSet(
        operators=operators, n_unary=n_unary, n_relations=n_rel,
        self_relations=config.self_relations, n_transitions=t,
        n_dropped_uncertain=len(data) - t, threshold=threshold,
        group_counts=np.sort(group_counts)[::-1], seconds=t4 - t0,
        timings={"check": t1 - t0, "canonical": t2 - t1, "group": t3 - t2,
                 "build": t4 - t3, "permuted_transitions": n_permuted})


def example_action(op: LiftedOperator) -> Action:
    """The operator's action on its example transition's object slots (o<slot>)."""
    s, t = op.example_slots[:2]
    return Action(f"o{s}", op.grasp, f"o{t}", op.release)


def load_symbols(path) -> SymbolDataset:
    """A symbolic data set saved as symbols.npz (`SymbolDataset.load`)."""
    return SymbolDataset.load(path)
