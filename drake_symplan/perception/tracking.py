"""Perception with a prior: the scene perceived before an action anchors the fit after it.

A pick and place moves a few objects and leaves the rest where they were. An object of the
prior scene whose old pose, or one nudged by up to 1 cm, the new depth data still supports
(some of it is seen, and its top face is seen at its height or hidden under something
higher, almost nowhere contradicted by the table or a lower surface) is kept, refined by a
fresh fit of the same box when there is one. The points those anchored boxes do not explain are fitted
bottom-up, with the anchored boxes' space unavailable to hidden parts. A pick and place
creates no object, so fits beyond the prior's count of a type are surplus and the least
supported go. No simulator state is used.
"""

from __future__ import annotations

import dataclasses as dc
from collections import Counter

import numpy as np

from drake_symplan.perception import segmentation as seg
from drake_symplan.perception.box_fitting import fit_boxes
from drake_symplan.perception.fitted_box import FittedBox

ANCHOR_TOL = 0.008  # m: a top-face sample is contradicted if seen lower than this
MAX_CONTRADICTED = 0.05  # fraction of top-face samples; ~5 mm of drift for a cube
REFINE_DISTANCE = 0.015  # m: a fresh fit this close (same type, same yaw) refines an anchor
REFINE_ANGLE = np.radians(8.0)
MIN_TOP_SEEN = 0.2  # fraction of top-face samples seen at the box's height
MIN_OWN_POINTS = 30  # else: side points only this box explains
NUDGE, NUDGE_STEP = 0.01, 0.005  # m: how far a prior box may have been pushed in x, y
_steps = np.arange(-NUDGE, NUDGE + 1e-9, NUDGE_STEP)
_NUDGES = sorted((np.array([x, y, 0.0]) for x in _steps for y in _steps),
                 key=lambda d: (float(np.linalg.norm(d)), tuple(d)))  # smallest first
VETO_DEPTH = 0.02  # m: how far inside a fresh fit a prior box's centre must lie to veto it
POINT_MARGIN = 0.006  # m: points this close to an anchored box are its own


def top_face_samples(box: FittedBox, inset: float = 0.004, step: float = 0.01) -> np.ndarray:
    """World points [K, 3] on the box face that looks up the most, inset from its edges."""
    k = int(np.argmax(np.abs(box.R[2, :])))
    h = box.half_extents
    axes = [i for i in range(3) if i != k]
    grids = [np.linspace(-h[i] + inset, h[i] - inset,
                         max(2, int(round(2 * (h[i] - inset) / step)) + 1)) for i in axes]
    a, b = np.meshgrid(*grids, indexing="ij")
    local = np.zeros((a.size, 3))
    local[:, axes[0]], local[:, axes[1]] = a.ravel(), b.ravel()
    local[:, k] = np.sign(box.R[2, k]) * h[k]
    return box.center + local @ box.R.T


def supported(box: FittedBox, hm: seg.HeightMap, others: list[FittedBox] = ()
              ) -> FittedBox | None:
    """`box` where the depth data still supports it, or None. Almost none of its top face
    may be contradicted, where it was or nudged by up to NUDGE (a placement pushes what it
    lands on), and some of the box must be seen: part of its top at its height, or points
    on its sides that no other box (`others`: the other prior boxes, fresh fits) can
    claim. A box held right above its old place hides that place without being there."""
    top = top_face_samples(box)
    for shift in _NUDGES:
        if hm.contradicts(top + shift, ANCHOR_TOL).mean() <= MAX_CONTRADICTED:
            break
    else:
        return None
    moved = dc.replace(box, center=box.center + shift) if shift.any() else box
    s = top + shift
    if np.mean(np.abs(hm.lookup(s[:, :2]) - s[:, 2]) < ANCHOR_TOL) >= MIN_TOP_SEEN:
        return moved
    own = moved.contains(hm.points, 0.003)
    for other in others:
        own[own] &= ~other.contains(hm.points[own], 0.003)
    return moved if own.sum() >= MIN_OWN_POINTS else None


def _same_box(a: FittedBox, b: FittedBox) -> bool:
    if a.type != b.type or np.linalg.norm(a.center - b.center) > REFINE_DISTANCE:
        return False
    # Compare the long axes up to the box's symmetry (a cube: any face axis).
    cos = np.abs(a.R.T @ b.R).max(axis=0) if a.type == "cube" else [abs(a.R[:, 1] @ b.R[:, 1])]
    return bool(np.min(cos) >= np.cos(REFINE_ANGLE))


def anchor(prior: list[FittedBox], fresh: list[FittedBox], hm: seg.HeightMap
           ) -> tuple[list[FittedBox], list[FittedBox]]:
    """The prior boxes the data still supports, each replaced by its fresh fit if any:
    (those that no fresh fit vetoes, all of them), in prior order.

    A confident fresh fit of another box seen from above through the prior box's centre
    vetoes it (`_vetoes`): its top face is then explained by that box (a block put down
    where a cube stood). Boxes fitted to side faces only do not veto: that is what hidden
    anchors look like."""
    kept, every = [], []
    for box in prior:
        # Points a fresh fit seen from above explains are not the prior box's own: a block
        # set on another's end pushed it 12 cm along, right under where it lay, and its
        # side faces, seen there, held its old pose while its seen end was fitted apart.
        seen_fits = [b for b in fresh
                     if not (b.from_side or b.uncertain) and not _same_box(b, box)]
        box = supported(box, hm, [b for b in prior if b is not box] + seen_fits)
        if box is None:
            continue
        match = [b for b in fresh if _same_box(b, box)]
        if match:
            box = max(match, key=lambda b: b.points)
            kept.append(box)
        elif not any(_vetoes(b, box) for b in fresh):
            kept.append(box)
        every.append(box)
    return kept, every


def _vetoes(fit: FittedBox, box: FittedBox) -> bool:
    """Does the fresh `fit` say that prior `box` is gone? It must be confident, seen from
    above, and overlap the box's centre, but not be a piece of the box: a cube-sized fit
    wholly inside a prior block is the visible end of that block (the rest hidden under
    something put on it), not another object. Nor does a fit of the box's own type: a pick
    and place moves one box (and what rides on it) away from its place and onto a target,
    so no other box of that type ends up where a box still supported by the data stood;
    such a fit is this box merged with a neighbour (a cube touching a block's end)."""
    if fit.uncertain or fit.from_side or fit.type == box.type:
        return False
    if fit.contains(box.center[None], -VETO_DEPTH)[0]:
        return True
    return bool(box.contains(fit.center[None], -VETO_DEPTH)[0]) and not _piece_of(fit, box)


def _piece_of(fit: FittedBox, box: FittedBox, margin: float = 0.01) -> bool:
    if fit.type != "cube" or box.type != "long":
        return False
    return bool(box.contains(fit.corners(), margin).all())


def unexplained(points: np.ndarray, boxes: list[FittedBox]) -> np.ndarray:
    keep = np.ones(len(points), bool)
    for b in boxes:
        keep &= ~b.contains(points, POINT_MARGIN)
    return points[keep]


def keep_inventory(anchored: list[FittedBox], new: list[FittedBox], inventory: Counter
                   ) -> list[FittedBox]:
    """`new` without the surplus over `inventory` (after the anchored boxes), dropping the
    uncertain and least supported fits first."""
    left = Counter(inventory)
    left.subtract(Counter(b.type for b in anchored))
    kept = []
    for b in sorted(new, key=lambda b: (b.uncertain, -b.points)):
        if left[b.type] > 0:
            left[b.type] -= 1
            kept.append(b)
    return kept


def track(prior: list[FittedBox], fresh: list[FittedBox], points: np.ndarray,
          hm: seg.HeightMap) -> list[FittedBox]:
    """The boxes after an action, given the boxes before it and a fresh (bottom-up) fit
    of `points`.

    Hypotheses, in order: the fresh fit if it agrees with the prior everywhere it is
    anchored; anchors (with vetoes) + a fit of the rest; every supported prior box
    anchored (a fresh fit that cut touching boxes into wrong pieces vetoes wrongly) + a fit
    of the rest. The first that keeps the prior's inventory of types wins; else the fresh
    fit (nothing trimmed: a held object cut up by the robot's self-filter is better left
    in pieces for association)."""
    inventory = Counter(b.type for b in prior)
    anchored, unvetoed = anchor(prior, fresh, hm)
    if Counter(b.type for b in fresh) == inventory and all(
            any(a is b for b in fresh) for a in anchored):
        return fresh  # the fresh fit agrees with the prior everywhere it is anchored
    hypotheses = [anchored] + ([unvetoed] if len(unvetoed) > len(anchored) else [])
    for anchored in hypotheses:
        rest = unexplained(points, anchored)
        new = keep_inventory(anchored, fit_boxes(rest, hm, anchored, seg.height_map(rest),
                                                 prior), inventory)
        tracked = anchored + new
        if Counter(b.type for b in tracked) == inventory:
            return tracked
    return fresh
