"""A depth-sensor model of the RealSense D400 kind (active stereo): what a camera makes of a
rendered depth image. `CAMERA_NOISE` names the settings (`--camera-noise`); `sense` gives frames.
"""

from __future__ import annotations

import dataclasses as dc
import functools

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

# Where the effects start; the magnitudes are CameraNoise's terms.
EDGE_JUMP = 0.015  # m: a depth step to a 4-neighbour larger than this makes an edge pixel
STEEP_FROM = np.radians(65.0)  # incidence (normal to view ray) where returns start to fail
DARK_BELOW = 0.35  # surface reflectance (diffuse luminance) where returns start to fail


@dc.dataclass(frozen=True)
class CameraNoise:
    """The sensor's error terms; all zero: the rendered depth exactly.

    Axial noise follows Intel's depth RMS error formula for the D400 cameras,
    rms(z) = z^2 * subpixel / (focal_px * baseline), with the camera's own focal length;
    with the D435's baseline and subpixel 0.08 it is 0.7 mm at 0.5 m and 6 mm at 1.5 m.
    """

    subpixel: float = 0.0  # px: RMS disparity error (the D400 white paper's "subpixel")
    baseline: float = 0.050  # m: the stereo pair's baseline (D435: 50 mm); not a term
    lateral_px: float = 0.0  # px: std of where in the image a pixel's depth is measured
    edge_missing: float = 0.0  # probability that a pixel at a depth edge returns nothing
    flying: float = 0.0  # ... returns a depth between the edge's two sides (a flying pixel)
    steep_holes: float = 0.0  # hole probability at grazing incidence (ramps from STEEP_FROM)
    dark_holes: float = 0.0  # hole probability on a black surface (ramps from DARK_BELOW)
    depth_unit: float = 0.0  # m: quantisation step of the depth (D400: 1 mm); 0: none
    calib_translation: float = 0.0  # m: each camera's extrinsic error (random direction)
    calib_rotation_deg: float = 0.0  # deg: ... and its rotation (random axis)

    TERMS = ("subpixel", "lateral_px", "edge_missing", "flying", "steep_holes", "dark_holes",
             "depth_unit", "calib_translation", "calib_rotation_deg")

    @property
    def active(self) -> bool:
        return any(getattr(self, t) > 0 for t in self.TERMS)

    def scaled(self, k: float) -> CameraNoise:
        """Every term times k (the baseline is the camera's geometry, not a term)."""
        return dc.replace(self, **{t: getattr(self, t) * k for t in self.TERMS})

    def axial_sigma(self, depth, focal_px: float):
        """Standard deviation (m) of the depth error at `depth` (m)."""
        return np.square(depth) * self.subpixel / (focal_px * self.baseline)


REALSENSE = CameraNoise(subpixel=0.08, lateral_px=0.25, edge_missing=0.3, flying=0.15,
                        steep_holes=0.5, dark_holes=0.5, depth_unit=0.001,
                        calib_translation=0.002, calib_rotation_deg=0.2)
CAMERA_NOISE: dict[str, CameraNoise] = {
    "none": CameraNoise(),
    "realsense": REALSENSE,
    "heavy": REALSENSE.scaled(2.0),
}


def camera_noise(name: str) -> CameraNoise:
    if name not in CAMERA_NOISE:
        raise ValueError(f"unknown camera noise {name!r}; expected one of {tuple(CAMERA_NOISE)}")
    return CAMERA_NOISE[name]


def calibration_error(noise: CameraNoise, rng: np.random.Generator) -> RigidTransform:
    """X_CB: the pose perception believes the camera has (B) in the true camera frame C;
    `calib_translation` and `calib_rotation_deg` long, in random directions."""
    axis, direction = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
    R = _axis_angle(axis, np.radians(noise.calib_rotation_deg))
    return RigidTransform(R, noise.calib_translation * direction)


def _axis_angle(axis: np.ndarray, angle: float) -> RotationMatrix:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return RotationMatrix(np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k)


def sense(depth: np.ndarray, focal_px: float, center: tuple[float, float], noise: CameraNoise,
          rng: np.random.Generator, frames: int = 1,
          reflectance: np.ndarray | None = None) -> np.ndarray:
    """`frames` depth images [F, H, W] (float32, NaN: no return) the sensor gives of the
    scene rendered as `depth` [H, W] (0 or inf: out of range). The scene is at rest, so one
    rendering serves every frame, and what the surfaces cause (holes, the edges' flying
    pixels and missing returns) stays the same in each; the axial noise and the lateral
    jitter are drawn per frame. `reflectance` [H, W]: each pixel's surface reflectance
    (what `dark_holes` reads)."""
    d = np.asarray(depth, np.float32).reshape(depth.shape[:2])
    d = np.where(np.isfinite(d) & (d > 0), d, np.float32(np.nan))
    # Central differences across columns (du) and rows (dv); 0 on the image's border.
    du, dv = np.zeros_like(d), np.zeros_like(d)
    np.subtract(d[:, 2:], d[:, :-2], out=du[:, 1:-1])
    np.subtract(d[2:, :], d[:-2, :], out=dv[1:-1, :])
    edges, across = _edges(d)
    holes, lost = _hole_probability(d, du, dv, focal_px, center, noise, reflectance)
    base = d  # what the surfaces make of the rendered depth, in place: d is read no more
    if len(edges):
        r = rng.random(len(edges))
        flying = (r >= noise.edge_missing) & (r < noise.edge_missing + noise.flying)
        mixed = d.flat[edges] + rng.random(len(edges)) * (across - d.flat[edges])
        base.flat[edges[flying]] = mixed[flying]  # NaN where the other side has no return
        base.flat[edges[r < noise.edge_missing]] = np.nan
    base.flat[holes[rng.random(len(holes), np.float32) < lost]] = np.nan
    # Lateral jitter to first order: the depth where the pixel's offset lands on its own
    # surface, gradient . offset (edges have their own errors above); it and the axial
    # noise are independent zero-mean normals, so their sum is one normal whose variance
    # is theirs summed.
    var = np.square(noise.axial_sigma(base, focal_px), dtype=np.float32)  # NaN: no return
    if noise.lateral_px > 0:
        smooth = (np.abs(du) <= 2 * EDGE_JUMP) & (np.abs(dv) <= 2 * EDGE_JUMP)
        slope = np.where(smooth, np.square(du) + np.square(dv), np.float32(0.0))
        var += np.float32((noise.lateral_px / 2) ** 2) * slope
    return _frames(base, var, noise, rng, frames)


def _frames(base: np.ndarray, var: np.ndarray, noise: CameraNoise, rng: np.random.Generator,
            frames: int) -> np.ndarray:
    """`frames` images [F, H, W]: base plus normal noise of variance `var`, in steps of
    `depth_unit`; all in units of the step (one scaling per camera), a frame at a time."""
    unit = np.float32(noise.depth_unit if noise.depth_unit > 0 else 1.0)
    shift = base / unit
    out = np.empty((frames, *base.shape), np.float32)
    noisy = noise.subpixel > 0 or noise.lateral_px > 0
    scale = np.sqrt(var) / unit if noisy else None
    for frame in out:
        if noisy:
            standard_normal(rng, frame)
            frame *= scale
            frame += shift
        else:
            frame[:] = shift
        if noise.depth_unit > 0:
            np.rint(frame, out=frame)
            frame *= unit
    return out


def standard_normal(rng: np.random.Generator, out: np.ndarray) -> np.ndarray:
    """Fills `out` (float32, C-contiguous) with independent standard normals drawn from
    `rng`'s bits: Box-Muller on 23-bit uniforms, float32 throughout (numpy's float32
    ziggurat costs twice as much). Each pair of 32-bit words u, t gives
    sqrt(-2 ln u) (cos 2 pi t, sin 2 pi t), u on (0, 1] and t on [0, 1) in steps of 2^-23;
    the tail is cut at 5.65 sigma (probability 2e-8)."""
    flat = out.reshape(-1)
    n = flat.size
    m = (n + 1) // 2
    bits = rng.bit_generator.random_raw(m).view(np.uint32)  # 2m words
    bits >>= 9
    bits |= np.uint32(0x3F800000)  # the float32 of 1 + the word's top 23 bits / 2^23
    f = bits.view(np.float32)
    r, turn = f[:m], f[m:]
    np.subtract(np.float32(2.0), r, out=r)  # u on (0, 1]
    np.log(r, out=r)
    r *= np.float32(-2.0)
    np.sqrt(r, out=r)
    turn *= np.float32(2 * np.pi)  # 2 pi (1 + t): the same cosine and sine as 2 pi t
    np.cos(turn, out=flat[:m])
    flat[:m] *= r
    np.sin(turn[:n - m], out=flat[m:])
    flat[m:] *= r[:n - m]
    return out


def _hole_probability(d, du, dv, focal_px, center, noise, reflectance
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The pixels that may have no return, for their surface: grazing or dark (flat
    indices), and each one's chance."""
    lost = np.zeros(d.size, np.float32)
    if noise.steep_holes > 0:
        at, cos = _steep(d, du, dv, focal_px, center)
        ramp = (np.arccos(cos) - np.float32(STEEP_FROM)) / np.float32(np.pi / 2 - STEEP_FROM)
        lost[at] = np.float32(noise.steep_holes) * np.clip(ramp, 0, 1)
    if noise.dark_holes > 0 and reflectance is not None:
        refl = np.asarray(reflectance, np.float32).reshape(-1)
        at = np.flatnonzero(refl < np.float32(DARK_BELOW))
        ramp = (DARK_BELOW - refl[at]) / np.float32(DARK_BELOW)
        lost[at] = np.maximum(lost[at], np.float32(noise.dark_holes) * np.clip(ramp, 0, 1))
    at = np.flatnonzero(lost)
    return at, lost[at]


def _edges(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(flat indices of the pixels at a depth edge, the depth across the edge: that of the
    4-neighbour with the largest step, NaN where it has no return)."""
    h, w = d.shape
    # A neighbour with no return (beyond the range) is a step as large as can be; outside
    # the image there is none. Most pixels have no edge: find those that do, then look
    # at their four neighbours.
    rows = ~(np.abs(d[1:] - d[:-1]) <= EDGE_JUMP)
    cols = ~(np.abs(d[:, 1:] - d[:, :-1]) <= EDGE_JUMP)
    jump = np.zeros((h, w), bool)
    jump[1:] |= rows
    jump[:-1] |= rows
    jump[:, 1:] |= cols
    jump[:, :-1] |= cols
    idx = np.flatnonzero(jump & np.isfinite(d))
    r, c = np.divmod(idx, w)
    pad = np.pad(d, 1, constant_values=np.nan).ravel()
    at = (r + 1) * (w + 2) + c + 1
    nbs = np.stack([pad[at - (w + 2)], pad[at + (w + 2)], pad[at - 1], pad[at + 1]])
    inside = np.stack([r > 0, r < h - 1, c > 0, c < w - 1])
    step = np.where(np.isnan(nbs), np.inf, np.abs(nbs - d.flat[idx]))
    step = np.where(inside, step, 0.0)
    k = np.argmax(step, axis=0)
    across = np.take_along_axis(nbs, k[None], 0)[0]
    return idx, across


def _steep(d: np.ndarray, du: np.ndarray, dv: np.ndarray, focal_px: float,
           center: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """The pixels seen past STEEP_FROM (flat indices) and the |cos| of the angle between
    each one's surface normal (from its neighbours' points) and its view ray. Where a
    neighbour has no return (or on the image's border) the normal is unknown: as if
    facing the camera. `du`, `dv`: the depth's central differences across columns and rows.

    With the ray r = (x, y, 1) and the point p = d r, the tangents are
    p(u+1) - p(u-1) = du r + (su / f, 0, 0) and p(v+1) - p(v-1) = dv r + (0, sv / f, 0),
    su and sv the sums of the two neighbours' depths; their cross product, the normal n, is
    (-du b, -dv a, du b x + dv a y + a b) with a = su / f, b = sv / f, and its dot with
    r is a b (> 0): cos = a b / (|n| |r|), below cos(STEEP_FROM) = c where
    (a b)^2 < c^2 |n|^2 |r|^2, whose terms are found for every pixel, in place."""
    h, w = d.shape
    x, y, ray_sq = _rays(h, w, float(focal_px), float(center[0]), float(center[1]))
    a = np.zeros_like(d)
    b = np.zeros_like(d)
    np.add(d[:, 2:], d[:, :-2], out=a[:, 1:-1])
    np.add(d[2:, :], d[:-2, :], out=b[1:-1, :])
    a *= np.float32(1.0 / focal_px)
    b *= np.float32(1.0 / focal_px)
    ab = a * b
    n_x = np.multiply(du, b, out=b)  # -(n's x)
    n_y = np.multiply(dv, a, out=a)
    n_z = n_x * x
    n_z += n_y * y
    n_z += ab
    norm_sq = np.square(n_x, out=n_x)
    norm_sq += np.square(n_y, out=n_y)
    norm_sq += np.square(n_z, out=n_z)
    norm_sq *= ray_sq  # |n|^2 |r|^2; 0 on the border; NaN: unknown
    ab = ab.reshape(-1)
    norm_sq = norm_sq.reshape(-1)
    at = np.flatnonzero(np.square(ab) < np.float32(np.cos(STEEP_FROM) ** 2) * norm_sq)
    return at, ab[at] / np.sqrt(norm_sq[at])


@functools.lru_cache(maxsize=8)
def _rays(h: int, w: int, focal_px: float, cx: float, cy: float):
    """A camera's pixel rays (x [1, W], y [H, 1], with z = 1) and their squared lengths
    [H, W]."""
    x = ((np.arange(w) - cx) / focal_px).astype(np.float32)[None, :]
    y = ((np.arange(h) - cy) / focal_px).astype(np.float32)[:, None]
    return x, y, (np.square(x) + np.square(y) + 1).astype(np.float32)


def reflectance_by_label(scene_graph) -> np.ndarray | None:
    """Each render label's surface reflectance (its perception diffuse colour's luminance;
    1 for labels without a colour), indexed by label: what `dark_holes` reads. None where
    no surface is dark (below DARK_BELOW; the hand back-end's station): no return is lost
    for it, and no label image need be rendered."""
    from pydrake.geometry import Role

    inspector = scene_graph.model_inspector()
    known = {}
    for gid in inspector.GetAllGeometryIds(Role.kPerception):
        props = inspector.GetPerceptionProperties(gid)
        if props.HasProperty("label", "id") and props.HasProperty("phong", "diffuse"):
            rgb = props.GetProperty("phong", "diffuse").rgba[:3]
            known[int(props.GetProperty("label", "id"))] = float(rgb @ [0.2126, 0.7152, 0.0722])
    table = np.ones(max(known, default=0) + 2, np.float32)  # the last: every label beyond
    for label, value in known.items():
        table[label] = value
    return table if table.min() < DARK_BELOW else None
