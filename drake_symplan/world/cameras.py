"""Depth cameras around the table: RgbdSensors rendered headless by VTK (EGL) + point clouds.

`AddDepthCameras` adds one RgbdSensor per camera config; `read_point_clouds` renders their
depth images (`render_depths`) and back-projects them into world-frame xyz arrays
(`depth_points`), with optional noise;
`read_depth_frames` gives the depth sensor's frames (world/depth_sensor.py) and
`back_project` their points, from where perception believes the camera is;
`robot_shapes` says where the robot is in them.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.geometry import (
    Box,
    ClippingRange,
    Cylinder,
    DepthRange,
    DepthRenderCamera,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.sensors import CameraInfo, RgbdSensor

from drake_symplan.world.depth_sensor import CameraNoise, sense

RENDERER = "vtk_depth"


@dc.dataclass
class CameraConfig:
    name: str = "camera"
    position: list[float] = dc.field(default_factory=lambda: [1.5, 0.0, 0.8])
    target: list[float] = dc.field(default_factory=lambda: [0.72, 0.0, 0.0])
    width: int = 640
    height: int = 480
    fov_y_deg: float = 45.0
    depth_min: float = 0.1
    depth_max: float = 3.0


def default_cameras() -> list[CameraConfig]:
    """Three cameras: one facing the robot across the table, one on each side."""
    return [
        CameraConfig("far", [1.55, 0.0, 0.80], [0.72, 0.0, 0.0]),
        CameraConfig("left", [0.80, 0.95, 0.75], [0.72, 0.0, 0.0]),
        CameraConfig("right", [0.80, -0.95, 0.75], [0.72, 0.0, 0.0]),
    ]


def look_at(position, target) -> RigidTransform:
    """Camera pose X_WC: camera z looks at `target`, camera y points down in the image."""
    p, t = np.asarray(position, float), np.asarray(target, float)
    z = t - p
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-6:  # looking straight down
        x = np.array([0.0, -1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return RigidTransform(RotationMatrix(np.column_stack([x, y, z])), p)


@dc.dataclass
class DepthCamera:
    """A camera where it is (X_WC, which renders) and where perception believes it is
    (X_WB, with `rays`: the same unless `miscalibrate` set an extrinsic error)."""

    config: CameraConfig
    sensor: RgbdSensor
    X_WC: RigidTransform
    rays: np.ndarray  # [H * W, 3] world-frame ray per pixel (believed), scaled to unit depth
    info: CameraInfo | None = None
    X_WB: RigidTransform | None = None

    def __post_init__(self):
        if self.X_WB is None:
            self.X_WB = self.X_WC
        # The height test runs on every pixel of every frame: a contiguous float32 column.
        self.ray_z = np.ascontiguousarray(self.rays[:, 2], dtype=np.float32)

    def miscalibrate(self, X_CB: RigidTransform) -> None:
        """Perception believes the camera is at X_WC * X_CB (an extrinsic calibration error)."""
        self.X_WB = self.X_WC @ X_CB
        self.rays = pixel_rays(self.info, self.X_WB)
        self.__post_init__()


def pixel_rays(info: CameraInfo, X_WC: RigidTransform) -> np.ndarray:
    """World-frame direction of each pixel's ray (row-major), scaled so that a point at
    depth d (along the optical axis) is X_WC.translation() + d * ray."""
    v, u = np.mgrid[0:info.height(), 0:info.width()]
    local = np.stack([(u.ravel() - info.center_x()) / info.focal_x(),
                      (v.ravel() - info.center_y()) / info.focal_y(),
                      np.ones(u.size)], axis=1)
    return local @ X_WC.rotation().matrix().T


def AddDepthCameras(builder, scene_graph, configs: list[CameraConfig]) -> list[DepthCamera]:
    """Adds the VTK (EGL, headless) renderer and the sensors."""
    if not configs:
        return []
    if not scene_graph.HasRenderer(RENDERER):
        scene_graph.AddRenderer(RENDERER, MakeRenderEngineVtk(RenderEngineVtkParams(
            backend="EGL")))
    cameras = []
    for cfg in configs:
        info = CameraInfo(cfg.width, cfg.height, np.radians(cfg.fov_y_deg))
        core = RenderCameraCore(RENDERER, info, ClippingRange(0.01, 10.0), RigidTransform())
        depth = DepthRenderCamera(core, DepthRange(cfg.depth_min, cfg.depth_max))
        X_WC = look_at(cfg.position, cfg.target)
        world_id = scene_graph.world_frame_id()
        sensor = builder.AddSystem(RgbdSensor(world_id, X_WC, depth))
        sensor.set_name(f"camera_{cfg.name}")
        builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
        cameras.append(DepthCamera(cfg, sensor, X_WC, pixel_rays(info, X_WC), info))
    return cameras


@dc.dataclass
class DepthNoise:
    """Gaussian noise along each camera ray plus random pixel dropout."""

    sigma: float = 0.0  # metres
    dropout: float = 0.0  # fraction of pixels lost

    @property
    def active(self) -> bool:
        return self.sigma > 0 or self.dropout > 0

    def apply(self, xyz: np.ndarray, origin: np.ndarray, rng: np.random.Generator):
        if self.dropout > 0:
            xyz = xyz[rng.random(len(xyz)) >= self.dropout]
        if self.sigma > 0:
            ray = xyz - origin
            ray /= np.linalg.norm(ray, axis=1, keepdims=True)
            xyz = xyz + ray * rng.normal(0.0, self.sigma, (len(xyz), 1))
        return xyz


def read_point_clouds(
    cameras: list[DepthCamera],
    root_context,
    noise: DepthNoise | None = None,
    rng: np.random.Generator | None = None,
    z_min: float | None = None,
) -> list[np.ndarray]:
    """World-frame points [M, 3] per camera (invalid depths dropped): `depth_points` of
    each camera's rendered depth."""
    return [depth_points(cam, depth, noise, rng, z_min)
            for cam, depth in zip(cameras, render_depths(cameras, root_context), strict=True)]


def render_depths(cameras: list[DepthCamera], root_context) -> list[np.ndarray]:
    """Each camera's rendered depth image [H, W] (float32, m; 0: nearer than depth_min,
    inf: beyond depth_max) of the scene now."""
    return [np.array(cam.sensor.depth_image_32F_output_port().Eval(
        cam.sensor.GetMyContextFromRoot(root_context)).data[:, :, 0]) for cam in cameras]


def depth_points(cam: DepthCamera, depth: np.ndarray, noise: DepthNoise | None = None,
                 rng: np.random.Generator | None = None, z_min: float | None = None
                 ) -> np.ndarray:
    """World-frame points [M, 3] of a perfect sensor's depth image [H, W] (float32; NaN,
    0 or inf: none), with optional noise.

    `z_min` drops points at or below that height (after noise) early, which saves most of
    the work when only what stands on the table matters: without noise, only the pixels
    that see something above z_min are back-projected.
    """
    depth = depth.reshape(-1)
    origin = cam.X_WB.translation()
    keep = depth > 0  # 0: nearer than depth_min; inf: beyond depth_max
    noisy = noise is not None and noise.active
    if z_min is not None and not noisy:
        keep &= depth * cam.ray_z > np.float32(z_min - origin[2])  # false for inf
    else:
        keep &= np.isfinite(depth)
    idx = np.flatnonzero(keep)
    xyz = origin + depth[idx, None].astype(float) * cam.rays[idx]
    if noisy:
        xyz = noise.apply(xyz, origin, rng or np.random.default_rng())
        if z_min is not None:
            xyz = xyz[xyz[:, 2] > z_min]
    return xyz


def read_depth_frames(cameras: list[DepthCamera], root_context, noise: CameraNoise,
                      rng: np.random.Generator, frames: int = 1,
                      reflectance: np.ndarray | None = None) -> list[np.ndarray]:
    """Each camera's `frames` sensor depth images [F, H, W] (NaN: no return) of the scene
    now; `reflectance[label]`: the surface reflectance of each render label."""
    out = []
    for cam in cameras:
        ctx = cam.sensor.GetMyContextFromRoot(root_context)
        depth = cam.sensor.depth_image_32F_output_port().Eval(ctx).data[:, :, 0]
        refl = None
        if noise.dark_holes > 0 and reflectance is not None:
            label = cam.sensor.label_image_output_port().Eval(ctx).data[:, :, 0]
            refl = reflectance.take(label, mode="clip")  # past the end: the last
        out.append(sense(depth, cam.info.focal_x(), (cam.info.center_x(), cam.info.center_y()),
                         noise, rng, frames, refl))
    return out


def back_project(cam: DepthCamera, depth: np.ndarray, z_min: float | None = None
                 ) -> np.ndarray:
    """World-frame points [M, 3] of a depth image [H, W] (NaN, 0, inf: none) as perception
    believes them (from X_WB), those at or below `z_min` dropped."""
    depth = depth.reshape(-1)
    idx = np.flatnonzero(np.isfinite(depth) & (depth > 0))
    xyz = np.take(cam.rays, idx, axis=0)  # (faster than rays[idx]; in place below)
    xyz *= depth[idx, None]
    xyz += cam.X_WB.translation()
    return xyz if z_min is None else xyz[xyz[:, 2] > z_min]


def robot_shapes(plant, query, model_instance) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The collision shapes of `model_instance` (the robot) at the state `query` was
    evaluated at, which perception cuts out of the point clouds: ("box", X_W [4x4],
    size xyz) or ("cylinder", X_W, [radius, length])."""
    inspector = query.inspector()
    shapes = []
    for body_index in plant.GetBodyIndices(model_instance):
        for gid in plant.GetCollisionGeometriesForBody(plant.get_body(body_index)):
            shape = inspector.GetShape(gid)
            X = query.GetPoseInWorld(gid).GetAsMatrix4()
            if isinstance(shape, Box):
                shapes.append(("box", X, np.array([shape.width(), shape.depth(),
                                                   shape.height()])))
            elif isinstance(shape, Cylinder):
                shapes.append(("cylinder", X, np.array([shape.radius(), shape.length()])))
    return shapes
