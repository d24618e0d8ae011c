"""Split a top surface that no rectangle explains into parts a rectangle does: a long block
seen whole is cut out at a time (two blocks touching at an angle, a block with a cube
turned against its side), so that top_surfaces reads each part on its own."""

from __future__ import annotations

import numpy as np
from scipy import ndimage, signal
from scipy.spatial import ConvexHull, QhullError

from drake_symplan.boxes import LONG, SIDE
from drake_symplan.perception.fitted_box import min_area_rectangle, plane_basis
from drake_symplan.perception.segmentation import CELL, MIN_REGION_CELLS, Surface

# A surface filling at least this share of its smallest enclosing rectangle is read as
# strips (top_surfaces); rows of boxes side by side and end to end fill it nearly whole,
# two blocks at right angles fill 40 %.
RECTANGLE_FILL = 0.8
# A block's footprint is cut out where this share of its cells lies on the surface.
BLOCK_FIT = 0.93
# The ring around a footprint whose cells count against it (cells from its edge) and how
# much: the block's own edge cells lie in the first cell outside the (inset) footprint.
RING = (1, 3)
RING_WEIGHT = 0.5
ANGLE_STEP = np.radians(2.0)  # a block's candidate headings, to this step; then refined
ANGLE_REFINE = np.radians(np.arange(-1.5, 1.51, 0.5))
SLIVER = SIDE / 2  # m: a piece left this narrow is the block's edge, not a box
MAX_PARTS = 8  # a scene holds at most eight boxes
CLOSING_PAD = 2  # cells: empty border a 3x3 closing needs to see no edge
BLOCK_PAD = int(np.ceil(LONG / CELL))  # cells: room for a block's footprint around a surface


def split_surface(surface: Surface) -> list[Surface]:
    """`surface` as parts each read on its own: itself where a rectangle explains it or
    no whole block fits in it; else a whole block's part and the parts of what is left."""
    parts, todo = [], [surface]
    while todo and len(parts) + len(todo) < MAX_PARTS:
        s = todo.pop()
        grid = _Grid(s)
        # Most surfaces are a cube's top: too small for a block, read as they are.
        block = grid.best_block() if grid.holds_block() and grid.fill() < RECTANGLE_FILL \
            else None
        if block is None:
            parts.append(s)
            continue
        rest = []
        for piece in grid.pieces(~block):
            if grid.sliver(piece):
                block |= piece  # a strip along the block's edge its footprint just missed
            else:
                rest.append(piece)
        parts.append(_part(s, block))
        todo.extend(_part(s, piece) for piece in rest)
    return parts + todo


def _part(s: Surface, point_mask: np.ndarray) -> Surface:
    pts = s.points[point_mask]
    return Surface(s.cells, pts, s.normal, pts.mean(axis=0))


class _Grid:
    """The surface's points on a grid in its own plane."""

    def __init__(self, s: Surface):
        b1, b2 = plane_basis(s.normal)
        rel = s.points - s.centroid
        self.uv = np.column_stack([rel @ b1, rel @ b2])
        # Cells counted from BLOCK_PAD cells before the points, as on a block search's
        # padded grid (the same points fall in the same cells), kept with CLOSING_PAD
        # empty ones around them.
        lo = self.uv.min(axis=0) - BLOCK_PAD * CELL
        self.idx = np.floor((self.uv - lo) / CELL).astype(int) - (BLOCK_PAD - CLOSING_PAD)
        occupied = np.zeros(self.idx.max(axis=0) + CLOSING_PAD + 1, bool)
        occupied[self.idx[:, 0], self.idx[:, 1]] = True
        # Cells the cameras left between seen ones (a pixel's footprint is near a cell).
        self.mask = ndimage.binary_closing(occupied, iterations=1) | occupied

    def holds_block(self) -> bool:
        """Is the surface large enough for a whole block's footprint to fit?"""
        return self.mask.sum() * CELL ** 2 >= BLOCK_FIT * LONG * SIDE

    def fill(self) -> float:
        _, lo, hi, _ = min_area_rectangle(self.uv)
        area = float(np.prod(np.maximum(hi - lo, CELL)))
        return self.mask.sum() * CELL ** 2 / area

    def best_block(self) -> np.ndarray | None:
        """Which points lie under the best-fitting whole block's footprint, or None where
        none has BLOCK_FIT of its cells on the surface."""
        # Room around the surface for a footprint centred anywhere on it.
        pad = BLOCK_PAD - CLOSING_PAD
        cells = np.pad(self.mask, pad).astype(float)
        best = max(_placements(cells, self._headings()), key=lambda t: t[0])
        best = max(_placements(cells, best[2] + ANGLE_REFINE), key=lambda t: t[0])
        _, covered, angle, at = best
        if covered < BLOCK_FIT:
            return None
        kernel = _footprint(angle)
        placed = np.zeros(cells.shape, bool)
        kx, ky = kernel.shape
        x0, y0 = at[0] - kx // 2, at[1] - ky // 2
        placed[x0:x0 + kx, y0:y0 + ky] = kernel
        # Edge points of the block fall in the cells just around its footprint.
        placed = ndimage.binary_dilation(placed, iterations=1)[pad:-pad, pad:-pad] & self.mask
        return placed[self.idx[:, 0], self.idx[:, 1]]

    def _headings(self) -> np.ndarray:
        """Candidate headings of a block: the directions of the surface's outline (a block
        seen whole has a long side on it) and their normals, to ANGLE_STEP."""
        try:
            hull = self.uv[ConvexHull(self.uv).vertices]
        except QhullError:
            return np.arange(0.0, np.pi, ANGLE_STEP)
        edges = np.roll(hull, -1, axis=0) - hull
        angles = np.arctan2(edges[:, 1], edges[:, 0])
        angles = np.concatenate([angles, angles + np.pi / 2]) % np.pi
        return np.unique(np.round(angles / ANGLE_STEP)) * ANGLE_STEP

    def sliver(self, point_mask: np.ndarray) -> bool:
        """Are the points in `point_mask` too narrow for any box's top?"""
        _, lo, hi, _ = min_area_rectangle(self.uv[point_mask])
        return bool(np.min(hi - lo) < SLIVER)

    def pieces(self, point_mask: np.ndarray) -> list[np.ndarray]:
        """The connected pieces of the points in `point_mask` of MIN_REGION_CELLS cells or
        more (as segmentation keeps regions), as point masks."""
        grid = np.zeros_like(self.mask)
        grid[self.idx[point_mask, 0], self.idx[point_mask, 1]] = True
        labels, n = ndimage.label(grid)
        sizes = ndimage.sum(grid, labels, np.arange(1, n + 1))
        point_label = labels[self.idx[:, 0], self.idx[:, 1]]
        return [point_mask & (point_label == lab) for lab in range(1, n + 1)
                if sizes[lab - 1] >= MIN_REGION_CELLS]


def _placements(cells: np.ndarray, angles):
    """(score, share of the footprint on the surface, angle, grid cell) of the best
    placement at each angle on the grid `cells`. The score counts the surface's cells under
    the footprint less half those in a ring just outside it: a block turned off its true
    heading covers as much but leaves its own corners in the ring."""
    for a in angles:
        inside = _footprint(a)
        ring = (ndimage.binary_dilation(inside, iterations=RING[1])
                & ~ndimage.binary_dilation(inside, iterations=RING[0]))
        on = signal.fftconvolve(cells, inside[::-1, ::-1].astype(float), mode="same")
        near = signal.fftconvolve(cells, ring[::-1, ::-1].astype(float), mode="same")
        score = on - RING_WEIGHT * near
        at = np.unravel_index(int(np.argmax(score)), score.shape)
        yield score[at], on[at] / inside.sum(), float(a), at


def _footprint(angle: float) -> np.ndarray:
    """A long block's top face, its long axis at `angle`, rasterised on CELL (odd sides,
    centred)."""
    half = int(np.ceil(LONG / 2 / CELL)) + RING[1] + 1
    c = np.arange(-half, half + 1) * CELL
    u, v = np.meshgrid(c, c, indexing="ij")
    along = u * np.cos(angle) + v * np.sin(angle)
    across = -u * np.sin(angle) + v * np.cos(angle)
    return (np.abs(along) <= LONG / 2 - CELL / 2) & (np.abs(across) <= SIDE / 2 - CELL / 2)
