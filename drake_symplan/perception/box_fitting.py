"""Fit the known box models (5 cm cube, 5x25x5 cm long block) to surfaces and leftover points.

`fit_boxes` is the bottom-up fit. Each visible top surface is explained by one or more
boxes: a minimum-area rectangle gives its axes and extents; a 25 cm extent is a long block,
a 5 cm square a cube, and anything in between is a long block only if the rest of its
length is hidden under something higher (else a row of touching cubes). Boxes whose
bottoms float with nothing fitted under them are supported by objects seen only from the
side (a cube under a bridge): those are fitted to the leftover points below.

The thresholds are module constants, each with its reason (those for reading a top
surface in top_surfaces.py).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from drake_symplan.boxes import LONG, SIDE
from drake_symplan.perception.fitted_box import FittedBox, box_from_top, min_area_rectangle
from drake_symplan.perception.segmentation import CELL, HeightMap, find_surfaces
from drake_symplan.perception.top_surfaces import EDGE_BAND, boxes_from_surface

# One object fitted twice (`suppress_duplicates`).
DUPLICATE_DEPTH = 0.005  # m: a centre this deep inside a better box is the same object

# Supports seen from the side (`hidden_supports`, `_fit_side_clusters`).
LEANING_TILT = np.radians(5.0)  # a box tilted more than this leans on something
ON_TABLE = 0.02  # m: a bottom lower than this rests on the table
STACK_TOL = 0.012  # m: cubes this close to a column's axis and height are in it
SUPPORT_SEARCH = 0.03  # m: look for support points this far around a box's footprint
SUPPORT_LAYER = 0.005  # m: a support's own layer: from this above a box's height under its top
EXPLAINED_MARGIN = 0.006  # m: points this close to a fitted box are its own
MIN_SIDE_POINTS = 40  # points in a cluster to fit a box to its side faces
UNDER_MARGIN = 0.01  # m: a support's points lie under the box it holds, within this
MIN_UNDER_POINTS = 20  # ... at least this many (not a neighbour's face in the search band)
CLUSTER_DILATION = 2  # cells: side points are grown by this, so a face's pieces join
OWN_YAW_EXTENT = 0.02  # m: a cluster this wide has a yaw of its own (else the box above's)
LONG_CLUSTER = 0.08  # m: a cluster longer than this is a long block
CLUSTER_CORE = 98  # percentile: a cluster's length for its type, between the 2nd and 98th
BOTH_FACES = 0.8  # fraction of a box's size seen along an axis: both faces are seen
ONE_FACE_UNSURE = 0.3  # ... less than this: the box's centre there is uncertain
GAP = 0.01  # m: a nearly empty stretch this long splits a side cluster (`_split_at_gaps`)
GAP_BIN = 0.005  # m: ... measured in bins this long
STRAY_SHARE = 0.05  # a bin with this share of a typical bin's points is nearly empty

# Upright blocks (`upright_blocks`).
UPRIGHT_TILT = np.radians(10.0)  # cubes tilted less than this may be stacked in a column
COLUMN_CUBES = round(LONG / SIDE)  # cubes in a column as tall as a block standing on its end


def fit_boxes(points: np.ndarray, hm: HeightMap, known: list[FittedBox] = (),
              surfaces_from: HeightMap | None = None, prior: list[FittedBox] = ()
              ) -> list[FittedBox]:
    """Boxes for `points`: one or more per visible top surface (found in `surfaces_from`,
    default `hm`), then supports seen only from the side. `known` boxes are already
    placed: their space is taken and they need no new support. `prior`: the boxes before
    the action, for layouts that look alike from above."""
    boxes: list[FittedBox] = []
    for surface in find_surfaces(surfaces_from or hm):
        boxes.extend(boxes_from_surface(surface, hm, known, prior))
    boxes = suppress_duplicates(boxes)
    return upright_blocks(boxes + hidden_supports([*known, *boxes], points))


def suppress_duplicates(boxes: list[FittedBox]) -> list[FittedBox]:
    """Drops a box whose centre lies inside a better-supported box (one object fitted twice,
    e.g. a block whose top is split in two by a cube standing on its middle)."""
    kept: list[FittedBox] = []
    for box in sorted(boxes, key=lambda b: -b.points):
        if not any(k.contains(box.center[None], -DUPLICATE_DEPTH)[0] for k in kept):
            kept.append(box)
    return kept


def hidden_supports(boxes: list[FittedBox], points: np.ndarray) -> list[FittedBox]:
    """Boxes for objects seen only from the side, under boxes that would otherwise float.

    A box needs a support if its bottom is above the table or if it is tilted (a tipped
    block leans on something). Points under it that no fitted box explains are clustered
    and each cluster is fitted with an upright box whose top is where the points end.
    """
    found: list[FittedBox] = []
    queue = list(boxes)
    while queue:
        box = queue.pop(0)
        bottom = box.bottom_z()
        tilted = box.tilt > LEANING_TILT
        if bottom < ON_TABLE and not tilted:
            continue
        footprint = box.corners()[:, :2]
        # A support already seen under it does not end the search: a block may rest on
        # two (one seen, a cube under its middle seen only from the side); what the seen
        # one explains is left out below.
        # A level box's support, its top at the box's bottom, may be a block reaching
        # farther than the search's margin (a block under a cube).
        reach = SUPPORT_SEARCH if tilted else LONG / 2
        lo, hi = footprint.min(axis=0) - reach, footprint.max(axis=0) + reach
        sel = ((points[:, 2] < box.center[2]) & np.all(points[:, :2] >= lo, axis=1)
               & np.all(points[:, :2] <= hi, axis=1))
        cand = points[sel]
        for other in boxes + found:
            if len(cand):
                cand = cand[~other.contains(cand, EXPLAINED_MARGIN)]
        new = [b for b in _fit_side_clusters(cand, None if tilted else bottom, box)
               if not any(k.tilt <= LEANING_TILT and k.contains(b.center[None],
                                                               -DUPLICATE_DEPTH)[0]
                          for k in [*boxes, *found])]  # a box fitted again from under another
        found.extend(new)
        queue.extend(new)
    return found


def _fit_side_clusters(cand: np.ndarray, top: float | None,
                       above: FittedBox) -> list[FittedBox]:
    """Upright boxes for point clusters under `above`; `top` None: from the points. With
    a `top`, a cluster's type is read from its points in the support's own layer (under a
    block, the side faces of a cube on a block are one cluster with the block's)."""
    if len(cand) < MIN_SIDE_POINTS:
        return []
    lo = cand[:, :2].min(axis=0)
    idx = np.floor((cand[:, :2] - lo) / CELL).astype(int)
    grid = np.zeros(idx.max(axis=0) + 1, bool)
    grid[idx[:, 0], idx[:, 1]] = True
    labels, n = ndimage.label(ndimage.binary_dilation(grid, iterations=CLUSTER_DILATION))
    out = []
    for lab in range(1, n + 1):
        for pts in _split_at_gaps(cand[labels[idx[:, 0], idx[:, 1]] == lab]):
            box = _side_box(pts, top, above)
            if box is not None:
                out.append(box)
    return out


def _split_at_gaps(pts: np.ndarray) -> list[np.ndarray]:
    """A side cluster cut where its points leave a stretch of GAP or more nearly empty
    along its longer axis, where that is longer than a cube: two cubes side by side under a
    span, joined by the clustering's dilation and a noisy sensor's stray points, are two
    supports."""
    # No two points farther apart than the footprint's diagonal: a cube's cluster (most of
    # them) is left whole before the rectangle `_side_box` fits anyway.
    if len(pts) < 2 * MIN_SIDE_POINTS or np.hypot(*np.ptp(pts[:, :2], axis=0)) <= LONG_CLUSTER:
        return [pts]
    angle, *_ = min_area_rectangle(pts[:, :2] - pts[:, :2].mean(axis=0))
    u = pts[:, :2] @ np.array([np.cos(angle), np.sin(angle)])
    v = pts[:, :2] @ np.array([-np.sin(angle), np.cos(angle)])
    u = u if np.ptp(u) >= np.ptp(v) else v
    if np.ptp(u) <= LONG_CLUSTER:  # a cube's own faces, seen from two sides, are one box
        return [pts]
    counts, edges = np.histogram(u, np.arange(u.min(), u.max() + GAP_BIN, GAP_BIN))
    sparse = counts <= STRAY_SHARE * np.median(counts[counts > 0])
    best, run, cut = 0, 0, None
    for i, empty in enumerate(sparse):
        run = run + 1 if empty else 0
        if run > best and 0 < i - run + 1 and i + 1 < len(sparse):
            best, cut = run, edges[i + 1 - run // 2]
    if cut is None or best * GAP_BIN < GAP:
        return [pts]
    parts = [pts[u < cut], pts[u >= cut]]
    if min(len(q) for q in parts) < MIN_SIDE_POINTS:
        return [pts]
    return [q for part in parts for q in _split_at_gaps(part)]


def _side_box(pts: np.ndarray, top: float | None, above: FittedBox) -> FittedBox | None:
    """The upright box a side cluster shows (`_fit_side_clusters`), or None."""
    if len(pts) < MIN_SIDE_POINTS:
        return None
    if top is not None and _under(pts, above) < MIN_UNDER_POINTS:
        return None  # the face of a box beside the support (the next tower under a bridge)
    # The visible side faces (one face, or an L of two) give the box's own yaw; the
    # box above may have been turned relative to it.
    angle, *_ = min_area_rectangle(pts[:, :2] - pts[:, :2].mean(axis=0))
    yaw = angle if np.ptp(pts[:, :2], axis=0).max() > OWN_YAW_EXTENT else above.yaw
    axes = np.array([[np.cos(yaw), np.sin(yaw)], [-np.sin(yaw), np.cos(yaw)]])
    uv = pts[:, :2] @ axes.T
    ext = np.ptp(uv, axis=0)
    layer = uv if top is None else uv[pts[:, 2] > top - SIDE + SUPPORT_LAYER]
    if len(layer) < MIN_SIDE_POINTS:
        layer = uv
    # The type from the extent without its tails: a noisy sensor's stray points (a
    # leaning block's own underside, flying pixels) stretched a cube's 5 cm past 8.
    core = np.subtract(*np.percentile(layer, [CLUSTER_CORE, 100 - CLUSTER_CORE], axis=0))
    kind = "long" if core.max() > LONG_CLUSTER else "cube"
    dims = np.array([SIDE, LONG if kind == "long" else SIDE])
    if kind == "long" and ext[0] > ext[1]:
        axes_k = axes[::-1]
        uv = uv[:, ::-1]
        ext = ext[::-1]
    else:
        axes_k = axes
    centre_uv = np.empty(2)
    uncertain = False
    for d in range(2):
        a, b = uv[:, d].min(), uv[:, d].max()
        if ext[d] >= BOTH_FACES * dims[d]:
            centre_uv[d] = (a + b) / 2
        else:  # one face seen: anchor on the side with more points near its extreme
            near_a = np.sum(uv[:, d] < a + EDGE_BAND)
            near_b = np.sum(uv[:, d] > b - EDGE_BAND)
            centre_uv[d] = b - dims[d] / 2 if near_b >= near_a else a + dims[d] / 2
            uncertain |= ext[d] < ONE_FACE_UNSURE * dims[d]
    xy = centre_uv @ axes_k
    y_dir = np.array([*axes_k[1], 0.0])
    n = np.array([0.0, 0.0, 1.0])
    z_top = top if top is not None else max(SIDE, SIDE * round(pts[:, 2].max() / SIDE))
    box = box_from_top(np.array([xy[0], xy[1], z_top]), n, y_dir, kind, uncertain,
                        len(pts))
    box.from_side = True
    return box


def _under(pts: np.ndarray, box: FittedBox) -> int:
    """How many of `pts` lie under the footprint of the upright `box` (UNDER_MARGIN): within
    its extents along its two axes nearest the horizontal (a standing block's too)."""
    flat = np.argsort(np.abs(box.R[2, :]))[:2]
    local = (pts - box.center) @ box.R[:, flat]
    return int(np.sum(np.all(np.abs(local) <= box.half_extents[flat] + UNDER_MARGIN, axis=1)))


def upright_blocks(boxes: list[FittedBox]) -> list[FittedBox]:
    """Five cubes stacked in one straight column are a long block standing on its end.

    From the cameras the two look alike (the seams of a tower are invisible); a tipped
    block standing up is far more common in these scenes than a tower of five.
    """
    cubes = sorted((b for b in boxes if b.type == "cube" and b.tilt < UPRIGHT_TILT),
                   key=lambda b: b.center[2])
    used: set[int] = set()
    merged = []
    for i, base in enumerate(cubes):
        if id(base) in used:
            continue
        column = [base]
        for other in cubes[i + 1:]:
            top = column[-1]
            if (id(other) not in used
                    and abs(other.center[2] - top.center[2] - SIDE) < STACK_TOL
                    and np.linalg.norm(other.center[:2] - top.center[:2]) < STACK_TOL):
                column.append(other)
            if len(column) == COLUMN_CUBES:
                break
        if len(column) < COLUMN_CUBES:
            continue
        used.update(id(c) for c in column)
        x = base.R[:, 0] - base.R[2, 0] * np.array([0.0, 0.0, 1.0])
        x /= np.linalg.norm(x)
        up = np.array([0.0, 0.0, 1.0])
        R = np.column_stack([x, up, np.cross(x, up)])
        centre = np.mean([c.center for c in column], axis=0)
        merged.append(FittedBox("long", centre, R, True, sum(c.points for c in column)))
    return [b for b in boxes if id(b) not in used] + merged
