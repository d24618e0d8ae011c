"""Fit the known box models (5 cm cube, 5x25x5 cm long block) to surfaces and leftover points.

`fit_boxes` is the bottom-up fit. Each visible top surface is explained by one or more
boxes: a minimum-area rectangle gives its axes and extents; a 25 cm extent is a long block,
a 5 cm square a cube, and anything in between is a long block only if the rest of its
length is hidden under something higher (else a row of touching cubes). Boxes whose
bottoms float with nothing fitted under them are supported by objects seen only from the
side (a cube under a bridge): those are fitted to the leftover points below.

The thresholds are module constants below, each with its reason.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Sequence

import numpy as np
from scipy import ndimage
from scipy.spatial import ConvexHull, QhullError

from drake_symplan.boxes import HALF_EXTENTS, LONG, SIDE
from drake_symplan.perception.segmentation import CELL, HeightMap, Surface, find_surfaces

# Minimum-area rectangle: a 1 deg search over a quarter turn (a rectangle repeats every
# 90 deg), then 0.1 deg steps within 1 deg of the best.
_ANGLES = np.radians(np.arange(0.0, 90.0, 1.0))
_REFINE_ANGLES = np.radians(np.arange(-1.0, 1.01, 0.1))
HULL_MIN_POINTS = 8  # up to this many points, taking the convex hull first saves nothing

# Hidden or seen (`_hidden_fractions`).
SEEN_TOL = 0.01  # m: a point is contradicted where the map is empty or this much lower
OCCUPIED_MARGIN = 0.002  # m: a point this deep inside a known box is in taken space
BLOCK_SAMPLE_INSET = 0.01  # m: samples along a block's top stop this short of its ends
BLOCK_SAMPLES = 24  # samples along a block's top centre line
PLACEMENTS = 21  # candidate centres when sliding a block along its axis

# Reading a top surface (`boxes_from_surface`).
STRIP_CORE = (0.25, 0.75)  # a strip's core: the middle half of its width, free of edges
MIN_CORE_POINTS = 10  # points in a strip's core to fit anything to it
CUBE_SHARE = 10  # a cube in a row of blocks and cubes gets 1/10 of the points as support
_ROUND_OFF = 1e-9  # m: slack for float round-off in comparisons
WHOLE_BLOCK_SLACK = 0.015  # m: a seen length this short of 25 cm is a whole block
EDGE_BAND = 0.006  # m: points this close to an extreme lie on that edge (count density)
PARTIAL_BLOCK = 0.075  # m: a piece longer than a cube and a half may be a hidden block
HIDDEN_ENOUGH = 0.9  # fraction of a placement seen or hidden for it to be possible
HIDDEN_SURE = 0.97  # ... and for it to be certain
END_PROBE = 0.008  # m: probe this far beyond a visible end to see if the table is there
SHORT_CUBE = 0.035  # m: a cube seen shorter than this is uncertain
PRIOR_REACH = 0.03  # m beyond half a block: how far a prior block may lie from a piece
PRIOR_SNAP = 0.05  # m: a block through a piece must lie this close to the prior block
STANDING_AXIS = 0.5  # a block's long axis projected on a plane: shorter, it stood on end
LAYOUT_DISTANCE_CAP = 0.1  # m: cap on a layout box's distance to its nearest prior box
DUPLICATE_DEPTH = 0.005  # m: a centre this deep inside a better box is the same object

# Supports seen from the side (`hidden_supports`, `_fit_side_clusters`).
LEANING_TILT = np.radians(5.0)  # a box tilted more than this leans on something
ON_TABLE = 0.02  # m: a bottom lower than this rests on the table
STACK_TOL = 0.012  # m: a bottom this close to a top rests on it; columns align this well
SUPPORT_SEARCH = 0.03  # m: look for support points this far around a box's footprint
EXPLAINED_MARGIN = 0.006  # m: points this close to a fitted box are its own
FOOTPRINT_OVERLAP = 0.005  # m: footprints must overlap by this to support
MIN_SIDE_POINTS = 40  # points in a cluster to fit a box to its side faces
CLUSTER_DILATION = 2  # cells: side points are grown by this, so a face's pieces join
OWN_YAW_EXTENT = 0.02  # m: a cluster this wide has a yaw of its own (else the box above's)
LONG_CLUSTER = 0.08  # m: a cluster longer than this is a long block
BOTH_FACES = 0.8  # fraction of a box's size seen along an axis: both faces are seen
ONE_FACE_UNSURE = 0.3  # ... less than this: the box's centre there is uncertain

# Upright blocks (`upright_blocks`).
UPRIGHT_TILT = np.radians(10.0)  # cubes tilted less than this may be stacked in a column
COLUMN_CUBES = round(LONG / SIDE)  # cubes in a column as tall as a block standing on its end


@dc.dataclass
class FittedBox:
    type: str
    center: np.ndarray  # (3,)
    R: np.ndarray  # 3x3, columns: box x, y (long axis), z in world
    uncertain: bool = False
    points: int = 0  # how many points support it
    from_side: bool = False  # fitted to side faces only (its top is hidden)

    @property
    def yaw(self) -> float:
        y = self.R[:, 1]
        return float(np.arctan2(-y[0], y[1]))  # yaw of the box's x axis == of its y axis

    @property
    def tilt(self) -> float:
        return float(np.arccos(np.clip(np.abs(self.R[2, :]).max(), -1, 1)))

    @property
    def half_extents(self) -> np.ndarray:
        return np.array(HALF_EXTENTS[self.type])

    def contains(self, pts: np.ndarray, margin: float) -> np.ndarray:
        local = (pts - self.center) @ self.R
        return np.all(np.abs(local) <= self.half_extents + margin, axis=1)

    def top_z(self) -> float:
        corners = self.corners()
        return float(corners[:, 2].max())

    def bottom_z(self) -> float:
        return float(self.corners()[:, 2].min())

    def corners(self) -> np.ndarray:
        s = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)])
        return self.center + (s * self.half_extents) @ self.R.T


def _plane_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    b1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
    b1 /= np.linalg.norm(b1)
    return b1, np.cross(n, b1)


def min_area_rectangle(uv: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """(angle, lo, hi, axes 2x2) of the smallest enclosing rectangle of 2D points."""
    if len(uv) > HULL_MIN_POINTS:
        try:
            uv = uv[ConvexHull(uv).vertices]  # the rectangle only depends on the hull
        except QhullError:
            pass
    best = None
    for angles in (_ANGLES, None):
        if angles is None:  # refine around the coarse optimum
            angles = best[0] + _REFINE_ANGLES
        c, s = np.cos(angles), np.sin(angles)
        pu = uv @ np.stack([c, s])  # [M, A]
        pv = uv @ np.stack([-s, c])
        area = np.ptp(pu, axis=0) * np.ptp(pv, axis=0)
        k = int(np.argmin(area))
        best = (angles[k], pu[:, k], pv[:, k])
    a, pu, pv = best
    axes = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    return a, np.array([pu.min(), pv.min()]), np.array([pu.max(), pv.max()]), axes


def _box_from_top(top_center: np.ndarray, n: np.ndarray, long_dir: np.ndarray, kind: str,
                  uncertain: bool, npts: int) -> FittedBox:
    y = long_dir - (long_dir @ n) * n
    y /= np.linalg.norm(y)
    x = np.cross(y, n)
    R = np.column_stack([x, y, n])
    return FittedBox(kind, top_center - n * HALF_EXTENTS[kind][2], R, uncertain, npts)


def _hidden_fractions(hm: HeightMap, pts3: np.ndarray, occupied: Sequence[FittedBox] = ()
                      ) -> np.ndarray:
    """For each set of plane points in `pts3` [K, S, 3], the fraction that are seen at that
    height or hidden under something higher; the rest are contradicted (the table or a
    lower surface is seen there: the table is not in the map, so an empty cell counts as
    the table; or the space is taken by an `occupied` box). Beyond the map's edge nothing
    is known."""
    flat = pts3.reshape(-1, 3)
    contradicted = hm.contradicts(flat, SEEN_TOL)
    for box in occupied:
        contradicted |= box.contains(flat, OCCUPIED_MARGIN)
    return 1.0 - contradicted.reshape(pts3.shape[:-1]).mean(axis=-1)


_BLOCK_SAMPLES = np.linspace(-LONG / 2 + BLOCK_SAMPLE_INSET, LONG / 2 - BLOCK_SAMPLE_INSET,
                             BLOCK_SAMPLES)


def _block_hidden_fractions(hm: HeightMap, top_centres: np.ndarray, d: np.ndarray,
                            occupied: Sequence[FittedBox]) -> np.ndarray:
    """`_hidden_fractions` along the top centre line of long blocks with axis `d` and top
    centres `top_centres` [K, 3]."""
    pts = top_centres[:, None, :] + _BLOCK_SAMPLES[None, :, None] * d
    return _hidden_fractions(hm, pts, occupied)


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


def boxes_from_surface(surface: Surface, hm: HeightMap, occupied: Sequence[FittedBox] = (),
                       prior: Sequence[FittedBox] = ()) -> list[FittedBox]:
    """The boxes whose top faces make up `surface`; `occupied`: boxes already known, whose
    space a hidden part cannot take; `prior`: the boxes before the action, which decide
    between layouts that look the same from above."""
    n = surface.normal
    b1, b2 = _plane_basis(n)
    rel = surface.points - surface.centroid
    uv = np.column_stack([rel @ b1, rel @ b2])
    _, lo, hi, axes = min_area_rectangle(uv)
    ext = hi - lo
    # Long side first: u along the rectangle's longer extent.
    if ext[1] > ext[0]:
        axes, lo, hi, ext = axes[::-1], lo[::-1], hi[::-1], ext[::-1]
    u_dir = axes[0, 0] * b1 + axes[0, 1] * b2
    v_dir = axes[1, 0] * b1 + axes[1, 1] * b2
    pu, pv = uv @ axes[0], uv @ axes[1]
    n_strips = max(1, int(round(ext[1] / SIDE)))
    boxes = []
    for k in range(n_strips):
        v0 = lo[1] + k * ext[1] / n_strips
        width = ext[1] / n_strips
        in_strip = (pv >= v0 - _ROUND_OFF) & (pv <= v0 + width + _ROUND_OFF)
        # The strip's length from its core only: a neighbour's edge points lie on the border.
        core = in_strip & (pv > v0 + STRIP_CORE[0] * width) & (pv < v0 + STRIP_CORE[1] * width)
        if core.sum() < MIN_CORE_POINTS:
            continue
        su = pu[core]
        u_lo, u_hi = su.min(), su.max()
        v_mid = pv[in_strip].min() / 2 + pv[in_strip].max() / 2 if n_strips > 1 \
            else (lo[1] + hi[1]) / 2
        length = u_hi - u_lo
        origin = surface.centroid + v_dir * v_mid
        npts = int(in_strip.sum())
        if length > LONG - WHOLE_BLOCK_SLACK:  # the whole block is seen
            n_long = int((length + WHOLE_BLOCK_SLACK) // LONG)
            extra = max(0, int(round((length - n_long * LONG) / SIDE)))
            if extra == 0 and n_long == 1:
                centre_u = (u_lo + u_hi) / 2
                boxes.append(_box_from_top(origin + u_dir * centre_u, n, u_dir, "long",
                                           False, npts))
                continue
            # Blocks end to end, with cubes touching an end: the blocks go at the end
            # whose edge points are densest (a block's end face is seen), cubes along
            # the rest. Which order is right is ambiguous from above: uncertain.
            # With a prior (the scene before the action) the order nearer to it wins.
            layouts = []
            for at_lo in (True, False):
                start, sign, layout = (u_lo, 1.0, []) if at_lo else (u_hi, -1.0, [])
                for size in [LONG] * n_long + [SIDE] * extra:
                    kind = "long" if size == LONG else "cube"
                    layout.append(_box_from_top(
                        origin + u_dir * (start + sign * size / 2), n, u_dir, kind, True,
                        npts // n_long if kind == "long" else npts // CUBE_SHARE))
                    start += sign * size
                layouts.append(layout)
            if prior:
                boxes.extend(min(layouts, key=lambda lay: _distance_to(lay, prior)))
            else:
                dense_lo = np.sum(su < u_lo + EDGE_BAND) >= np.sum(su > u_hi - EDGE_BAND)
                boxes.extend(layouts[0] if dense_lo else layouts[1])
            continue
        if length > PARTIAL_BLOCK:
            # Could be a long block partly hidden under something, or touching cubes:
            # slide a 25 cm block over every placement that covers what is seen.
            centres = np.linspace(u_hi - LONG / 2, u_lo + LONG / 2, PLACEMENTS)
            fracs = _block_hidden_fractions(hm, origin + np.outer(centres, u_dir), u_dir,
                                            occupied)
            if fracs.max() > HIDDEN_ENOUGH:
                good = centres[fracs >= fracs.max() - _ROUND_OFF]
                centre_u = (good.min() + good.max()) / 2
                # A visible end that borders the table is the block's real end.
                beyond = origin + np.outer([u_lo - END_PROBE, u_hi + END_PROBE], u_dir)
                lo_real, hi_real = _hidden_fractions(hm, beyond[:, None], occupied) == 0
                if lo_real and not hi_real:
                    centre_u = u_lo + LONG / 2
                elif hi_real and not lo_real:
                    centre_u = u_hi - LONG / 2
                boxes.append(_box_from_top(origin + u_dir * centre_u, n, u_dir, "long",
                                           fracs.max() < HIDDEN_SURE, npts))
                continue
        if length <= PARTIAL_BLOCK and prior:
            # A short piece may be the visible end of a block the prior knows, now mostly
            # under something put on it.
            block = _prior_block_through(origin + u_dir * (u_lo + u_hi) / 2, n, prior, hm,
                                         occupied, npts)
            if block is not None:
                boxes.append(block)
                continue
        count = max(1, int(round(length / SIDE)))
        for j in range(count):
            centre_u = u_lo + length * (j + 0.5) / count
            boxes.append(_box_from_top(origin + u_dir * centre_u, n, u_dir, "cube",
                                       length < SHORT_CUBE, npts // count))
    return boxes


def _prior_block_through(piece: np.ndarray, n: np.ndarray, prior: Sequence[FittedBox],
                         hm: HeightMap, occupied: Sequence[FittedBox], npts: int
                         ) -> FittedBox | None:
    """A long block along a nearby prior block's axis that covers the visible `piece`
    (a point on its top) and is hidden everywhere else, placed nearest the prior one."""
    best = None
    for p in prior:
        reach = LONG / 2 + PRIOR_REACH
        if p.type != "long" or np.linalg.norm(p.center[:2] - piece[:2]) > reach:
            continue
        d = p.R[:, 1] - (p.R[:, 1] @ n) * n
        if np.linalg.norm(d) < STANDING_AXIS:  # the prior block stood on its end
            continue
        d /= np.linalg.norm(d)
        offsets = np.linspace(-LONG / 2 + SIDE / 2, LONG / 2 - SIDE / 2, PLACEMENTS)
        centres = piece + np.outer(offsets, d)
        hidden = _block_hidden_fractions(hm, centres, d, occupied)
        for centre in centres[hidden >= HIDDEN_ENOUGH]:
            top_prior = p.center + n * HALF_EXTENTS["long"][2]
            dist = float(np.linalg.norm(centre - top_prior))
            if dist < PRIOR_SNAP and (best is None or dist < best[0]):
                best = (dist, centre, d)
    if best is None:
        return None
    return _box_from_top(best[1], n, best[2], "long", True, npts)


def _distance_to(layout: list[FittedBox], prior: Sequence[FittedBox]) -> float:
    """Sum over `layout` of the distance to the nearest prior box of the same type."""
    total = 0.0
    for b in layout:
        d = [np.linalg.norm(b.center - p.center) for p in prior if p.type == b.type]
        total += min(min(d, default=LAYOUT_DISTANCE_CAP), LAYOUT_DISTANCE_CAP)
    return total


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
        if not tilted and any(abs(other.top_z() - bottom) < STACK_TOL
                              and _xy_overlap(footprint, other)
                              for other in boxes + found if other is not box):
            continue
        lo, hi = footprint.min(axis=0) - SUPPORT_SEARCH, footprint.max(axis=0) + SUPPORT_SEARCH
        sel = ((points[:, 2] < box.center[2]) & np.all(points[:, :2] >= lo, axis=1)
               & np.all(points[:, :2] <= hi, axis=1))
        cand = points[sel]
        for other in boxes + found:
            if len(cand):
                cand = cand[~other.contains(cand, EXPLAINED_MARGIN)]
        new = _fit_side_clusters(cand, None if tilted else bottom, box)
        found.extend(new)
        queue.extend(new)
    return found


def _xy_overlap(footprint: np.ndarray, other: FittedBox) -> bool:
    o = other.corners()[:, :2]
    return bool(np.all(footprint.max(axis=0) > o.min(axis=0) + FOOTPRINT_OVERLAP)
                and np.all(o.max(axis=0) > footprint.min(axis=0) + FOOTPRINT_OVERLAP))


def _fit_side_clusters(cand: np.ndarray, top: float | None,
                       above: FittedBox) -> list[FittedBox]:
    """Upright boxes for point clusters under `above`; `top` None: from the points."""
    if len(cand) < MIN_SIDE_POINTS:
        return []
    lo = cand[:, :2].min(axis=0)
    idx = np.floor((cand[:, :2] - lo) / CELL).astype(int)
    grid = np.zeros(idx.max(axis=0) + 1, bool)
    grid[idx[:, 0], idx[:, 1]] = True
    labels, n = ndimage.label(ndimage.binary_dilation(grid, iterations=CLUSTER_DILATION))
    out = []
    for lab in range(1, n + 1):
        pts = cand[labels[idx[:, 0], idx[:, 1]] == lab]
        if len(pts) < MIN_SIDE_POINTS:
            continue
        # The visible side faces (one face, or an L of two) give the box's own yaw; the
        # box above may have been turned relative to it.
        angle, *_ = min_area_rectangle(pts[:, :2] - pts[:, :2].mean(axis=0))
        yaw = angle if np.ptp(pts[:, :2], axis=0).max() > OWN_YAW_EXTENT else above.yaw
        axes = np.array([[np.cos(yaw), np.sin(yaw)], [-np.sin(yaw), np.cos(yaw)]])
        uv = pts[:, :2] @ axes.T
        ext = np.ptp(uv, axis=0)
        kind = "long" if ext.max() > LONG_CLUSTER else "cube"
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
        box = _box_from_top(np.array([xy[0], xy[1], z_top]), n, y_dir, kind, uncertain,
                            len(pts))
        box.from_side = True
        out.append(box)
    return out


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
