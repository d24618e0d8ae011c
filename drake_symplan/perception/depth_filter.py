"""Noisy depth frames -> points perception can trust: per camera, a temporal median, an
edge-preserving local plane fit (which also drops flying pixels), and the table's plane.

The sensor is world/depth_sensor.py's; these are the filters a RealSense user runs (the
SDK's temporal and edge-preserving spatial filters) plus a check of each camera's
calibration against the table, whose top is the plane z = 0.

Most of an image is the table, which perception crops away: the table's plane is read from
a grid of pixels (every 4th of every 4th row), and the filter runs only on the 16-px tiles
where that grid sees something stand on the table in the workspace, with their neighbours'
pixels; a noisy perception costs about what a perfect sensor's does (docs/perception.md).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy import ndimage

from drake_symplan.perception.segmentation import CROP_X, CROP_Y, CROP_Z
from drake_symplan.world.cameras import DepthCamera

MEDIAN_EFFICIENCY = 1.25  # the median of n normal samples has about 1.25 / sqrt(n) their std
WORKSPACE_MARGIN = 0.05  # m: what the grid sees this near the workspace is filtered


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
    grid: int = 4  # px: the table's plane, and where things stand on it, from every 4th pixel
    reach: int = 1  # grid steps around a grid pixel that sees a thing, filtered with it
    tile: int = 16  # px: the filter runs on the squares of this side the things are in

    def __post_init__(self):
        if self.frames < 1 or self.radius < 0:
            raise ValueError("DepthFilter: frames must be >= 1 and radius >= 0")
        if self.grid < 1 or self.reach < 0 or self.tile < 1 or self.tile % self.grid:
            raise ValueError("DepthFilter: grid must be >= 1, reach >= 0 and tile a multiple "
                             "of grid")


@dc.dataclass
class CameraReading:
    """What one camera's sensor gave and what the filter made of it (for reports)."""

    camera: str
    pixels: int
    returns: int  # pixels with a return (in the first frame)
    holes: int  # pixels without: out of range or lost
    kept: int  # points after the filter, above the table (in the workspace, or near)
    table_tilt_deg: float  # the table's plane as this camera sees it, before correction
    table_height_mm: float

    def to_json(self) -> dict:
        return {k: round(v, 3) if isinstance(v, float) else v
                for k, v in dc.asdict(self).items()}


def filtered_clouds(cameras: list[DepthCamera], frames: list[np.ndarray], noise, cfg: DepthFilter,
                    z_min: float | None = None) -> tuple[list[np.ndarray], list[CameraReading]]:
    """World-frame points of each camera from its frames [F, H, W], each camera's cloud
    put back on the table's plane; and what each camera gave.

    With `z_min`, only the points above the table's crop (z_min plus `table_sigmas` of the
    point's own noise, after levelling) in the workspace: the table's plane is read from a
    grid of pixels (every `grid`-th row and column), and the filter runs only on the tiles
    of the image where that grid sees something stand on the table (most of an image is
    the table). Without it, every point."""
    clouds, readings = [], []
    for cam, stack in zip(cameras, frames, strict=True):
        R, p, tilt, height, tiles = _table_and_tiles(cam, stack, noise, cfg, z_min)
        origin = cam.X_WB.translation()
        idx, depth, spread = _filtered_tiles(cam, stack, noise, cfg, tiles)
        if z_min is not None:
            # The table's own points reach a few sigma above it: its crop grows with them.
            # Levelled, a pixel's height is linear in its depth: z = R[2] . (o + d ray) + p.
            slope = _height_slopes(cam, R, idx)
            keep = R[2] @ origin + p[2] + depth * slope > z_min + cfg.table_sigmas * spread * (
                np.abs(slope))
            idx, depth = idx[keep], depth[keep]
        xyz = np.take(cam.rays, idx, axis=0)  # the points of pixels idx, as believed
        xyz *= depth[:, None]
        xyz += origin
        clouds.append(np.einsum("ij,kj->ik", xyz, R) + p)  # (BLAS is slow for [N, 3])
        returns = int(np.count_nonzero(np.isfinite(stack[0])))
        pixels = stack[0].size
        readings.append(CameraReading(cam.config.name, pixels, returns, pixels - returns,
                                      len(xyz), tilt, height))
    return clouds, readings


def _height_slopes(cam: DepthCamera, R: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """R[2] . ray of the pixels `idx` (flat): how their heights, levelled by R, grow with
    depth; the ray (u - cx) / fx, (v - cy) / fy, 1 turned to the world, separably."""
    info = cam.info
    q = cam.X_WB.rotation().matrix().T @ R[2]
    v, u = np.divmod(idx, info.width())
    return (q[0] / info.focal_x()) * (u - info.center_x()) + (
        (q[1] / info.focal_y()) * (v - info.center_y()) + q[2])


def _table_and_tiles(cam: DepthCamera, stack: np.ndarray, noise, cfg: DepthFilter,
                     z_min: float | None) -> tuple:
    """(R, p, tilt, height): `table_levelling` of the grid's pixels' medians; and the
    image's tiles (a boolean [rows, columns] of `tile` px squares) where the grid sees
    something above the table in the workspace (all of them without `z_min`)."""
    g, h, w = cfg.grid, *stack.shape[1:]
    med = temporal_median(stack[:, g // 2::g, g // 2::g], cfg.min_returns)
    rays = _grid_rays(cam, g)  # [3, rows, columns]
    origin = cam.X_WB.translation()
    xyz = [o + med * ray for o, ray in zip(origin, rays, strict=True)]  # NaN: no median
    R, p, tilt, height = table_levelling(xyz, origin, cfg, min_points=max(1000 // (g * g), 10))
    if z_min is None:
        blocks = np.ones(med.shape, bool)
    else:
        x, y, z = (R[k, 0] * xyz[0] + R[k, 1] * xyz[1] + R[k, 2] * xyz[2] + p[k]
                   for k in range(3))
        # The median's noise in height, for the levelled ray's slope at each point.
        slope = np.abs(R[2, 0] * rays[0] + R[2, 1] * rays[1] + R[2, 2] * rays[2])
        sigma_z = noise.axial_sigma(med, cam.info.focal_x()) * slope * (
            MEDIAN_EFFICIENCY / np.sqrt(len(stack)))
        m = WORKSPACE_MARGIN
        blocks = ((z > z_min + 3 * sigma_z) & (z < CROP_Z[1] + m) & (x > CROP_X[0] - m)
                  & (x < CROP_X[1] + m) & (y > CROP_Y[0] - m) & (y < CROP_Y[1] + m))
        # A grid pixel stands for its block; the neighbours' blocks hold the edges and the
        # low rows of what stands there, which the grid may have missed.
        blocks = _window_extreme(blocks, 2 * cfg.reach + 1, np.maximum, False)
    k = cfg.tile // g
    rows, cols = -(-h // cfg.tile), -(-w // cfg.tile)
    padded = np.zeros((rows * k, cols * k), bool)
    padded[:blocks.shape[0], :blocks.shape[1]] = blocks
    return R, p, tilt, height, padded.reshape(rows, k, cols, k).any(axis=(1, 3))


def _grid_rays(cam: DepthCamera, g: int) -> np.ndarray:
    """The rays (world/cameras.pixel_rays) of every g-th pixel of every g-th row, from
    g // 2, as [3, rows, columns]: the camera's rotation of (u - cx) / fx, (v - cy) / fy, 1."""
    info, R = cam.info, cam.X_WB.rotation().matrix()
    u = (np.arange(g // 2, info.width(), g) - info.center_x()) / info.focal_x()
    v = (np.arange(g // 2, info.height(), g) - info.center_y()) / info.focal_y()
    return R[:, 0, None, None] * u + R[:, 1, None, None] * v[:, None] + R[:, 2, None, None]


def _filtered_tiles(cam: DepthCamera, stack: np.ndarray, noise, cfg: DepthFilter,
                    tiles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pixels, as flat indices; their filtered depths; their standard deviations) of the
    pixels in `tiles` that the filter keeps: `temporal_median` and `local_plane_depth` of
    each tile with a margin of `radius` px (all tiles in one tall image, so that no
    window of a tile's own pixels reaches another)."""
    f, h, w = stack.shape
    t, r = cfg.tile, cfg.radius
    ty, tx = np.divmod(np.flatnonzero(tiles), tiles.shape[1])
    k = np.arange(-r, t + r)
    rows, cols = ty[:, None] * t + k, tx[:, None] * t + k  # [tiles, t + 2r]
    inside = ((rows >= 0) & (rows < h))[:, :, None] & ((cols >= 0) & (cols < w))[:, None, :]
    rows, cols = np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)
    flat = rows[:, :, None] * w + cols[:, None, :]
    side = t + 2 * r
    windows = np.take(stack.reshape(f, -1), flat.reshape(-1, side), axis=1)
    depth = temporal_median(windows, cfg.min_returns)  # [tiles * side, side]
    depth[~inside.reshape(depth.shape)] = np.nan
    sigma = np.nan_to_num(noise.axial_sigma(depth, cam.info.focal_x()) * np.float32(
        MEDIAN_EFFICIENCY / np.sqrt(f)))
    core = np.zeros((len(ty), side, side), bool)
    core[:, r:r + t, r:r + t] = True
    core = core.reshape(depth.shape)
    smooth, spread = local_plane_depth(depth, sigma, cfg, core)  # (a margin's: not needed)
    keep = np.flatnonzero(core & np.isfinite(smooth) & inside.reshape(depth.shape))
    return flat.ravel()[keep], smooth.ravel()[keep], spread.ravel()[keep]


def temporal_median(stack: np.ndarray, min_returns: float) -> np.ndarray:
    """Per-pixel median of the frames' returns [F, H, W] -> [H, W] (float32); NaN where
    fewer than `min_returns` of the frames returned."""
    f = len(stack)
    n = np.isfinite(stack).sum(axis=0, dtype=np.uint8 if f < 256 else np.int64)
    if f == 5:
        # Five frames (the filter's): the median by nine minima and maxima where every
        # frame returned (NaN where none did); sorted only where some did.
        a, b, c, d, e = stack
        lo = np.maximum(np.minimum(a, b), np.minimum(c, d))
        hi = np.minimum(np.maximum(a, b), np.maximum(c, d))
        med = np.maximum(np.minimum(e, lo), np.minimum(np.maximum(e, lo), hi))
        some = np.flatnonzero((n > 0) & (n < f))
        if len(some):
            med.flat[some] = _sorted_median(stack.reshape(f, -1)[:, some], n.flat[some])
    else:
        med = _sorted_median(stack, n)
    med[n < max(1, np.ceil(min_returns * f))] = np.nan
    return med


def _sorted_median(stack: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The median of each pixel's `n` returns among the frames [F, ...] (float32)."""
    f = len(stack)
    # The frames sorted pixel by pixel (no return: inf, last) by an odd-even transposition
    # network: f rounds of elementwise min and max, much faster than np.sort across frames.
    s = [np.fmin(frame, np.float32(np.inf)) for frame in stack]
    for i in range(f):
        for j in range(i % 2, f - 1, 2):
            lo = np.minimum(s[j], s[j + 1])
            np.maximum(s[j], s[j + 1], out=s[j + 1])
            s[j] = lo
    med = _pick(s, (n.astype(np.int64) - 1) // 2)
    med += _pick(s, n // 2)
    med *= np.float32(0.5)
    return med


def _pick(planes: list[np.ndarray], k: np.ndarray) -> np.ndarray:
    """planes[k] pixel by pixel (planes[0] where k is out of range)."""
    out = planes[0].astype(np.float32)
    for j in range(1, len(planes)):
        np.copyto(out, planes[j], where=k == j)
    return out


def local_plane_depth(depth: np.ndarray, sigma: np.ndarray, cfg: DepthFilter,
                      where: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's depth from a plane fitted to it and its neighbours on the same surface
    (depth within `same_surface` + 3 sigma): an edge-preserving smoothing that stays
    unbiased on slanted surfaces and at edges. Pixels with fewer than `min_support` such
    neighbours, or farther than `off_plane` + 3 sigma from the plane (flying pixels,
    specks), become NaN.

    A plane in the camera frame is linear in inverse depth over the image, so the fit is
    least squares of 1/depth on the pixel offsets (du, dv); where the whole window is on
    one surface that is the window's mean (the offsets are symmetric), elsewhere a small
    fit per pixel. Returns the depths and their standard deviations (sigma over the root of
    the pixels fitted), float32; with `where` (boolean, the image's shape), only those
    pixels' (the others' are NaN or a window's mean)."""
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
    idx = np.flatnonzero(valid & ~whole if where is None else valid & ~whole & where)
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


def table_levelling(xyz, origin: np.ndarray, cfg: DepthFilter, min_points: int = 1000
                    ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(R, p): the turn and lift, xyz -> xyz R^T + p, that put the table's points of the
    cloud (x, y, z: arrays of one shape; NaN: none) of the camera at `origin` on z = 0,
    correcting the camera's calibration in tilt and height; with the plane's tilt (deg)
    and its height at the workspace's centre (mm) before. The identity when fewer than
    `min_points` of the table are seen."""
    centre = np.array([np.mean(CROP_X), np.mean(CROP_Y), 0.0])
    x, y, z = (np.ravel(v) for v in xyz)
    on_table = np.flatnonzero((np.abs(z) < cfg.table_band) & (x > CROP_X[0]) & (x < CROP_X[1])
                              & (y > CROP_Y[0]) & (y < CROP_Y[1]))
    if len(on_table) < min_points:
        return np.eye(3), np.zeros(3), float("nan"), float("nan")
    on_table = on_table[::-(-len(on_table) // 4000)]  # plenty for three parameters
    dx, dy, tz = x[on_table] - centre[0], y[on_table] - centre[1], z[on_table]
    keep = np.ones(len(tz), bool)
    for _ in range(cfg.table_iterations):
        # z = a x + b y + c, the boxes' low side points trimmed by their residuals (three
        # parameters: the normal equations, well conditioned about the centre).
        u, v, w = dx[keep], dy[keep], tz[keep]
        su, sv = u.sum(), v.sum()
        a, b, c = np.linalg.solve([[u @ u, u @ v, su], [u @ v, v @ v, sv], [su, sv, len(w)]],
                                  [u @ w, v @ w, w.sum()])
        res = np.abs(tz - (a * dx + b * dy + c))
        kept = res[keep]
        median = np.partition(kept, len(kept) // 2)[len(kept) // 2]  # (np.median: slower)
        keep = res <= max(3 * 1.4826 * median, 1e-4)
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
