"""Meshcat drawing for `symplan inspect` (agent/inspection.py): perceived boxes coloured by
their symbols, relations as brackets, a plan's steps as arcs, point clouds, the camera."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Box, Cylinder, Rgba, Sphere
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from drake_symplan.boxes import HALF_EXTENTS

PREFIX = "/symplan"
STEP_COLOURS = ("#ff7f0e", "#17becf", "#bcbd22", "#e377c2", "#2ca02c", "#9467bd")


def _rgba(hex_colour: str, alpha: float = 1.0):

    h = hex_colour.lstrip("#")
    return Rgba(*(int(h[i:i + 2], 16) / 255 for i in (0, 2, 4)), alpha)


def _rod(meshcat, path: str, p: np.ndarray, q: np.ndarray, rgba, radius: float = 0.004):

    d = np.asarray(q, float) - np.asarray(p, float)
    length = float(np.linalg.norm(d))
    if length < 1e-6:
        return
    meshcat.SetObject(path, Cylinder(radius, length), rgba)
    meshcat.SetTransform(path, RigidTransform(RotationMatrix.MakeFromOneVector(d, 2),
                                              (np.asarray(p) + np.asarray(q)) / 2))


def _ball(meshcat, path: str, p: np.ndarray, rgba, radius: float = 0.009):

    meshcat.SetObject(path, Sphere(radius), rgba)
    meshcat.SetTransform(path, RigidTransform(np.asarray(p, float)))


SCREEN_RIGHT = np.array([0.72, 0.69, 0.0])  # horizontal, across the default camera's view


def look_at(meshcat, points, distance: float = 0.95, shift: float = 0.12) -> None:
    """Camera toward the centroid of `points` from the default view's direction, nearer;
    the target moves `shift` m to the screen's left so that the scene clears the panel."""
    target = np.mean(np.asarray(points, float), axis=0)
    back = np.array([1.25, -1.3, 1.0]) / np.linalg.norm([1.25, -1.3, 1.0])
    target = target - shift * SCREEN_RIGHT
    meshcat.SetCameraPose(camera_in_world=target + distance * back, target_in_world=target)


def draw_view(meshcat, named_scene, view: dict, layer: str = "start", alpha: float = 0.8,
              inflate: float = 0.003) -> None:
    """Draws `view` (symbol_view) under /symplan/<layer>: boxes and relation brackets."""

    meshcat.Delete(f"{PREFIX}/{layer}")
    centres = {}
    for o, v in zip(named_scene.objects, view["objects"], strict=True):
        size = 2 * np.asarray(HALF_EXTENTS[o.type]) + inflate
        path = f"{PREFIX}/{layer}/boxes/{o.name}"
        meshcat.SetObject(path, Box(*size), _rgba(v["colour"], alpha))
        meshcat.SetTransform(path, RigidTransform(RotationMatrix(np.asarray(o.R)),
                                                  np.asarray(o.position, float)))
        centres[o.name] = np.asarray(o.position, float)
    for r in view["relations"]:
        p, q = centres[r["x"]], centres[r["y"]]
        k = int(r["relation"][1:])
        d = q - p
        vertical = abs(d[2]) > np.linalg.norm(d[:2])
        away = SCREEN_RIGHT if vertical else np.array([0.0, 0.0, 1.0])
        off = away * (0.04 + 0.015 * k)
        path = f"{PREFIX}/{layer}/relations/{r['relation']}/{r['x']}_{r['y']}"
        rgba = _rgba(r["colour"], alpha)
        for i, (a, b) in enumerate(((p, p + off), (p + off, q + off), (q + off, q))):
            _rod(meshcat, f"{path}/rod{i}", a, b, rgba)
        _ball(meshcat, f"{path}/head", q + off, rgba)


CLOUD_COLOURS = ("#e15759", "#4e79a7", "#59a14f", "#b07aa1")


def draw_clouds(meshcat, clouds: list[np.ndarray], layer: str = "start") -> None:
    """Each camera's points [n, 3] as a point cloud in its own colour."""
    from pydrake.perception import PointCloud

    for i, points in enumerate(clouds):
        cloud = PointCloud(len(points))
        cloud.mutable_xyzs()[:] = np.asarray(points, np.float32).T
        meshcat.SetObject(f"{PREFIX}/{layer}/clouds/camera{i}", cloud, point_size=0.002,
                          rgba=_rgba(CLOUD_COLOURS[i % len(CLOUD_COLOURS)]))


def draw_plan(meshcat, start_view: dict, plan: list[dict]) -> None:
    """Step i as an arc from its source to its target (start-scene positions) under
    /symplan/plan/step<i>, with a ball at the target's end."""
    meshcat.Delete(f"{PREFIX}/plan")
    where = {o["name"]: np.asarray(o["position"], float) for o in start_view["objects"]}
    top = max((p[2] for p in where.values()), default=0.0)
    for i, step in enumerate(plan):
        p, q = where[step["source"]], where[step["target"]]
        peak = top + 0.15 + 0.03 * i
        s = np.linspace(0, 1, 13)
        pts = [(1 - t) * p + t * q + np.array([0, 0, 4 * t * (1 - t) * (peak - max(p[2], q[2]))])
               for t in s]
        rgba = _rgba(STEP_COLOURS[i % len(STEP_COLOURS)])
        for j in range(len(pts) - 1):
            _rod(meshcat, f"{PREFIX}/plan/step{i}/rod{j}", pts[j], pts[j + 1], rgba, 0.004)
        _ball(meshcat, f"{PREFIX}/plan/step{i}/head", pts[-2], rgba, 0.012)


def draw_goal_scene(meshcat, goal_scene, alpha: float = 0.3) -> None:
    """The goal scene file's boxes (world.scenes.Scene), translucent green, under
    /symplan/goal/boxes: the demo's goal beside the recorded execution."""

    meshcat.Delete(f"{PREFIX}/goal")
    for o in goal_scene.objects:
        path = f"{PREFIX}/goal/boxes/{o.name}"
        meshcat.SetObject(path, Box(*(2 * np.asarray(HALF_EXTENTS[o.type]) + 0.004)),
                          _rgba("#2ca02c", alpha))
        meshcat.SetTransform(path, RigidTransform(RollPitchYaw(o.orientation),
                                                  np.asarray(o.position, float)))
