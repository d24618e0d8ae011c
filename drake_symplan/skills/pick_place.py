"""The paper's single action as an IK-planned joint trajectory executed in full physics.

pick(source, grasp) then place on target at a release offset: approach, descend, close,
lift, carry, descend, open, retreat, home. Offsets run along world y. The gripper TCP goes
to source + grasp offset, then to target + release offset, so the two offsets compose
(a long block grasped off-centre and released at the centre of a cube hangs over it).
Where the target's top is not under the released box (beside a raised target), the box
is set down on what is, as far as the gripper clears its neighbours (skills/geometry.py).
"""

from __future__ import annotations

import dataclasses as dc
import time
from collections.abc import Callable
from typing import TypeVar

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from drake_symplan.actions import Action
from drake_symplan.datasets import ObjectState
from drake_symplan.relations import riders
from drake_symplan.skills.arm_clearance import link_strikes
from drake_symplan.skills.carry import (
    CAREFUL_FINGER,
    CAREFUL_OPEN_SECONDS,
    CAREFUL_TCP_ACCELERATION,
)
from drake_symplan.skills.geometry import (
    ActionGeometry,
    InfeasibleAction,
    arm_geometry,
    refuse_strikes,
)
from drake_symplan.skills.ik import ArmIK
from drake_symplan.skills.timing import TCP_ACCELERATION, PathTimer, Phase
from drake_symplan.world.settling import settle_until_rest
from drake_symplan.world.station import FINGER_CLOSED, FINGER_OPEN, HOME_Q, Station

APPROACH_HEIGHT = 0.12  # m above grasp/release points
LIFTED_THRESHOLD = 0.05  # m of rise after the lift that counts as lifted
FINGER_SECONDS = 0.15  # the fingers close (open) on a box while the arm holds still
ARM_SETTLE_MAX = 0.5  # s of settling at most once home (the boxes were let go before)
LIFT_HOLD = 0.1  # s: the arm comes to rest after the lift (the PD overshoots ~1 cm)
RELEASE_HOLD = 0.1  # s: the arm comes to rest over the target before the fingers open

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


class PickPlaceMotions:
    """Turns an action and the caller's object states into a joint trajectory."""

    def __init__(self, ik: ArmIK | None = None):
        self.ik = ik or ArmIK()
        self.timer = PathTimer(self.ik.plant, self.ik.tcp)

    def _solve(self, what: str, p: np.ndarray, yaw: float, seed: np.ndarray) -> np.ndarray:
        q = self.ik.solve(p, yaw, seed)
        if q is None:
            raise InfeasibleAction(
                f"unreachable pose: {what} at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})",
                at="release" if what in ("release", "retreat") else "grasp")
        return q

    def plan(self, action: Action, objects: dict[str, ObjectState],
             q_start: np.ndarray = HOME_Q, lift_hold: bool = True) -> Motion:
        """The motion for `action` from the believed `objects`; `lift_hold`: the arm holds
        still LIFT_HOLD after the lift, for a camera to see the lifted scene."""
        # The fingers are symmetric under a half turn: the same grasp and release with
        # the wrist turned by pi. Near a box's folded yaw (a long block at +-90 deg, a
        # cube at +-45) a few degrees of belief pick the turn the joint box cannot reach.
        # A cube's quarter turn clear of its neighbours (action_geometry) that the arm
        # cannot reach either way is done unturned.
        g, carry = arm_geometry(action, objects)
        refusals = []
        for turned in (True, False):
            if not turned:
                plain, _ = arm_geometry(action, objects, turn=False)
                if (plain.yaw_grasp, plain.yaw_release) == (g.yaw_grasp, g.yaw_release):
                    break
                g = plain
            for geometry in (g, dc.replace(g, yaw_grasp=g.yaw_grasp + np.pi,
                                           yaw_release=g.yaw_release + np.pi)):
                try:
                    return self._motion(geometry, carry, q_start, lift_hold, action, objects)
                except InfeasibleAction as e:
                    refusals.append(e)
        # A turn whose pose is out of reach says nothing of what stands in the way; a
        # strike at another turn names the box that, moved, would let the arm run it
        raise next((e for e in refusals if e.obstacles), refusals[0])

    def _clear(self, waypoints: list[np.ndarray], objects: dict[str, ObjectState],
               skip: set[str], where: str, at: str) -> None:
        """InfeasibleAction where the wrist or forearm would strike a believed box (but
        `skip`) between the `waypoints` (skills/arm_clearance.py)."""
        struck = link_strikes(self.ik, waypoints, objects, skip)
        if struck is not None:
            link, name = struck
            raise InfeasibleAction(f"the arm's {link.removesuffix('_link')} would strike "
                                   f"{name} on the way {where}", (name,), at)

    def _motion(self, g: ActionGeometry, carry: str, q_start: np.ndarray,
                lift_hold: bool, action: Action, objects: dict[str, ObjectState]) -> Motion:
        load = {action.source, *riders(action.source, objects)}
        refuse_strikes(action, objects, g, load)
        careful = carry == "careful"
        loaded = CAREFUL_TCP_ACCELERATION if careful else TCP_ACCELERATION
        grip = CAREFUL_FINGER if careful else FINGER_CLOSED
        opening = CAREFUL_OPEN_SECONDS if careful else FINGER_SECONDS
        up = np.array([0.0, 0.0, APPROACH_HEIGHT])
        pre = self._solve("pre-grasp", g.grasp + up, g.yaw_grasp, q_start)
        mid = self._solve("grasp", g.grasp + up * 0.5, g.yaw_grasp, pre)
        at_grasp = self._solve("grasp", g.grasp, g.yaw_grasp, mid)
        lift = np.array([g.grasp[0], g.grasp[1], g.carry_z])
        carry = [self._solve("lift", lift, g.yaw_grasp, at_grasp)]
        above = np.array([g.release[0], g.release[1], g.carry_z])
        steps = max(1, int(np.ceil(float(np.linalg.norm(above[:2] - lift[:2])) / 0.15)))
        for k in range(1, steps + 1):
            f = k / steps
            carry.append(self._solve("carry", lift + (above - lift) * f,
                                     g.yaw_grasp + (g.yaw_release - g.yaw_grasp) * f, carry[-1]))
        at_release = self._solve("release", g.release, g.yaw_release, carry[-1])
        retreat = self._solve("retreat", g.release + up, g.yaw_release, at_release)
        self._clear([q_start, pre, mid, at_grasp], objects, {action.source},
                    f"down to {action.source}", "grasp")
        self._clear([carry[-1], at_release, retreat, HOME_Q], objects, load,
                    f"down to {action.target}", "release")
        opened, closed = _with_fingers(FINGER_OPEN), _with_fingers(grip)
        lifting = [
            Phase(opened(q_start, pre)),
            Phase(opened(pre, mid, at_grasp), tcp_acceleration=TCP_ACCELERATION),
            Phase(opened(at_grasp), dwell=FINGER_SECONDS, finger=grip),
            Phase(closed(at_grasp, carry[0]), tcp_acceleration=loaded),
        ]
        if lift_hold:
            lifting.append(Phase(closed(carry[0]), dwell=LIFT_HOLD, finger=grip))
        placing = [
            Phase(closed(*carry), tcp_acceleration=loaded),
            Phase(closed(carry[-1], at_release), tcp_acceleration=loaded),
            Phase(closed(at_release), dwell=RELEASE_HOLD, finger=grip),
            Phase(closed(at_release), dwell=opening, finger=FINGER_OPEN),
            Phase(opened(at_release, retreat, HOME_Q)),
        ]
        trajectory, ends = self.timer.trajectory(lifting + placing)
        return Motion(trajectory, ends[len(lifting) - 1], ends[-1])


def _with_fingers(finger: float):
    """Arm waypoints -> plant positions with both fingers at `finger`."""
    return lambda *qs: [np.concatenate([q, [finger, finger]]) for q in qs]


def run_motion(station: Station, motion: Motion, at_lift: Callable[[], T]) -> T:
    """Executes `motion` from the station's current time, then lets the boxes come to rest;
    returns what `at_lift()`, called once the lift has ended, returned (e.g. the scene
    perceived then)."""
    station.follow(motion.trajectory, 0.0, motion.t_lift)
    lifted = at_lift()
    station.follow(motion.trajectory, motion.t_lift, motion.t_end)
    settle_until_rest(station, 0.0, ARM_SETTLE_MAX)
    return lifted


def pick_place(
    station: Station,
    planner: PickPlaceMotions,
    action: Action,
    objects: dict[str, ObjectState],
) -> Outcome:
    """Plans from `objects` (the caller's belief) and executes on the station.

    Actions chain: each starts where the last one left the station. Reported poses are the
    simulator's (this is the outcome report, not an input to any decision); no camera
    looks at the lift, so the arm does not stop there.
    """
    t_wall = time.perf_counter()
    try:
        motion = planner.plan(action, objects, station.robot_positions(), lift_hold=False)
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
