"""Canonical object order of symbolic transitions, without trying all permutations.

Two transitions belong to one operator when their lifted action and preconditions are
equal under a substitution of objects (paper III-C). Comparing them needs a canonical
order of each transition's objects:

1. roles fix the first two slots: the source, then the target;
2. the other objects are ordered by a colour that summarises their symbols and
   relations: their unary bits (and self-relations, if kept), then refined by the
   sorted multiset of (relation bits to and from each other object, that object's
   colour) until the colouring is stable (colour refinement, all transitions at once
   in numpy; colours are ranks of sorted signatures over the whole data set, so they
   do not depend on the order of the transitions);
3. objects left with equal colours are ties. A tie whose swap is an automorphism of
   the transition (identical objects, before and after the action) needs nothing:
   either order gives the same encoding. Only the remaining, genuine ties are
   permuted, and the order with the smallest (precondition, next state) encoding wins,
   which also makes the effect canonical among the orders of equal preconditions.

Cost: a few sorts over T x N rows; permutations only for genuine ties (none in most
data; for k tied objects that colour refinement cannot tell apart, k! encodings of
that one transition, vectorised).
"""

from __future__ import annotations

import itertools

import numpy as np


def rank_rows(rows: np.ndarray) -> np.ndarray:
    """Dense rank of each row among all rows, in lexicographic order of int rows."""
    order = np.lexsort(rows.T[::-1])
    ranked = rows[order]
    new = np.ones(len(rows), dtype=bool)
    new[1:] = (ranked[1:] != ranked[:-1]).any(1)
    out = np.empty(len(rows), dtype=np.int64)
    out[order] = np.cumsum(new) - 1
    return out


def colours(unary, rel, mask, src, tgt, self_relations) -> np.ndarray:
    """Colour refinement over all transitions at once; returns [T, N] colour ranks,
    sorted role-major (source < target < others < padding)."""
    t, n = mask.shape
    k = rel.shape[1]
    ar = np.arange(t)
    role = np.where(mask, 2, 3).astype(np.int64)
    role[ar, tgt] = 1
    role[ar, src] = 0
    feats = [role[:, :, None], unary.astype(np.int64)]
    if self_relations:
        idx = np.arange(n)
        feats.append(rel[:, :, idx, idx].transpose(0, 2, 1).astype(np.int64))
    colour = rank_rows(np.concatenate(feats, axis=2).reshape(t * n, -1)).reshape(t, n)
    weights = (1 << np.arange(k)).astype(np.int64)
    out_bits = np.einsum("tkij,k->tij", rel.astype(np.int64), weights)
    bits = out_bits + (out_bits.transpose(0, 2, 1) << k)  # [T, N, N]: to j and from j
    invalid = ~mask[:, None, :] | np.eye(n, dtype=bool)[None]
    n_colours = colour.max() + 1
    for _ in range(n):
        code = colour[:, None, :] * (1 << (2 * k)) + bits
        code[invalid] = -1
        code.sort(axis=2)
        sig = np.concatenate([colour[:, :, None], code], axis=2).reshape(t * n, -1)
        colour = rank_rows(sig).reshape(t, n)
        if colour.max() + 1 == n_colours:
            break
        n_colours = colour.max() + 1
    return colour


def permute(unary, rel, order):
    """Arrays with objects reordered: unary [B,N,P], rel [B,K,N,N], order [B,N]."""
    u = np.take_along_axis(unary, order[:, :, None], axis=1)
    r = np.take_along_axis(rel, order[:, None, :, None], axis=2)
    r = np.take_along_axis(r, order[:, None, None, :], axis=3)
    return u, r


def encode(unary, rel):
    b = unary.shape[0]
    return np.concatenate([unary.reshape(b, -1), rel.reshape(b, -1)], axis=1).astype(np.uint8)


def canonical_orders(unary, rel, next_unary, next_rel, mask, src, tgt, self_relations=False):
    """[T, N] object index per canonical slot (padding last) and the number of
    transitions whose ties needed permuting."""
    t, n = mask.shape
    colour = colours(unary, rel, mask, src, tgt, self_relations)
    order = np.argsort(colour, axis=1, kind="stable")
    sorted_colour = np.take_along_axis(colour, order, axis=1)
    real = np.take_along_axis(mask, order, axis=1)
    tie = (sorted_colour[:, 1:] == sorted_colour[:, :-1]) & real[:, 1:]  # slot s ~ s+1
    rows = np.flatnonzero(tie.any(1))
    if len(rows) == 0:
        return order, 0
    # A tie whose transposition is an automorphism of (pre, next) needs no permuting.
    o = order[rows]
    u, r = permute(unary[rows], rel[rows], o)
    nu, nr = permute(next_unary[rows], next_rel[rows], o)
    genuine = np.zeros(len(rows), dtype=bool)
    for s in range(n - 1):
        has = tie[rows, s]
        if not has.any():
            continue
        perm = np.arange(n)
        perm[[s, s + 1]] = perm[[s + 1, s]]
        same = np.ones(len(rows), dtype=bool)
        for arr_u, arr_r in ((u, r), (nu, nr)):
            same &= (arr_u[:, perm] == arr_u).all((1, 2))
            same &= (arr_r[:, :, perm][:, :, :, perm] == arr_r).all((1, 2, 3))
        genuine |= has & ~same
    for row in rows[genuine]:
        order[row] = _best_tie_order(
            unary[row], rel[row], next_unary[row], next_rel[row], order[row], tie[row]
        )
    return order, int(genuine.sum())


def _best_tie_order(unary, rel, next_unary, next_rel, order, tie):
    """Tries the permutations inside each run of tied slots; returns the order with
    the lexicographically smallest (precondition, next state) encoding."""
    n = len(order)
    runs, start = [], 0
    for s in range(n):
        if s == n - 1 or not tie[s]:
            if s > start:
                runs.append(list(range(start, s + 1)))
            start = s + 1
    choices = [list(itertools.permutations(run)) for run in runs]
    perms = []
    for combo in itertools.product(*choices):
        perm = np.arange(n)
        for run, p in zip(runs, combo, strict=True):
            perm[run] = p
        perms.append(order[perm])
    perms = np.array(perms)
    m = len(perms)
    u, r = permute(np.repeat(unary[None], m, 0), np.repeat(rel[None], m, 0), perms)
    nu, nr = permute(np.repeat(next_unary[None], m, 0), np.repeat(next_rel[None], m, 0), perms)
    enc = np.concatenate([encode(u, r), encode(nu, nr)], axis=1)
    best = np.lexsort(enc.T[::-1])[0]
    return perms[best]
