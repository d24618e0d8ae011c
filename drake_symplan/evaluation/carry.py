"""The carry suite: boxes riding on a carried box, and whether they stay on it.

Five scenes, each a base box with riders beside a target long block: a cube on a long
block at -9, 0 and +9 cm along its length, a two-cube tower, two cubes on a long block,
each also yawed as a whole. `kept` judges from the simulator's poses whether every rider
still rests on the base (ground truth: for benchmarks and tests, never a learning input);
`Runner` runs one action on the `hand` or the `arm` from a fresh scene, planned from the
scene itself or, with a sensor named, from the scene as the depth cameras perceive it.
tools/bench_carry.py runs the suite.
"""

from __future__ import annotations

import math
import time

import numpy as np

from drake_symplan.actions import OFFSETS, Action
from drake_symplan.agent.beliefs import name_by_file
from drake_symplan.datasets import ObjectState
from drake_symplan.perception.perceive import Perceiver
from drake_symplan.relations import Relation, unmet
from drake_symplan.skills.arm_twin import ArmTwin
from drake_symplan.skills.geometry import InfeasibleAction
from drake_symplan.skills.hand_place import hand_pick_place
from drake_symplan.skills.pick_place import PickPlaceMotions, pick_place
from drake_symplan.world.cameras import default_cameras
from drake_symplan.world.scenes import ObjectSpec, Scene, validate_scene
from drake_symplan.world.station import Station, StationConfig

BASE_XY = np.array([0.70, -0.15])  # the base's centre (unrotated)
TARGET_XY = np.array([0.70, 0.18])  # the target long block's centre
PIVOT = (BASE_XY + TARGET_XY) / 2  # the rotated variants turn about this point

# scene name -> [(name, type, offset along the base's long axis in m, level)]; level 0 is
# the base's (on the table), 1 on the base, 2 on level 1 (on the box below it).
SUITE: dict[str, list[tuple[str, str, float, int]]] = {
    "rider_m9": [("base", "long", 0.0, 0), ("r0", "cube", -0.09, 1)],
    "rider_0": [("base", "long", 0.0, 0), ("r0", "cube", 0.0, 1)],
    "rider_p9": [("base", "long", 0.0, 0), ("r0", "cube", 0.09, 1)],
    "tower": [("base", "cube", 0.0, 0), ("r0", "cube", 0.0, 1)],
    "two_cubes": [("base", "long", 0.0, 0), ("r0", "cube", -0.07, 1), ("r1", "cube", 0.07, 1)],
}
# Beyond the suite (`--scenes` may name them): what a careful arm cannot or can hardly keep.
HARD: dict[str, list[tuple[str, str, float, int]]] = {
    "hanging": [("base", "long", 0.0, 0), ("r0", "cube", 0.131, 1)],  # centre off the end
    "tall_p9": [("base", "long", 0.0, 0), ("r0", "cube", 0.09, 1), ("r1", "cube", 0.09, 2),
                ("r2", "cube", 0.09, 3)],  # a three-cube tower at the far end
    "tower3": [("base", "cube", 0.0, 0), ("r0", "cube", 0.0, 1), ("r1", "cube", 0.0, 2)],
    "long_on_long": [("base", "long", 0.0, 0), ("r0", "long", 0.0, 1)],  # a block on a block
    "long_on_cube": [("base", "cube", 0.0, 0), ("r0", "long", 0.0, 1)],  # a block balanced
}
SCENES = {**SUITE, **HARD}
ONTO = {"target": "target", "rider": "r0"}  # what the suite's actions place the base on


def suite_scene(name: str, yaw_deg: float = 0.0) -> Scene:
    """Suite scene `name` with the target block, the whole scene yawed by `yaw_deg` about PIVOT."""
    yaw = math.radians(yaw_deg)
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    objects = []
    for obj, kind, along, level in [*SCENES[name], ("target", "long", 0.0, 0)]:
        xy = (TARGET_XY if obj == "target" else BASE_XY) + np.array([0.0, along])
        xy = PIVOT + rot @ (xy - PIVOT)
        z = 0.025 + 0.05 * level
        objects.append(ObjectSpec(obj, kind, [float(xy[0]), float(xy[1]), z], yaw))
    return validate_scene(Scene(objects))


def supports(name: str) -> dict[str, str]:
    """Rider -> the box it rests on in scene `name` (the one a level below, same offset, or
    the base)."""
    boxes = SCENES[name]
    return {obj: next((o for o, _, a, lv in boxes if lv == level - 1 and a == along), "base")
            for obj, _, along, level in boxes if level > 0}


def kept(states: dict[str, ObjectState], name: str) -> bool:
    """Does every rider of suite scene `name` still rest on what it rested on, upright
    (relations.py's `on`, on the simulator's states)?"""
    return not unmet([Relation("on", (r, b)) for r, b in supports(name).items()], states)


class Runner:
    """One station per back-end; runs an action from a fresh scene, returns its verdict.
    `belief`: "truth" plans from the scene as built; a sensor of
    world/depth_sensor.CAMERA_NOISE ("none", "realsense", "heavy") plans from the scene as
    the cameras perceive it after it settles (`belief_error_mm` in each row)."""

    def __init__(self, belief: str = "truth", camera_seed: int = 0):
        self.belief = belief
        sensed = {} if belief == "truth" else {
            "cameras": default_cameras(), "camera_noise": belief, "camera_seed": camera_seed}
        self.arm = Station(StationConfig(**sensed))
        self.hand = Station(StationConfig(robot="hand", **sensed))
        self.planner = PickPlaceMotions()
        self.twin = ArmTwin()
        self.perceiver = Perceiver()

    def beliefs(self, station: Station, scene: Scene) -> dict[str, ObjectState]:
        if self.belief == "truth":
            return scene.object_states()
        # the scene file's names, as the agent gives them (a box not seen is left out)
        return name_by_file(self.perceiver.perceive(station), scene).scene.object_states()

    def run(self, backend: str, scene: Scene, name: str, action: Action) -> dict:
        station = self.arm if backend == "arm" else self.hand
        station.reset(scene)
        station.settle(0.1)
        start = {n: X.translation()[2] for n, X in station.object_poses().items()}
        beliefs = self.beliefs(station, scene)
        truth = station.object_states()
        error = max((float(np.linalg.norm(b.position - truth[n].position))
                     for n, b in beliefs.items()), default=0.0)
        t = time.process_time()
        if "base" not in beliefs or action.target not in beliefs:
            status, by_arm = "perception", False
        elif backend == "arm":
            status = pick_place(station, self.planner, action, beliefs).status
        else:
            status, by_arm = "ok", False
            try:
                by_arm = hand_pick_place(station, action, beliefs, twin=self.twin)[0].by_arm
            except InfeasibleAction:
                status = "infeasible"
            except RuntimeError:
                status = "sim_failure"
        cpu = time.process_time() - t
        poses = station.object_poses()
        base = poses["base"].translation()
        moved = bool(np.linalg.norm(base[:2] - scene.object("base").position[:2]) > 0.05
                     or abs(base[2] - start["base"]) > 0.02)
        row = {"status": status, "kept": kept(station.object_states(), name), "moved": moved,
               "cpu_s": round(cpu, 3), "seen": len(beliefs),
               "belief_error_mm": round(1000 * error, 2)}
        if backend == "hand":
            row["by_arm"] = by_arm
        return row


def bench_scene(runner: Runner, name: str, yaw_deg: float, onto: str = "target") -> dict:
    """The nine actions pick(base) place(`onto`) of scene `name` yawed by `yaw_deg` on both
    back-ends: onto the target block, or onto the base's first rider, `r0` (the stack
    shifted by the two offsets: what random play does to a stack every other time)."""
    scene = suite_scene(name, yaw_deg)
    target = ONTO[onto]
    rows = []
    for grasp in OFFSETS:
        for release in OFFSETS:
            action = Action("base", grasp, target, release)
            row = {"action": f"{grasp}/{release}"}
            for backend in ("hand", "arm"):
                row[backend] = runner.run(backend, scene, name, action)
            rows.append(row)
    n = len(rows)
    agree = sum(r["hand"]["kept"] == r["arm"]["kept"] for r in rows)
    return {
        "scene": name, "yaw_deg": round(yaw_deg, 2), "onto": onto, "actions": n,
        "moved": {b: sum(r[b]["moved"] for r in rows) for b in ("hand", "arm")},
        "kept": {b: sum(r[b]["kept"] for r in rows) for b in ("hand", "arm")},
        "agreement": round(agree / n, 4),
        "arm_cpu_s": round(sum(r["arm"]["cpu_s"] for r in rows) / n, 3),
        "rows": rows,
    }


