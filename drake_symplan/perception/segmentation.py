"""Point-cloud processing: crop to the workspace, drop the table and the robot, find surfaces.

Surfaces come from a fused top-down height map (max z per cell): cells whose neighbourhood
is locally flat are grouped into connected regions, and each region gets a plane fit. A
region is (part of) the visible top face of one box or of several touching boxes.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy import ndimage

CELL = 0.004  # m, height-map resolution
CROP_X = (0.38, 1.12)
CROP_Y = (-0.56, 0.56)
CROP_Z = (0.004, 0.50)  # table top is z = 0; everything above 4 mm is an object
FLAT_RANGE = 0.009  # m, max height spread in a 3x3 neighbourhood of a surface cell
MIN_REGION_CELLS = 12
MIN_PLANE_WIDTH = CELL / 4  # m, rms spread of a surface's points across its long axis


@dc.dataclass
class Surface:
    """A connected, locally planar region of the height map."""

    cells: np.ndarray  # [K, 2] int grid indices (ix, iy)
    points: np.ndarray  # [M, 3] the points that fell in those cells
    normal: np.ndarray  # (3,) unit, z > 0
    centroid: np.ndarray  # (3,)


@dc.dataclass
class HeightMap:
    height: np.ndarray  # [NX, NY] max z, NaN where no point
    origin: np.ndarray  # world xy of cell (0, 0)'s corner
    cell_of_point: np.ndarray  # [M] flat cell index of each cropped point
    points: np.ndarray  # [M, 3] cropped points

    def centres(self, cells: np.ndarray) -> np.ndarray:
        return self.origin + (cells + 0.5) * CELL

    def cell_index(self, xy: np.ndarray) -> np.ndarray:
        return np.floor((xy - self.origin) / CELL).astype(int)

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """Which world xy points [N, 2] fall on the map (inside the crop)."""
        return self._on_map(self.cell_index(xy))

    def contradicts(self, pts3: np.ndarray, tol: float) -> np.ndarray:
        """Which world points [N, 3] the map rules out: on the map, with nothing seen there
        (the table is not in the map) or only a surface more than `tol` below them."""
        ok, seen = self._lookup(pts3[:, :2])
        return ok & (np.isnan(seen) | (seen < pts3[:, 2] - tol))

    def lookup(self, xy: np.ndarray) -> np.ndarray:
        """Height at world xy [N, 2]; NaN outside the map or where nothing was seen."""
        return self._lookup(xy)[1]

    def _on_map(self, idx: np.ndarray) -> np.ndarray:
        nx, ny = self.height.shape
        return (idx[:, 0] >= 0) & (idx[:, 0] < nx) & (idx[:, 1] >= 0) & (idx[:, 1] < ny)

    def _lookup(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        idx = self.cell_index(xy)
        ok = self._on_map(idx)
        out = np.full(len(xy), np.nan)
        out[ok] = self.height[idx[ok, 0], idx[ok, 1]]
        return ok, out


def crop(points: np.ndarray) -> np.ndarray:
    p = points
    keep = ((p[:, 0] > CROP_X[0]) & (p[:, 0] < CROP_X[1]) & (p[:, 1] > CROP_Y[0])
            & (p[:, 1] < CROP_Y[1]) & (p[:, 2] > CROP_Z[0]) & (p[:, 2] < CROP_Z[1]))
    return p[keep]


def remove_inside(points: np.ndarray, shapes: list[tuple[str, np.ndarray, np.ndarray]],
                  margin: float = 0.015) -> np.ndarray:
    """Drops points inside any (kind, X_WG 4x4, size) shape inflated by `margin`.

    kind "box": size = full extents (3,); kind "cylinder": size = (radius, length), axis z.
    """
    keep = np.ones(len(points), bool)
    for kind, X, size in shapes:
        local = (points - X[:3, 3]) @ X[:3, :3]
        if kind == "box":
            inside = np.all(np.abs(local) <= np.asarray(size) / 2 + margin, axis=1)
        else:
            r, length = size
            inside = ((local[:, 0] ** 2 + local[:, 1] ** 2 <= (r + margin) ** 2)
                      & (np.abs(local[:, 2]) <= length / 2 + margin))
        keep &= ~inside
    return points[keep]


def height_map(points: np.ndarray) -> HeightMap:
    origin = np.array([CROP_X[0], CROP_Y[0]])
    nx = int(np.ceil((CROP_X[1] - CROP_X[0]) / CELL))
    ny = int(np.ceil((CROP_Y[1] - CROP_Y[0]) / CELL))
    idx = np.clip(np.floor((points[:, :2] - origin) / CELL).astype(int), 0, [nx - 1, ny - 1])
    flat = idx[:, 0] * ny + idx[:, 1]
    h = np.full(nx * ny, -np.inf)
    np.maximum.at(h, flat, points[:, 2])
    h[np.isinf(h)] = np.nan
    return HeightMap(h.reshape(nx, ny), origin, flat, points)


def find_surfaces(hm: HeightMap) -> list[Surface]:
    """Connected locally-flat regions of the height map, each with a plane fit."""
    h = hm.height
    filled = np.where(np.isnan(h), -1.0, h)
    valid = ~np.isnan(h)
    hi = ndimage.maximum_filter(filled, size=3, mode="nearest")
    lo = ndimage.minimum_filter(np.where(valid, h, 10.0), size=3, mode="nearest")
    flat = valid & (hi - lo < FLAT_RANGE)
    labels, n = ndimage.label(flat)
    if n == 0:
        return []
    ny = h.shape[1]
    # Points grouped by their region label, in one pass.
    point_label = labels.ravel()[hm.cell_of_point]
    order = np.argsort(point_label, kind="stable")
    sorted_labels = point_label[order]
    bounds = np.searchsorted(sorted_labels, np.arange(n + 2))
    surfaces = []
    nx = h.shape[0]
    for lab in range(1, n + 1):
        cells = np.argwhere(labels == lab)
        if len(cells) < MIN_REGION_CELLS:
            continue
        idx = order[bounds[lab]:bounds[lab + 1]]
        # Only each cell's top points: side-face points share the edge cells.
        top = hm.points[idx, 2] >= h.ravel()[hm.cell_of_point[idx]] - 0.004
        pts = hm.points[idx[top]]
        if len(pts) < 10:
            continue
        fit = _fit_plane(pts)
        if fit is None:
            continue
        normal, centroid = fit
        # Grow back the edge cells that the flatness test dropped: points within two
        # cells of the region that lie on its plane.
        lo_c = np.maximum(cells.min(axis=0) - 2, 0)
        hi_c = np.minimum(cells.max(axis=0) + 3, [nx, ny])
        sub = labels[lo_c[0]:hi_c[0], lo_c[1]:hi_c[1]] == lab
        grown = ndimage.binary_dilation(sub, iterations=2)
        near = np.zeros(h.shape, bool)
        near[lo_c[0]:hi_c[0], lo_c[1]:hi_c[1]] = grown
        cand = hm.points[near.ravel()[hm.cell_of_point]]
        on_plane = np.abs((cand - centroid) @ normal) < 0.003
        pts = cand[on_plane]
        surfaces.append(Surface(cells, pts, normal, centroid))
    return surfaces


def _fit_plane(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(unit normal with z > 0, centroid), or None for points on a line (no plane)."""
    centroid = pts.mean(axis=0)
    _, sv, vt = np.linalg.svd(pts - centroid, full_matrices=False)
    # A single row of pixels along a box's edge fills a flat region of cells with
    # collinear points; its "normal" is any direction across the line.
    if sv[1] / np.sqrt(len(pts)) < MIN_PLANE_WIDTH:
        return None
    n = vt[2]
    if n[2] < 0:
        n = -n
    # One refit without the worst residuals (edge points from side faces).
    r = np.abs((pts - centroid) @ n)
    keep = r <= max(np.percentile(r, 90), 1e-4)
    if keep.sum() >= 10:
        centroid = pts[keep].mean(axis=0)
        _, _, vt = np.linalg.svd(pts[keep] - centroid, full_matrices=False)
        n = vt[2] if vt[2][2] > 0 else -vt[2]
    return n / np.linalg.norm(n), centroid
