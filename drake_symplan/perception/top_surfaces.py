"""Read one visible top surface as the top faces of one or more boxes: strips of it are
whole blocks, blocks partly hidden under something higher, or rows of cubes."""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Iterator, Sequence

import numpy as np

from drake_symplan.boxes import HALF_EXTENTS, LONG, SIDE
from drake_symplan.perception.fitted_box import (
    FittedBox,
    box_from_top,
    min_area_rectangle,
    plane_basis,
)
from drake_symplan.perception.segmentation import HeightMap, Surface
from drake_symplan.perception.surface_parts import split_surface

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
# m: a piece longer than this may be a block partly hidden under something higher: a
# cube's top is seen 5.1-5.6 cm long (realsense), a block's end left 7 cm clear by a
# block on it 7.2-7.4 cm (was 7.5 cm: that end was a cube, the block a second box)
PARTIAL_BLOCK = 0.065
HIDDEN_ENOUGH = 0.9  # fraction of a placement seen or hidden for it to be possible
HIDDEN_SURE = 0.97  # ... and for it to be certain
END_PROBE = 0.008  # m: probe this far beyond a visible end to see if the table is there
SHORT_CUBE = 0.035  # m: a cube seen shorter than this is uncertain
PRIOR_REACH = 0.03  # m beyond half a block: how far a prior block may lie from a piece
PRIOR_SNAP = 0.05  # m: a block through a piece must lie this close to the prior block
STANDING_AXIS = 0.5  # a block's long axis projected on a plane: shorter, it stood on end
LAYOUT_DISTANCE_CAP = 0.1  # m: cap on a layout box's distance to its nearest prior box


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


def boxes_from_surface(surface: Surface, hm: HeightMap, occupied: Sequence[FittedBox] = (),
                       prior: Sequence[FittedBox] = ()) -> list[FittedBox]:
    """The boxes whose top faces make up `surface`; `occupied`: boxes already known, whose
    space a hidden part cannot take; `prior`: the boxes before the action, which decide
    between layouts that look the same from above."""
    boxes = []
    for part in split_surface(surface):
        for strip in _strips(part):
            boxes.extend(_strip_boxes(strip, hm, occupied, prior))
    return boxes


@dc.dataclass
class _Strip:
    """A box-wide strip of a top surface, along the long side `u` of its rectangle."""

    n: np.ndarray  # the surface's normal
    u_dir: np.ndarray  # u in world
    origin: np.ndarray  # u = 0 on the strip's centre line
    su: np.ndarray  # u of the points in the strip's core
    u_lo: float  # where the core's points start and end along u
    u_hi: float
    npts: int  # points in the whole strip

    @property
    def length(self) -> float:
        return self.u_hi - self.u_lo

    def box(self, centre_u: float, kind: str, uncertain: bool, npts: int) -> FittedBox:
        """A box whose top centre lies at `centre_u` on the strip's centre line."""
        return box_from_top(self.origin + self.u_dir * centre_u, self.n, self.u_dir, kind,
                            uncertain, npts)


def _strips(surface: Surface) -> Iterator[_Strip]:
    """`surface` cut into box-wide strips along the long side of its minimum-area rectangle,
    leaving out strips with too few points in their core."""
    n = surface.normal
    b1, b2 = plane_basis(n)
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
    for k in range(n_strips):
        v0 = lo[1] + k * ext[1] / n_strips
        width = ext[1] / n_strips
        in_strip = (pv >= v0 - _ROUND_OFF) & (pv <= v0 + width + _ROUND_OFF)
        # The strip's length from its core only: a neighbour's edge points lie on the border.
        core = in_strip & (pv > v0 + STRIP_CORE[0] * width) & (pv < v0 + STRIP_CORE[1] * width)
        if core.sum() < MIN_CORE_POINTS:
            continue
        su = pu[core]
        v_mid = pv[in_strip].min() / 2 + pv[in_strip].max() / 2 if n_strips > 1 \
            else (lo[1] + hi[1]) / 2
        yield _Strip(n, u_dir, surface.centroid + v_dir * v_mid, su, su.min(), su.max(),
                     int(in_strip.sum()))


def _strip_boxes(strip: _Strip, hm: HeightMap, occupied: Sequence[FittedBox],
                 prior: Sequence[FittedBox]) -> list[FittedBox]:
    """The boxes whose tops make up `strip`: whole blocks (with any cubes in line), a block
    partly hidden, the visible end of a prior block, or else a row of cubes."""
    if strip.length > LONG - WHOLE_BLOCK_SLACK:  # the whole block is seen
        return _whole_blocks(strip, prior)
    if strip.length > PARTIAL_BLOCK:
        block = _partly_hidden_block(strip, hm, occupied)
        if block is not None:
            return [block]
    if strip.length <= PARTIAL_BLOCK and prior:
        # A short piece may be the visible end of a block the prior knows, now mostly
        # under something put on it.
        block = _prior_block_through(strip.origin + strip.u_dir * (strip.u_lo + strip.u_hi) / 2,
                                     strip.n, prior, hm, occupied, strip.npts)
        if block is not None:
            return [block]
    return _cubes(strip)


def _whole_blocks(strip: _Strip, prior: Sequence[FittedBox]) -> list[FittedBox]:
    """A strip whose blocks are seen whole: one block, or blocks end to end with cubes."""
    n_long = int((strip.length + WHOLE_BLOCK_SLACK) // LONG)
    extra = max(0, int(round((strip.length - n_long * LONG) / SIDE)))
    if extra == 0 and n_long == 1:
        return [strip.box((strip.u_lo + strip.u_hi) / 2, "long", False, strip.npts)]
    # Blocks end to end, with cubes touching an end: the blocks go at the end whose edge
    # points are densest (a block's end face is seen), cubes along the rest. Which order
    # is right is ambiguous from above: uncertain. With a prior (the scene before the
    # action) the order nearer to it wins.
    layouts = [_end_to_end(strip, n_long, extra, at_lo) for at_lo in (True, False)]
    if prior:
        return min(layouts, key=lambda lay: _distance_to(lay, prior))
    su = strip.su
    dense_lo = np.sum(su < strip.u_lo + EDGE_BAND) >= np.sum(su > strip.u_hi - EDGE_BAND)
    return layouts[0] if dense_lo else layouts[1]


def _end_to_end(strip: _Strip, n_long: int, extra: int, at_lo: bool) -> list[FittedBox]:
    """`n_long` blocks then `extra` cubes, from the strip's low end (`at_lo`) or high end."""
    start, sign, layout = (strip.u_lo, 1.0, []) if at_lo else (strip.u_hi, -1.0, [])
    for size in [LONG] * n_long + [SIDE] * extra:
        kind = "long" if size == LONG else "cube"
        layout.append(strip.box(
            start + sign * size / 2, kind, True,
            strip.npts // n_long if kind == "long" else strip.npts // CUBE_SHARE))
        start += sign * size
    return layout


def _partly_hidden_block(strip: _Strip, hm: HeightMap, occupied: Sequence[FittedBox]
                         ) -> FittedBox | None:
    """A long block partly hidden under something, of which `strip` is the part seen; None
    if no placement is hidden enough (touching cubes, then). A 25 cm block slides over
    every placement that covers what is seen."""
    u_lo, u_hi, origin, u_dir = strip.u_lo, strip.u_hi, strip.origin, strip.u_dir
    centres = np.linspace(u_hi - LONG / 2, u_lo + LONG / 2, PLACEMENTS)
    fracs = _block_hidden_fractions(hm, origin + np.outer(centres, u_dir), u_dir, occupied)
    if fracs.max() <= HIDDEN_ENOUGH:
        return None
    good = centres[fracs >= fracs.max() - _ROUND_OFF]
    centre_u = (good.min() + good.max()) / 2
    # A visible end that borders the table is the block's real end.
    beyond = origin + np.outer([u_lo - END_PROBE, u_hi + END_PROBE], u_dir)
    lo_real, hi_real = _hidden_fractions(hm, beyond[:, None], occupied) == 0
    if lo_real and not hi_real:
        centre_u = u_lo + LONG / 2
    elif hi_real and not lo_real:
        centre_u = u_hi - LONG / 2
    return strip.box(centre_u, "long", fracs.max() < HIDDEN_SURE, strip.npts)


def _cubes(strip: _Strip) -> list[FittedBox]:
    """A row of touching cubes along `strip`, sharing its points; short ones are uncertain."""
    count = max(1, int(round(strip.length / SIDE)))
    return [strip.box(strip.u_lo + strip.length * (j + 0.5) / count, "cube",
                      strip.length < SHORT_CUBE, strip.npts // count) for j in range(count)]


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
    return box_from_top(best[1], n, best[2], "long", True, npts)


def _distance_to(layout: list[FittedBox], prior: Sequence[FittedBox]) -> float:
    """Sum over `layout` of the distance to the nearest prior box of the same type."""
    total = 0.0
    for b in layout:
        d = [np.linalg.norm(b.center - p.center) for p in prior if p.type == b.type]
        total += min(min(d, default=LAYOUT_DISTANCE_CAP), LAYOUT_DISTANCE_CAP)
    return total
