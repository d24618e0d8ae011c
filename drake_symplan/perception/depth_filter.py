"""Noisy depth frames -> points perception can trust: per camera, a temporal median, an
edge-preserving local plane fit (which also drops flying pixels), and the table's plane.

The sensor is world/depth_sensor.py's; these are the filters a RealSense user runs (the
SDK's temporal and edge-preserving spatial filters) plus a check of each camera's
calibration against the table, whose top is the plane z = 0.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy import ndimage

from drake_symplan.perception.segmentation import CROP_X, CROP_Y
from drake_symplan.world.cameras import DepthCamera, back_project

MEDIAN_EFFICIENCY = 1.25  # the median of n normal samples has about 1.25 / sqrt(n) their std


@dc.dataclass
class DepthFilter:
    """How perception cleans the sensor's depth (used only when the station's sensor has
    noise; a perfect sensor's points go straight to segmentation)."""

    frames: int = 5  # frames averaged: the robot waits that long anyway (1/6 s at 30 fps)
    min_returns: float = 0.5  # a pixel needs a return in this fraction of the frames
    radius: int = 2  # px: the local plane fit's window is (2 radius + 1)^2
    same_surface: float = 0.012  # m (+ 3 sigma): a neighbour this near in depth is on it
    min_support: int = 8  # neighbours on a pixel's surface, itself included, to keep it
    off_plane: float = 0.002  # m (+ 3 sigma): a pixel farther from that plane is dropped
    table_band: float = 0.03  # m: points this near z = 0 in the workspace are the table's
    table_iterations: int = 3
    table_sigmas: float = 4.0  # a point this many sigma (in z) above the table's crop is kept

    def __post_init__(self):
        if self.frames < 1 or self.radius < 0:
            raise ValueError("DepthFilter: frames must be >= 1 and radius >= 0")


@dc.dataclass
class CameraReading:
    """What one camera's sensor gave and what the filter made of it (for reports)."""

    camera: str
    pixels: int
    returns: int  # pixels with a return (in the first frame)
    holes: int  # pixels without: out of range or lost
    kept: int  # points after the filter, above the table
    table_tilt_deg: float  # the table's plane as this camera sees it, before correction
    table_height_mm: float

    def to_json(self) -> dict:
        return {k: round(v, 3) if isinstance(v, float) else v
                for k, v in dc.asdict(self).items()}


def filtered_clouds(cameras: list[DepthCamera], frames: list[np.ndarray], noise, cfg: DepthFilter,
                    z_min: float | None = None) -> tuple[list[np.ndarray], list[CameraReading]]:
    """World-frame points of each camera from its frames [F, H, W], each camera's cloud
    put back on the table's plane; and what each camera gave."""
    clouds, readings = [], []
    for cam, stack in zip(cameras, frames, strict=True):
        rows, cols = _workspace_window(cam, stack[0], cfg.radius)
        depth = temporal_median(stack[:, rows, cols], cfg.min_returns)
        sigma = noise.axial_sigma(depth, cam.info.focal_x()) * np.float32(
            MEDIAN_EFFICIENCY / np.sqrt(len(stack)))
        smooth = np.full(stack.shape[1:], np.nan, np.float32)
        spread = np.zeros(stack.shape[1:], np.float32)
        smooth[rows, cols], spread[rows, cols] = local_plane_depth(
            depth, np.nan_to_num(sigma), cfg)
        idx = np.flatnonzero(np.isfinite(smooth))
        xyz = back_project(cam, smooth)  # the points of pixels idx
        R, p, tilt, height = table_levelling(xyz, cam.X_WB.translation(), cfg)
        if z_min is not None:
            # The table's own points reach a few sigma above it: its crop grows with them.
            # Most points are the table's: only those kept are levelled in full.
            sigma_z = spread.flat[idx] * np.abs(cam.rays[idx, 2])
            z = np.einsum("ij,j->i", xyz, R[2]) + p[2]
            xyz = xyz[z > z_min + cfg.table_sigmas * sigma_z]
        clouds.append(np.einsum("ij,kj->ik", xyz, R) + p)  # (BLAS is slow for [N, 3])
        returns = int(np.isfinite(stack[0]).sum())
        pixels = stack[0].size
        readings.append(CameraReading(cam.config.name, pixels, returns, pixels - returns,
                                      len(xyz), tilt, height))
    return clouds, readings


def _workspace_window(cam: DepthCamera, depth: np.ndarray, margin: int) -> tuple[slice, slice]:
    """The image rows and columns (with `margin`) that see the workspace: filtering the
    rest would be wasted."""
    d = np.nan_to_num(depth).reshape(-1).astype(np.float64)
    x, y, z = (o + d * cam.rays[:, k] for k, o in enumerate(cam.X_WB.translation()))
    inside = ((x > CROP_X[0] - 0.05) & (x < CROP_X[1] + 0.05) & (y > CROP_Y[0] - 0.05)
              & (y < CROP_Y[1] + 0.05) & (z > -0.05)).reshape(depth.shape)
    if not inside.any():
        return slice(0, 0), slice(0, 0)
    r, c = np.flatnonzero(inside.any(axis=1)), np.flatnonzero(inside.any(axis=0))
    h, w = depth.shape
    return (slice(max(r[0] - margin, 0), min(r[-1] + margin + 1, h)),
            slice(max(c[0] - margin, 0), min(c[-1] + margin + 1, w)))


def temporal_median(stack: np.ndarray, min_returns: float) -> np.ndarray:
    """Per-pixel median of the frames' returns [F, H, W] -> [H, W] (float32); NaN where
    fewer than `min_returns` of the frames returned."""
    f = len(stack)
    returns = np.isfinite(stack)
    # The frames sorted pixel by pixel (no return: inf, last) by an odd-even transposition
    # network: f rounds of elementwise min and max, much faster than np.sort across frames.
    s = [np.fmin(frame, np.float32(np.inf)) for frame in stack]
    for i in range(f):
        for j in range(i % 2, f - 1, 2):
            lo = np.minimum(s[j], s[j + 1])
            np.maximum(s[j], s[j + 1], out=s[j + 1])
            s[j] = lo
    n = returns.sum(axis=0)
    med = _pick(s, (n - 1) // 2)
    med += _pick(s, n // 2)
    med *= np.float32(0.5)
    med[n < max(1, np.ceil(min_returns * f))] = np.nan
    return med


def _pick(planes: list[np.ndarray], k: np.ndarray) -> np.ndarray:
    """planes[k] pixel by pixel (planes[0] where k is out of range)."""
    out = planes[0].astype(np.float32)
    for j in range(1, len(planes)):
        np.copyto(out, planes[j], where=k == j)
    return out


def local_plane_depth(depth: np.ndarray, sigma: np.ndarray, cfg: DepthFilter
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's depth from a plane fitted to it and its neighbours on the same surface
    (depth within `same_surface` + 3 sigma): an edge-preserving smoothing that stays
    unbiased on slanted surfaces and at edges. Pixels with fewer than `min_support` such
    neighbours, or farther than `off_plane` + 3 sigma from the plane (flying pixels,
    specks), become NaN.

    A plane in the camera frame is linear in inverse depth over the image, so the fit is
    least squares of 1/depth on the pixel offsets (du, dv); where the whole window is on
    one surface that is the window's mean (the offsets are symmetric), elsewhere a small
    fit per pixel. Returns the depths and their standard deviations (sigma over the root of
    the pixels fitted), float32."""
    r = cfg.radius
    size = 2 * r + 1
    depth = np.asarray(depth, np.float32)
    sigma = np.asarray(sigma, np.float32)
    valid = np.isfinite(depth)
    tol = np.float32(cfg.same_surface) + 3 * sigma
    # Beyond the image: a spread too large; holes: left out.
    hi = _window_extreme(np.fmax(depth, -np.inf), size, np.maximum, np.inf)
    lo = _window_extreme(np.fmin(depth, np.inf), size, np.minimum, -np.inf)
    whole = valid & (hi - lo <= tol)  # every neighbour there and on the same surface
    # A full window whose every pixel is on the centre's surface (on a steep one the
    # window's spread passes the tolerance) fits the plane the whole window does.
    full = _window_extreme(valid, size, np.minimum, False)
    whole |= full & (hi - depth <= tol) & (depth - lo <= tol)
    inv = np.zeros_like(depth)
    np.divide(1, depth, out=inv, where=valid)
    mean = ndimage.uniform_filter(inv, size, mode="constant")
    out = np.full(depth.shape, np.nan, np.float32)
    np.divide(1, mean, out=out, where=whole)
    idx = np.flatnonzero(valid & ~whole)
    if len(idx) == 0:
        return out, sigma / size
    fitted = np.full(depth.shape, size * size, np.float32)
    a, n = _plane_intercepts(depth, valid, tol, idx, r)
    keep = n >= cfg.min_support
    out.flat[idx[keep]] = 1.0 / a[keep]
    fitted.flat[idx] = np.maximum(n, 1)
    # A pixel off its neighbours' plane is a flying pixel (or a speck) between surfaces.
    off = ~(np.abs(out - depth) <= cfg.off_plane + 3 * sigma)
    out[off] = np.nan
    return out, sigma / np.sqrt(fitted)


def _plane_intercepts(depth: np.ndarray, valid: np.ndarray, tol: np.ndarray, idx: np.ndarray,
                      r: int) -> tuple[np.ndarray, np.ndarray]:
    """At the pixels `idx` (flat): the least-squares plane of 1/depth over the pixel offsets
    of the (2r + 1)^2 window's neighbours within `tol` of the pixel's depth, as (its
    intercept, the neighbours fitted); `local_plane_depth`'s fit where a window spans
    surfaces."""
    size = 2 * r + 1
    w = depth.shape[1]
    padded = np.pad(np.where(valid, depth, np.nan), r, constant_values=np.nan).ravel()
    k = np.arange(-r, r + 1)
    rows, cols = np.divmod(idx, w)
    at = (rows + r) * (w + 2 * r) + cols + r
    # The windows [dv, du, N], pixels last: the sums below add whole rows of arrays (no
    # BLAS: for these shapes its threads cost more than they save).
    nb = np.take(padded, (k[:, None] * (w + 2 * r) + k).reshape(-1, 1) + at)
    on = np.abs(nb - depth.flat[idx]) <= tol.flat[idx]
    y = np.reciprocal(nb).reshape(size, size, -1)
    np.copyto(y, 0, where=~on.reshape(y.shape))
    on = on.reshape(size, size, -1).astype(np.float32)  # counts: exact in float32
    kk = k[:, None].astype(np.float64)
    by_u, by_v = on.sum(0, dtype=np.float64), on.sum(1, dtype=np.float64)
    n, su, suu = by_u.sum(0), (kk * by_u).sum(0), (kk * kk * by_u).sum(0)
    sv, svv = (kk * by_v).sum(0), (kk * kk * by_v).sum(0)
    suv = (kk * sum(np.float32(k[i]) * on[i] for i in range(size))).sum(0)
    yu, yv = y.sum(0, dtype=np.float64), y.sum(1, dtype=np.float64)
    sy, suy, svy = yu.sum(0), (kk * yu).sum(0), (kk * yv).sum(0)
    # Cramer's rule for the intercept of [[n su sv] [su suu suv] [sv suv svv]] x = [sy suy svy].
    det = n * (suu * svv - suv ** 2) - su * (su * svv - suv * sv) + sv * (su * suv - suu * sv)
    num = sy * (suu * svv - suv ** 2) - su * (suy * svv - suv * svy) + sv * (suy * suv - suu * svy)
    # A window whose pixels lie on a line (a one-pixel-wide strip) has no plane: its mean.
    flat = np.abs(det) > 1e-9 * n ** 3
    a = np.where(flat, num / np.where(flat, det, 1.0), sy / np.maximum(n, 1))
    return a, n


def _window_extreme(a: np.ndarray, size: int, extreme, outside: float) -> np.ndarray:
    """Each pixel's largest (np.maximum) or smallest (np.minimum) value of its
    (size x size) window, `outside` beyond the image: ndimage's filter, several times
    faster for small windows."""
    r = size // 2
    h, w = a.shape
    padded = np.pad(a, r, constant_values=outside)
    rows = padded[:, :w].copy()
    for j in range(1, size):
        extreme(rows, padded[:, j:j + w], out=rows)
    out = rows[:h].copy()
    for j in range(1, size):
        extreme(out, rows[j:j + h], out=out)
    return out


def table_levelling(xyz: np.ndarray, origin: np.ndarray, cfg: DepthFilter
                    ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(R, p): the turn and lift, xyz -> xyz R^T + p, that put the table's points of the
    cloud of the camera at `origin` on z = 0, correcting the camera's calibration in tilt
    and height; with the plane's tilt (deg) and its height at the workspace's centre (mm)
    before. The identity when too little table is seen."""
    centre = np.array([np.mean(CROP_X), np.mean(CROP_Y), 0.0])
    x, y, z = xyz.T
    on_table = np.flatnonzero((np.abs(z) < cfg.table_band) & (x > CROP_X[0]) & (x < CROP_X[1])
                              & (y > CROP_Y[0]) & (y < CROP_Y[1]))
    if len(on_table) < 1000:
        return np.eye(3), np.zeros(3), float("nan"), float("nan")
    table = xyz[on_table[::max(1, len(on_table) // 20000)]]  # plenty for three parameters
    keep = np.ones(len(table), bool)
    for _ in range(cfg.table_iterations):
        # z = a x + b y + c, the boxes' low side points trimmed by their residuals.
        pts = table[keep]
        A = np.column_stack([pts[:, 0] - centre[0], pts[:, 1] - centre[1], np.ones(len(pts))])
        (a, b, c), *_ = np.linalg.lstsq(A, pts[:, 2], rcond=None)
        res = table[:, 2] - (a * (table[:, 0] - centre[0]) + b * (table[:, 1] - centre[1]) + c)
        keep = np.abs(res) <= max(3 * 1.4826 * np.median(np.abs(res[keep])), 1e-4)
    n = np.array([-a, -b, 1.0]) / np.linalg.norm([-a, -b, 1.0])
    # A tilt is the camera turned (its rotation moves far points most): turn the cloud
    # about the camera back onto the plane, then the height left is its offset.
    axis = np.cross(n, [0.0, 0.0, 1.0])
    s, cos = np.linalg.norm(axis), n[2]
    k = np.zeros((3, 3)) if s < 1e-12 else _skew(axis / s)
    R = np.eye(3) + s * k + (1 - cos) * k @ k
    on_plane = centre + [0.0, 0.0, c]
    p = origin - R @ origin
    p[2] -= (R @ on_plane + p)[2]
    return R, p, float(np.degrees(np.arccos(min(cos, 1.0)))), float(c * 1000)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
