"""The perception system: depth images -> perceived objects, features and contacts.

Perception reads `DepthViews`: each camera's intrinsics and pose, its depth frames, the
sensor model that made them and the robot's collision shapes. `station_views(station)`
gives them from the simulator's cameras, perception/frames.py from frames on disk; either
way `Perceiver.perceive_views` fuses the cameras' world-frame points (through the depth
filter when the sensor has noise), crops to the workspace, removes the table and the
robot's own points (from its geometry at the current joint state, as a real robot
self-filters), fits the known box models and builds the contact graph.
`Perceiver.perceive(station)` is the two together. Nothing here reads object poses from
the simulator.
"""

from __future__ import annotations

import dataclasses as dc
import time

import numpy as np

from drake_symplan.boxes import YAW_PERIOD, contact_graph, fold_yaw
from drake_symplan.datasets import ObjectState
from drake_symplan.features import object_features
from drake_symplan.perception import segmentation as seg
from drake_symplan.perception import tracking
from drake_symplan.perception.box_fitting import fit_boxes
from drake_symplan.perception.depth_filter import DepthFilter, filtered_clouds
from drake_symplan.perception.fitted_box import FittedBox
from drake_symplan.world.cameras import DepthCamera, depth_points, render_depths
from drake_symplan.world.depth_sensor import CameraNoise


@dc.dataclass
class PerceivedObject:
    name: str
    type: str
    position: np.ndarray
    yaw: float  # folded by the box's symmetry: in [-45, 45) deg for a cube, [-90, 90) a block
    tilt: float
    features: np.ndarray
    uncertain: bool
    R: np.ndarray  # box axes in world (columns x, y = long axis, z)

    def to_json(self) -> dict:
        return {"name": self.name, "type": self.type,
                "position": [round(float(v), 4) for v in self.position],
                "yaw_deg": round(float(np.degrees(self.yaw)), 2),
                "tilt_deg": round(float(np.degrees(self.tilt)), 2),
                "features": [round(float(v), 4) for v in self.features],
                "uncertain": bool(self.uncertain)}


@dc.dataclass
class PerceivedScene:
    objects: list[PerceivedObject]
    contacts: set[tuple[str, str]]

    @property
    def names(self) -> list[str]:
        return [o.name for o in self.objects]

    def object(self, name: str) -> PerceivedObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"no perceived object named {name!r} (perceived: {self.names})")

    def object_states(self) -> dict[str, ObjectState]:
        """What the skills take as beliefs."""
        return {o.name: ObjectState(o.name, o.type, o.position.copy(), o.yaw, o.tilt)
                for o in self.objects}

    def features(self) -> np.ndarray:
        return np.stack([o.features for o in self.objects]) if self.objects else \
            np.zeros((0, 9), np.float32)


@dc.dataclass
class DepthViews:
    """What perception reads of a scene, from the simulator or from frames on disk."""

    cameras: list[DepthCamera]  # intrinsics (info) and the pose perception believes (X_WB)
    frames: list[np.ndarray]  # each camera's depth images [F, H, W], float32 m (NaN, 0, inf: none)
    sensor: CameraNoise  # the sensor model that made them; none active: used as they are
    robot_shapes: list = dc.field(default_factory=list)  # cameras.robot_shapes, to cut out


def station_views(station, frames: int = 1) -> DepthViews:
    """What the station's cameras see now: `frames` frames of a sensor with noise, the
    rendered depth (one frame) of a perfect one."""
    if not station.cameras:
        raise ValueError("the station has no cameras (StationConfig.cameras is empty)")
    if station.sensor.active:
        depth = station.depth_frames(frames)
    else:
        depth = [d[None] for d in render_depths(station.cameras, station.context)]
    shapes = [s for s in station.robot_collision_shapes() if _near_workspace(s[1])]
    return DepthViews(station.cameras, depth, station.sensor, shapes)


class Perceiver:
    """Turns depth images into perceived objects.

    With a `prior` (the scene perceived before the action that led here) the objects the
    action left alone anchor the fit (perception/tracking.py); without one every object
    is fitted from the points alone. Frames of a sensor with noise are read through
    `depth_filter` (several frames, filtered, levelled on the table); `readings` says what
    each camera gave the last time, `stage_seconds` what each stage took (wall time:
    `sensing` the station's frames, `clouds` their points, `fitting` the boxes).
    """

    def __init__(self, depth_filter: DepthFilter | None = None):
        self.depth_filter = depth_filter or DepthFilter()
        self.readings = []
        self.stage_seconds: dict[str, float] = {}

    def perceive(self, station, noise=None, rng=None, prior: PerceivedScene | None = None
                 ) -> PerceivedScene:
        """The station's scene now; `noise` (a cameras.DepthNoise) perturbs the points
        further, drawn from `rng` (a noisy sensor's default: the station's own stream)."""
        # The sensor's own noise comes from the station (its seed and the scene), so a
        # scene is seen alike whatever the caller's stream has drawn before.
        t = time.perf_counter()
        views = station_views(station, self.depth_filter.frames)
        sensing = time.perf_counter() - t
        if rng is None and station.sensor.active:
            rng = station.sensor_rng
        perceived = self.perceive_views(views, noise, rng, prior)
        self.stage_seconds = {"sensing": sensing, **self.stage_seconds}
        return perceived

    def perceive_views(self, views: DepthViews, noise=None, rng=None,
                       prior: PerceivedScene | None = None) -> PerceivedScene:
        """The scene `views` show."""
        t = time.perf_counter()
        points = seg.crop(np.vstack(self.read_clouds(views, noise, rng)))
        points = seg.remove_inside(points, views.robot_shapes)
        t_clouds = time.perf_counter()
        perceived = self.perceive_points(points, prior)
        self.stage_seconds = {"clouds": t_clouds - t, "fitting": time.perf_counter() - t_clouds}
        return perceived

    def read_clouds(self, views: DepthViews, noise=None, rng=None) -> list[np.ndarray]:
        """Each camera's world-frame points above the table's crop; `noise` (a
        cameras.DepthNoise) perturbs them further."""
        z_min = seg.CROP_Z[0]
        if not views.sensor.active:
            self.readings = []
            return [depth_points(cam, f[0], noise, rng, z_min)
                    for cam, f in zip(views.cameras, views.frames, strict=True)]
        clouds, self.readings = filtered_clouds(views.cameras, views.frames, views.sensor,
                                                self.depth_filter, z_min)
        if noise is not None and noise.active:
            rng = rng or np.random.default_rng()
            clouds = [_above(noise.apply(c, cam.X_WB.translation(), rng), z_min)
                      for cam, c in zip(views.cameras, clouds, strict=True)]
        return clouds

    def perceive_points(self, points: np.ndarray, prior: PerceivedScene | None = None
                        ) -> PerceivedScene:
        hm = seg.height_map(points)
        old = [FittedBox(o.type, o.position, o.R, o.uncertain) for o in prior.objects] \
            if prior is not None else []
        boxes = fit_boxes(points, hm, prior=old)
        if old:
            boxes = tracking.track(old, boxes, points, hm)
        # Stable names by position so a scene always gets the same names.
        boxes.sort(key=lambda b: (round(b.center[0], 2), round(b.center[1], 2), b.center[2]))
        objects = [
            PerceivedObject(f"p{i}", b.type, b.center, fold_yaw(b.yaw, YAW_PERIOD[b.type]),
                            b.tilt, object_features(b.type, b.center, b.R), b.uncertain, b.R)
            for i, b in enumerate(boxes)
        ]
        contacts = contact_graph({o.name: (o.position, o.R, np.array(b.half_extents))
                                  for o, b in zip(objects, boxes, strict=True)})
        return PerceivedScene(objects, contacts)


def _above(points: np.ndarray, z: float) -> np.ndarray:
    return points[points[:, 2] > z]


def _near_workspace(X: np.ndarray) -> bool:
    p = X[:3, 3]
    return bool(seg.CROP_X[0] - 0.3 < p[0] < seg.CROP_X[1] + 0.3
                and seg.CROP_Y[0] - 0.3 < p[1] < seg.CROP_Y[1] + 0.3 and p[2] < 0.8)


from drake_symplan.perception.association import associate  # noqa: E402,F401  (public API)
