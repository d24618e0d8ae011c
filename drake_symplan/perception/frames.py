"""Depth frames on disk, both ways: `write_frames` puts what perception reads of a scene
(perceive.DepthViews) in a folder, `read_frames` reads such a folder back, checked, for
`Perceiver.perceive_views`: the same pipeline as from the simulator's cameras.

A frames folder holds, per camera NAME:

- depth images, 16-bit grayscale PNGs of the depth along the optical axis in units of
  `depth_scale` (millimetres: 0.001), 0 where the camera got no return: the format the
  RealSense SDK and ROS write. One image, or several of the scene at rest (a sensor with
  noise: the depth filter takes their temporal median);
- NAME.yaml, its camera file: the fields of ROS's sensor_msgs/CameraInfo that apply
  (`header.frame_id`, `width`, `height`, `K` = [fx, 0, cx, 0, fy, cy, 0, 0, 1]; `D`, if
  given, all zero: the images are undistorted; `R`, if given, the identity), and
  `depth_scale` (m per unit), `X_WC` (4x4, row by row: the camera's optical frame, z
  forward, x right, y down, in the world frame, whose plane z = 0 is the table's top),
  `depth` (its images' file names) and `sensor` (the sensor model the depth filter
  assumes, world/depth_sensor.CAMERA_NOISE: realsense for a RealSense D400, none for a
  perfect sensor, whose depth is used as it is; default none).

and, optionally, robot.yaml: `collision_shapes`, the robot's collision shapes in the
world (each `shape`: box or cylinder, `X_W` 4x4, `size`: [x, y, z] or [radius, length]),
whose points perception cuts out; leave it out when the arm is clear of the table.

A RealSense user records such a folder with pyrealsense2 (`pip install pyrealsense2`; not a
dependency of this package), the camera's extrinsics X_WC from their own calibration:

    import numpy as np, pyrealsense2 as rs, yaml
    from PIL import Image

    pipe, cfg = rs.pipeline(), rs.config()
    cfg.enable_stream(rs.stream.depth, 640, 480, rs.format.z16, 30)
    profile = pipe.start(cfg)
    scale = profile.get_device().first_depth_sensor().get_depth_scale()  # 0.001: mm
    k = profile.get_stream(rs.stream.depth).as_video_stream_profile().get_intrinsics()
    names = [f"d435_{i}.png" for i in range(5)]  # five frames of the scene at rest
    for name in names:
        depth = pipe.wait_for_frames().get_depth_frame()
        Image.fromarray(np.asanyarray(depth.get_data())).save(f"frames/{name}")  # uint16
    pipe.stop()
    X_WC = np.loadtxt("d435_extrinsics.txt")  # 4x4, from your hand-eye calibration
    yaml.safe_dump({"header": {"frame_id": "d435"}, "width": k.width, "height": k.height,
                    "K": [k.fx, 0, k.ppx, 0, k.fy, k.ppy, 0, 0, 1], "depth_scale": scale,
                    "X_WC": X_WC.tolist(), "sensor": "realsense", "depth": names},
                   open("frames/d435.yaml", "w"))

then `symplan perceive --frames frames`. A folder that cannot be read as such (a PNG no
camera file names, an image missing or of the wrong size or bit depth, a pose that is not
a rigid transform, a camera that sees no table) is a `BadFrames` naming the file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from PIL import Image
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.sensors import CameraInfo

from drake_symplan.perception.perceive import DepthViews
from drake_symplan.perception.segmentation import CROP_X, CROP_Y
from drake_symplan.world.cameras import CameraConfig, DepthCamera, pixel_rays
from drake_symplan.world.depth_sensor import CAMERA_NOISE

DEPTH_SCALE = 0.001  # m per PNG unit written: millimetres, the RealSense SDK's and ROS's
ROBOT_FILE = "robot.yaml"
# Pillow's modes of a 16-bit grayscale PNG (older Pillows read them as "I"; an 8-bit one
# is "L", a colour one "RGB", ...).
PNG_MODES = ("I;16", "I;16B", "I;16L", "I")
MAX_UNIT = np.iinfo(np.uint16).max
ROTATION_TOLERANCE = 1e-6
TABLE_BAND = 0.03  # m: a point this near z = 0 inside the workspace is the table's
MIN_TABLE_POINTS = 1000  # a camera seeing fewer of the table's points sees no table


class BadFrames(ValueError):
    """A frames folder that cannot be read: the message names the file and the problem."""


def sensor_name(views: DepthViews) -> str:
    for name, model in CAMERA_NOISE.items():
        if model == views.sensor:
            return name
    raise ValueError(f"the sensor model {views.sensor} has no name in CAMERA_NOISE")


def write_frames(views: DepthViews, out: Path) -> dict:
    """Writes `views` into the folder `out` (which exists); what it wrote, by camera."""
    out = Path(out)
    sensor = sensor_name(views)
    written = {}
    for cam, frames in zip(views.cameras, views.frames, strict=True):
        name = cam.config.name
        images = [f"{name}.png"] if len(frames) == 1 else \
            [f"{name}_{i}.png" for i in range(len(frames))]
        for image, depth in zip(images, frames, strict=True):
            Image.fromarray(to_units(depth, DEPTH_SCALE)).save(out / image)
        (out / f"{name}.yaml").write_text(yaml.safe_dump(
            camera_file(cam, images, sensor), sort_keys=False, default_flow_style=None))
        written[name] = images
    shapes = [{"shape": kind, "X_W": np.asarray(X).tolist(), "size": np.asarray(size).tolist()}
              for kind, X, size in views.robot_shapes]
    (out / ROBOT_FILE).write_text(yaml.safe_dump({"collision_shapes": shapes},
                                                 sort_keys=False, default_flow_style=None))
    return written


def to_units(depth: np.ndarray, scale: float) -> np.ndarray:
    """Depth [H, W] in m (NaN, 0, inf: none) as uint16 units of `scale`, 0: none."""
    units = np.rint(np.asarray(depth, np.float64) / scale)
    units[~np.isfinite(units) | (units > MAX_UNIT) | (units < 0)] = 0
    return units.astype(np.uint16)


def camera_file(cam: DepthCamera, images: list[str], sensor: str) -> dict:
    """The camera file of `cam` (the pose perception believes it has)."""
    info = cam.info
    fx, fy, cx, cy = info.focal_x(), info.focal_y(), info.center_x(), info.center_y()
    return {
        "header": {"frame_id": cam.config.name},
        "width": info.width(), "height": info.height(),
        "distortion_model": "plumb_bob", "D": [0.0] * 5,
        "K": [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
        "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "P": [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        "depth_scale": DEPTH_SCALE,
        "X_WC": cam.X_WB.GetAsMatrix4().tolist(),
        "sensor": sensor,
        "depth": images,
    }


def read_frames(folder: Path) -> DepthViews:
    """The folder's cameras and frames, checked (BadFrames names the file at fault)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise BadFrames(f"{folder}: not a directory")
    files = sorted(p for p in folder.glob("*.yaml") if p.name != ROBOT_FILE)
    if not files:
        raise BadFrames(f"{folder}: no camera file (NAME.yaml)")
    cameras, frames, sensors, named = [], [], [], set()
    for path in files:
        fields = _yaml(path)
        cam, images, scale = _camera(path, fields)
        sensor = _field(path, fields, "sensor", str, "none")
        if sensor not in CAMERA_NOISE:
            raise BadFrames(f"{path}: unknown sensor {sensor!r}; expected one of "
                            f"{tuple(CAMERA_NOISE)}")
        if sensors and sensor != sensors[0]:
            raise BadFrames(f"{path}: sensor {sensor}, but {files[0].name} says {sensors[0]}")
        stack = np.stack([_read_depth(folder / image, cam, scale) for image in images])
        _check_table(folder / images[0], cam, stack[0])
        cameras.append(cam)
        frames.append(stack)
        sensors.append(sensor)
        named |= set(images)
    for png in sorted(folder.glob("*.png")):
        if png.name not in named:
            raise BadFrames(f"{png}: no camera file names this depth image")
    return DepthViews(cameras, frames, CAMERA_NOISE[sensors[0]], _robot_shapes(folder))


def _yaml(path: Path) -> dict:
    try:
        fields = yaml.safe_load(path.read_text())
    except yaml.YAMLError as e:
        raise BadFrames(f"{path}: not YAML ({' '.join(str(e).split())})") from e
    if not isinstance(fields, dict):
        raise BadFrames(f"{path}: not a mapping of fields")
    return fields


_MISSING = object()


def _field(path: Path, fields: dict, key: str, kind, default=_MISSING):
    value = fields.get(key, default)
    if value is _MISSING:
        raise BadFrames(f"{path}: no field {key!r}")
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or isinstance(value, bool):
        raise BadFrames(f"{path}: {key} must be a {kind.__name__}, got {value!r}")
    return value


def _numbers(path: Path, fields: dict, key: str, shape: tuple, default=_MISSING) -> np.ndarray:
    value = fields.get(key, default)
    if value is _MISSING:
        raise BadFrames(f"{path}: no field {key!r}")
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != shape or not np.isfinite(a).all():
        raise BadFrames(f"{path}: {key} must be {' x '.join(map(str, shape))} finite numbers")
    return a


def _camera(path: Path, fields: dict) -> tuple[DepthCamera, list[str], float]:
    """(the camera, its images' names, its depth scale) of the camera file `path`."""
    width, height = (_field(path, fields, k, int) for k in ("width", "height"))
    K = _numbers(path, fields, "K", (9,))
    fx, cx, fy, cy = K[0], K[2], K[4], K[5]
    if width < 1 or height < 1 or fx <= 0 or fy <= 0 or not np.allclose(
            K[[1, 3, 6, 7, 8]], [0, 0, 0, 0, 1]):
        raise BadFrames(f"{path}: width, height and K = [fx, 0, cx, 0, fy, cy, 0, 0, 1] "
                        "must describe a pinhole camera (fx, fy > 0)")
    D = fields.get("D") or []
    if not isinstance(D, list) or np.any(_numbers(path, fields, "D", (len(D),)) != 0):
        raise BadFrames(f"{path}: D must be all zero (undistorted depth images)")
    if not np.allclose(_numbers(path, fields, "R", (9,), np.eye(3).ravel()), np.eye(3).ravel()):
        raise BadFrames(f"{path}: R must be the identity (no rectification)")
    scale = _field(path, fields, "depth_scale", float)
    if not 0 < scale < np.inf:
        raise BadFrames(f"{path}: depth_scale must be a positive number of m per unit")
    X = _pose(path, fields, "X_WC")
    images = _field(path, fields, "depth", list)
    if not images or not all(isinstance(i, str) and Path(i).name == i for i in images):
        raise BadFrames(f"{path}: depth must list its images' file names (in this folder)")
    name = str((fields.get("header") or {}).get("frame_id") or path.stem)
    try:
        info = CameraInfo(width, height, fx, fy, cx, cy)
    except (RuntimeError, ValueError) as e:
        raise BadFrames(f"{path}: {' '.join(str(e).split())}") from e
    config = CameraConfig(name, width=width, height=height)
    return DepthCamera(config, None, X, pixel_rays(info, X), info), images, scale


def _pose(path: Path, fields: dict, key: str, where: str = "") -> RigidTransform:
    """The 4x4 pose `fields[key]`, checked to be a rigid transform."""
    X = _numbers(path, fields, key, (4, 4))
    R = X[:3, :3]
    if not np.allclose(X[3], [0, 0, 0, 1], rtol=0, atol=ROTATION_TOLERANCE) or not np.allclose(
            R.T @ R, np.eye(3), rtol=0, atol=ROTATION_TOLERANCE) or np.linalg.det(R) <= 0:
        raise BadFrames(f"{path}: {where}{key} is not a pose: its upper 3 x 3 must be a rotation "
                        "(orthonormal, determinant 1) and its last row 0 0 0 1")
    if not np.allclose(R.T @ R, np.eye(3), rtol=0, atol=1e-14):
        # A file's few digits: made exactly orthonormal (the nearest rotation).
        u, _, vt = np.linalg.svd(R)
        R = u @ vt
    return RigidTransform(RotationMatrix(R), X[:3, 3])


def _read_depth(png: Path, cam: DepthCamera, scale: float) -> np.ndarray:
    """The depth image `png` in m [H, W] (float32, NaN: no return), checked."""
    if not png.is_file():
        raise BadFrames(f"{png}: missing (named by {cam.config.name}'s camera file)")
    try:
        with Image.open(png) as image:
            image.load()
    except (OSError, SyntaxError, ValueError) as e:  # Pillow's unreadable image
        raise BadFrames(f"{png}: not an image ({' '.join(str(e).split())})") from e
    if image.format != "PNG" or image.mode not in PNG_MODES:
        raise BadFrames(f"{png}: a {image.format} of mode {image.mode}, not a 16-bit "
                        "grayscale PNG")
    w, h = cam.info.width(), cam.info.height()
    if image.size != (w, h):
        raise BadFrames(f"{png}: {image.size[0]} x {image.size[1]} pixels, its camera file "
                        f"says {w} x {h}")
    units = np.asarray(image, dtype=np.uint16)
    depth = units.astype(np.float32)
    depth *= np.float32(scale)
    depth[units == 0] = np.nan
    return depth


def _check_table(png: Path, cam: DepthCamera, depth: np.ndarray) -> None:
    """BadFrames unless the camera sees the table's top (z = 0) in the workspace: a camera
    that does not is posed wrong (or looks elsewhere)."""
    d = depth.reshape(-1)
    idx = np.flatnonzero(np.isfinite(d))
    xyz = cam.X_WB.translation() + d[idx, None] * cam.rays[idx]
    x, y, z = xyz.T
    on = int(((np.abs(z) < TABLE_BAND) & (x > CROP_X[0]) & (x < CROP_X[1]) & (y > CROP_Y[0])
              & (y < CROP_Y[1])).sum())
    if on < MIN_TABLE_POINTS:
        raise BadFrames(f"{png}: no table in view ({on} points within {TABLE_BAND * 1000:g} "
                        "mm of the table's top z = 0 in the workspace, from the pose in its "
                        "camera file)")


def _robot_shapes(folder: Path) -> list:
    path = folder / ROBOT_FILE
    if not path.exists():
        return []
    shapes = _field(path, _yaml(path), "collision_shapes", list)
    out = []
    for i, s in enumerate(shapes):
        kind = s.get("shape") if isinstance(s, dict) else None
        if kind not in ("box", "cylinder"):
            raise BadFrames(f"{path}: collision_shapes[{i}] must be a box or a cylinder")
        X = _pose(path, s, "X_W", f"collision_shapes[{i}].")
        size = _numbers(path, s, "size", (3,) if kind == "box" else (2,))
        out.append((kind, X.GetAsMatrix4(), size))
    return out
