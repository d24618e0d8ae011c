"""The paper's single action as an IK-planned joint trajectory executed in full physics.

pick(source, grasp) then place on target at a release offset: approach, descend, close,
lift, carry, descend, open, retreat, home. Offsets run along world y. The gripper TCP goes
to source + grasp offset, then to target + release offset, so the two offsets compose
(a long block grasped off-centre and released at the centre of a cube hangs over it).
"""

from __future__ import annotations

import dataclasses as dc
import time
from collections.abc import Callable
from typing import TypeVar

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from drake_symplan.boxes import HALF_EXTENTS, YAW_PERIOD, fold_yaw
from drake_symplan.skills.ik import ArmIK
from drake_symplan.structs import OFFSET_METRES, Action, ObjectState
from drake_symplan.world.station import FINGER_CLOSED, FINGER_OPEN, HOME_Q, Station

APPROACH_HEIGHT = 0.12  # m above grasp/release points
MIN_CARRY_HEIGHT = 0.20  # m, TCP height while carrying
CARRY_CLEARANCE = 0.10  # m above the highest object top while carrying
RELEASE_CLEARANCE = 0.004  # m gap between the held box's bottom and the target's top
LIFTED_THRESHOLD = 0.05  # m of rise after the lift that counts as lifted
JOINT_SPEED = np.array([2.09, 2.09, np.pi, np.pi, np.pi, np.pi])  # UR10 limits

T = TypeVar("T")


@dc.dataclass
class Motion:
    """A joint trajectory with the times at which the lift ends and the motion ends."""

    trajectory: PiecewisePolynomial
    t_lift: float
    t_end: float


@dc.dataclass
class ObjectOutcome:
    type: str
    start: list[float]
    after_lift: list[float]
    end: list[float]
    tilt_deg: float
    lifted: bool


@dc.dataclass
class Outcome:
    status: str  # "ok" | "infeasible" | "sim_failure"
    objects: dict[str, ObjectOutcome]
    seconds: float
    message: str = ""

    def to_json(self) -> dict:
        return {
            "status": self.status,
            "message": self.message,
            "objects": {
                n: {"type": o.type, "start": o.start, "end": o.end,
                    "after_lift": o.after_lift, "tilt_deg": o.tilt_deg, "lifted": o.lifted}
                for n, o in self.objects.items()
            },
            "seconds": self.seconds,
        }


class InfeasibleAction(Exception):
    """No IK solution for a waypoint of the action."""


def _top_z(o: ObjectState) -> float:
    hx, hy, hz = HALF_EXTENTS[o.type]
    return float(o.position[2] + hz * np.cos(o.tilt) + max(hx, hy) * np.sin(o.tilt))


def grasp_yaw(o: ObjectState) -> float:
    """Gripper yaw that closes the fingers across the box's short x side."""
    return fold_yaw(o.yaw, YAW_PERIOD[o.type])


@dc.dataclass
class ActionGeometry:
    """Where the gripper TCP goes for an action, from the caller's beliefs.

    Shared by the arm planner and the simulated hand (skills/hand_place.py), so both
    back-ends grasp, carry and release at the same points.
    """

    grasp: np.ndarray  # TCP at the grasp: source centre + grasp offset along world y
    release: np.ndarray  # TCP at the release: above target + release offset
    carry_z: float  # TCP height while carrying
    yaw_grasp: float
    yaw_release: float

    @property
    def carry_xy(self) -> np.ndarray:
        """The TCP's lateral travel from grasp to release (world xy, m)."""
        return (self.release - self.grasp)[:2]


def action_geometry(action: Action, objects: dict[str, ObjectState]) -> ActionGeometry:
    for name in (action.source, action.target):
        if name not in objects:
            raise ValueError(f"unknown object {name!r} (objects: {sorted(objects)})")
    src, tgt = objects[action.source], objects[action.target]
    grasp = src.position + np.array([0.0, OFFSET_METRES[action.grasp], 0.0])
    release = tgt.position + np.array([0.0, OFFSET_METRES[action.release], 0.0])
    release[2] = _top_z(tgt) + HALF_EXTENTS[src.type][2] + RELEASE_CLEARANCE
    carry_z = max(MIN_CARRY_HEIGHT, max(_top_z(o) for o in objects.values()) + CARRY_CLEARANCE)
    yaw_g = grasp_yaw(src)
    yaw_r = yaw_g + fold_yaw(tgt.yaw - src.yaw, YAW_PERIOD["cube"])  # any quarter turn lines up faces
    return ActionGeometry(grasp, release, float(carry_z), yaw_g, yaw_r)


def carry_duration(distance: float, steps: int) -> float:
    """Minimum carry time: >= 0.6 s per 30 cm so that boxes stacked on the load ride along."""
    return 0.6 * distance / 0.3 + 0.05 * steps


class PickPlacePlanner:
    """Turns an action and the caller's object states into a joint trajectory."""

    def __init__(self, ik: ArmIK | None = None):
        self.ik = ik or ArmIK()

    def _solve(self, what: str, p: np.ndarray, yaw: float, seed: np.ndarray) -> np.ndarray:
        q = self.ik.solve(p, yaw, seed)
        if q is None:
            raise InfeasibleAction(
                f"unreachable pose: {what} at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})")
        return q

    def plan(
        self, action: Action, objects: dict[str, ObjectState], q_start: np.ndarray = HOME_Q
    ) -> Motion:
        g = action_geometry(action, objects)
        grasp, release, carry_z = g.grasp, g.release, g.carry_z
        yaw_g, yaw_r = g.yaw_grasp, g.yaw_release
        up = np.array([0.0, 0.0, APPROACH_HEIGHT])

        knots: list[tuple[np.ndarray, float, float]] = []  # (q_arm, finger, min duration)
        q = self._solve("pre-grasp", grasp + up, yaw_g, q_start)
        knots.append((q, FINGER_OPEN, 0.4))
        for frac in (0.5, 1.0):
            q = self._solve("grasp", grasp + up * (1 - frac), yaw_g, q)
            knots.append((q, FINGER_OPEN, 0.15))
        knots.append((q, FINGER_CLOSED, 0.25))
        lift = np.array([grasp[0], grasp[1], carry_z])
        q = self._solve("lift", lift, yaw_g, q)
        knots.append((q, FINGER_CLOSED, 0.35))
        n_lift = len(knots)
        above = np.array([release[0], release[1], carry_z])
        dist = float(np.linalg.norm(above[:2] - lift[:2]))
        steps = max(1, int(np.ceil(dist / 0.15)))
        for k in range(1, steps + 1):
            f = k / steps
            q = self._solve("carry", lift + (above - lift) * f, yaw_g + (yaw_r - yaw_g) * f, q)
            knots.append((q, FINGER_CLOSED, carry_duration(dist, steps) / steps))
        q = self._solve("release", release, yaw_r, q)
        knots.append((q, FINGER_CLOSED, 0.35))
        knots.append((q, FINGER_OPEN, 0.25))
        q = self._solve("retreat", release + up, yaw_r, q)
        knots.append((q, FINGER_OPEN, 0.2))
        knots.append((HOME_Q, FINGER_OPEN, 0.45))
        knots.append((HOME_Q, FINGER_OPEN, 0.15))  # settle

        times, qs = [0.0], [np.concatenate([q_start, [FINGER_OPEN] * 2])]
        t_lift = 0.0
        for i, (qk, finger, dmin) in enumerate(knots):
            dq = np.abs(qk - qs[-1][:6])
            times.append(times[-1] + max(dmin, float(np.max(1.5 * dq / JOINT_SPEED))))
            qs.append(np.concatenate([qk, [finger, finger]]))
            if i + 1 == n_lift:
                t_lift = times[-1]
        traj = PiecewisePolynomial.CubicShapePreserving(
            times, np.column_stack(qs), zero_end_point_derivatives=True)
        return Motion(traj, t_lift, times[-1])


def run_motion(station: Station, motion: Motion, at_lift: Callable[[], T]) -> T:
    """Executes `motion` from the station's current time; returns what `at_lift()`, called
    once the lift has ended, returned (e.g. the scene perceived then)."""
    station.follow(motion.trajectory, 0.0, motion.t_lift)
    lifted = at_lift()
    station.follow(motion.trajectory, motion.t_lift, motion.t_end)
    return lifted


def pick_place(
    station: Station,
    planner: PickPlacePlanner,
    action: Action,
    objects: dict[str, ObjectState],
) -> Outcome:
    """Plans from `objects` (the caller's belief) and executes on the station.

    Actions chain: each starts where the last one left the station. Reported poses are the
    simulator's (this is the outcome report, not an input to any decision).
    """
    t_wall = time.perf_counter()
    try:
        motion = planner.plan(action, objects, station.robot_positions())
    except InfeasibleAction as e:
        now = station.object_states()
        return Outcome("infeasible", _report(now, now, now), time.perf_counter() - t_wall,
                       str(e))
    start = station.object_states()
    snapshot = station.snapshot()
    try:
        lifted = run_motion(station, motion, station.object_states)
    except RuntimeError as e:
        station.restore(snapshot)
        return Outcome("sim_failure", _report(start, start, start),
                       time.perf_counter() - t_wall, f"simulation failed: {e}")
    return Outcome("ok", _report(start, lifted, station.object_states()),
                   time.perf_counter() - t_wall)


def _report(start: dict, lifted: dict, end: dict) -> dict[str, ObjectOutcome]:
    out = {}
    for name, s in start.items():
        out[name] = ObjectOutcome(
            type=s.type,
            start=[round(float(v), 5) for v in s.position],
            after_lift=[round(float(v), 5) for v in lifted[name].position],
            end=[round(float(v), 5) for v in end[name].position],
            tilt_deg=round(float(np.degrees(end[name].tilt)), 3),
            lifted=bool(lifted[name].position[2] - s.position[2] > LIFTED_THRESHOLD),
        )
    return out
