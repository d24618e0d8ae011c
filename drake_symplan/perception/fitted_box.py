"""The fitted box (`FittedBox`) and the planar geometry that places one: the minimum-area
rectangle of a point set, and a box from the centre and normal of its top face."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from drake_symplan.boxes import HALF_EXTENTS

# Minimum-area rectangle: a 1 deg search over a quarter turn (a rectangle repeats every
# 90 deg), then 0.1 deg steps within 1 deg of the best.
_ANGLES = np.radians(np.arange(0.0, 90.0, 1.0))
_REFINE_ANGLES = np.radians(np.arange(-1.0, 1.01, 0.1))
HULL_MIN_POINTS = 8  # up to this many points, taking the convex hull first saves nothing


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


def plane_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def box_from_top(top_center: np.ndarray, n: np.ndarray, long_dir: np.ndarray, kind: str,
                 uncertain: bool, npts: int) -> FittedBox:
    y = long_dir - (long_dir @ n) * n
    y /= np.linalg.norm(y)
    x = np.cross(y, n)
    R = np.column_stack([x, y, n])
    return FittedBox(kind, top_center - n * HALF_EXTENTS[kind][2], R, uncertain, npts)
