"""What a scene is and when it is valid: boxes on the table (ObjectSpec, Scene), the
workspace and validate_scene; world/scenes.py reads, writes and samples them.

Frames: world origin at the robot base, table top at z = 0. Positions are box centres;
a long block's long axis is its local y.

An object's orientation is its `yaw` (radians about world z) or, for poses a yaw cannot
express (a block tipped over a cube's edge, a block standing on its end), `rpy: [roll,
pitch, yaw]` (radians, Drake's RollPitchYaw: R = Rz(yaw) Ry(pitch) Rx(roll)); a file gives
one or the other, and `yaw` is then rpy's third angle. Upright objects (local z within
TILT_TOL of world z, up or down) must rest on the table or on another upright box; a
tilted object is not checked for support or overlap (physics settles it where it lands),
and an upright object above the table with a tilted object under its footprint is taken
as resting on it. Scenes written from a simulator's settled poses use `rpy` for the
tilted objects only (world/scenes.py: `scene_to_yaml`).
"""

from __future__ import annotations

import dataclasses as dc
import math

import numpy as np

from drake_symplan.boxes import HALF_EXTENTS, OBJECT_TYPES
from drake_symplan.datasets import ObjectState

# Where objects may be placed (box centres), metres.
WORKSPACE_X = (0.45, 1.0)
WORKSPACE_Y = (-0.4, 0.4)
MAX_OBJECTS = 16
POOL = {"cube": 16, "long": 8}  # boxes of each type the station holds (StationConfig's pool)

# Resting tolerance: a box is supported if its bottom is within this of the table or
# of another box's top, with overlapping footprints.
_SUPPORT_TOL = 0.005
_OVERLAP_TOL = 1e-4
TILT_TOL = math.radians(1.0)  # rad: a body z axis this close to world z (or -z) is upright


class SceneError(ValueError):
    """A malformed or physically impossible scene."""


@dc.dataclass
class ObjectSpec:
    name: str = ""
    type: str = "cube"
    position: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, 0.0])
    yaw: float = 0.0
    rpy: list[float] | None = None  # full orientation; None: upright at `yaw`

    def __post_init__(self):
        if self.rpy is not None and len(self.rpy) == 3:
            self.yaw = float(self.rpy[2])  # one yaw, whichever field the caller set

    @property
    def half_extents(self) -> np.ndarray:
        return np.array(HALF_EXTENTS[self.type])

    @property
    def orientation(self) -> list[float]:
        """[roll, pitch, yaw] (radians): `rpy`, or [0, 0, yaw] for an upright object."""
        return list(self.rpy) if self.rpy is not None else [0.0, 0.0, self.yaw]

    @property
    def tilted(self) -> bool:
        """Is the local z axis more than TILT_TOL away from world z (and from -z)?"""
        if self.rpy is None:
            return False
        roll, pitch, _ = self.rpy
        return abs(math.cos(roll) * math.cos(pitch)) < math.cos(TILT_TOL)


@dc.dataclass
class Scene:
    objects: list[ObjectSpec] = dc.field(default_factory=list)

    @property
    def names(self) -> list[str]:
        return [o.name for o in self.objects]

    def object_states(self) -> dict[str, ObjectState]:
        """The scene as written, as object states (a file's author's view of it)."""
        return {o.name: ObjectState(o.name, o.type, np.array(o.position, float), o.yaw)
                for o in self.objects}

    def object(self, name: str) -> ObjectSpec:
        for o in self.objects:
            if o.name == name:
                return o
        raise SceneError(f"no object named {name!r} in the scene (objects: {self.names})")


def _footprint_corners(o: ObjectSpec) -> np.ndarray:
    hx, hy, _ = HALF_EXTENTS[o.type]
    c, s = math.cos(o.yaw), math.sin(o.yaw)
    local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    return local @ np.array([[c, s], [-s, c]]) + np.array(o.position[:2])


def footprints_overlap(a: ObjectSpec, b: ObjectSpec, tol: float) -> bool:
    """Separating-axis test on the two yawed rectangles; touching is not overlapping."""
    ca, cb = _footprint_corners(a), _footprint_corners(b)
    for yaw in (a.yaw, b.yaw):
        for axis in (np.array([math.cos(yaw), math.sin(yaw)]),
                     np.array([-math.sin(yaw), math.cos(yaw)])):
            pa, pb = ca @ axis, cb @ axis
            if pa.max() <= pb.min() + tol or pb.max() <= pa.min() + tol:
                return False
    return True


def validate_scene(scene: Scene) -> Scene:
    """Raises SceneError naming the problem; returns the scene unchanged if it is valid."""
    if not scene.objects:
        raise SceneError("scene has no objects")
    if len(scene.objects) > MAX_OBJECTS:
        raise SceneError(f"scene has {len(scene.objects)} objects; at most {MAX_OBJECTS}")
    names = scene.names
    if len(set(names)) != len(names) or any(not n for n in names):
        raise SceneError(f"object names must be unique and non-empty, got {names}")
    for o in scene.objects:
        if o.type not in HALF_EXTENTS:
            raise SceneError(
                f"object {o.name!r} has unknown type {o.type!r}; expected one of {OBJECT_TYPES}"
            )
        if len(o.position) != 3 or not all(math.isfinite(v) for v in o.position):
            raise SceneError(f"object {o.name!r} position must be 3 finite numbers")
        if o.rpy is not None and (len(o.rpy) != 3 or not all(math.isfinite(v) for v in o.rpy)):
            raise SceneError(f"object {o.name!r} rpy must be 3 finite numbers")
        if not math.isfinite(o.yaw):
            raise SceneError(f"object {o.name!r} yaw must be a finite number, got {o.yaw}")
        x, y, _ = o.position
        if not (WORKSPACE_X[0] <= x <= WORKSPACE_X[1] and WORKSPACE_Y[0] <= y <= WORKSPACE_Y[1]):
            raise SceneError(
                f"object {o.name!r} at ({x:.3f}, {y:.3f}) is outside the workspace "
                f"x in {WORKSPACE_X}, y in {WORKSPACE_Y}"
            )
    upright = [o for o in scene.objects if not o.tilted]
    tilted = [o for o in scene.objects if o.tilted]
    for i, a in enumerate(upright):
        za, ha = a.position[2], HALF_EXTENTS[a.type][2]
        for b in upright[i + 1:]:
            zb, hb = b.position[2], HALF_EXTENTS[b.type][2]
            z_overlap = min(za + ha, zb + hb) - max(za - ha, zb - hb)
            if z_overlap > _SUPPORT_TOL and footprints_overlap(a, b, _OVERLAP_TOL):
                raise SceneError(f"objects {a.name!r} and {b.name!r} overlap")
        bottom = za - ha
        if abs(bottom) <= _SUPPORT_TOL:
            continue
        supported = any(
            abs(bottom - (b.position[2] + HALF_EXTENTS[b.type][2])) <= _SUPPORT_TOL
            and footprints_overlap(a, b, _OVERLAP_TOL)
            for b in upright if b is not a
        ) or any(b.position[2] < za and footprints_overlap(a, b, _OVERLAP_TOL) for b in tilted)
        if not supported:
            raise SceneError(
                f"object {a.name!r} (bottom at z = {bottom:.3f}) rests on neither the table "
                f"nor another object"
            )
    return scene
