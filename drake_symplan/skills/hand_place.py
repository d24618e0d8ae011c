"""The paper's action executed by the collision-free hand (world/hand.py) on a "hand" station.

Same geometry as the arm (`action_geometry`: grasp point = source + grasp offset along
world y at the source's centre height, release point above target + release offset, the
same carry height and a carry no faster than the arm's; where the beliefs put boxes on the
source, the careful carry's points, `arm_geometry`), but no IK and no finger contact:
the simulator decides which box the fingers would close on (`grasp_catches`), welds it to
the hand, lifts, carries and lowers it along the TCP's path, releases it and lets physics
settle the scene. A box stacked on the held one rides along by friction, as with the arm.

When nothing rests on or leans against the held box (the simulator checks its own contact
state), carrying it cannot disturb anything: the hand then moves it kinematically (set
straight to the lift pose, then to the release pose) and only the release and settling
are simulated, which is most of the back-end's speed. Otherwise the lift runs in full
physics (what it raises rides along, what leaned on the box falls), and the load then
moves rigidly to the release pose. Either way, a release pose that is not clear of the
rest of the scene is reached by a descent in full physics from above it, as the arm's.

Where the arm would touch what the hand does not (its wrist striking a box on the way
down to the grasp, its open fingers landing on a neighbour there, its palm striking a
stack beside the grasp or the release: world/hand.py's `wrist_strikes`, `finger_strikes`,
`palm_strikes`; its fingers pinching the source and a rider together),
the hand would keep what the arm knocks over or drops; given an `ArmTwin`, the action is
run by the arm instead (skills/arm_twin.py), which refuses it where its planned wrist or
forearm would strike a believed box (skills/arm_clearance.py).
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.trajectories import PiecewisePolynomial

from drake_symplan.actions import Action
from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.datasets import ObjectState
from drake_symplan.relations import riders
from drake_symplan.skills.arm_twin import ArmTwin
from drake_symplan.skills.carry import release_strikes
from drake_symplan.skills.geometry import action_geometry, arm_geometry
from drake_symplan.world.hand import (
    finger_strikes,
    grasp_catches,
    hand_q_of_pose,
    palm_strikes,
    wrist_strikes,
)
from drake_symplan.world.settling import settle_until_rest
from drake_symplan.world.station import Station

VERTICAL_SPEED = 0.4  # m/s while lifting and lowering
MIN_VERTICAL_TIME = 0.35  # s, as the arm's lift and release knots
CARRY_STEP = 0.15  # m per carry segment, as the arm's
HAND_SETTLE_MIN = 0.15  # s of physics after the release before checking for rest
HAND_SETTLE_MAX = 1.2  # s
RELEASE_MIN_CLEARANCE = 0.001  # m: a release pose closer than this to anything is not free
STACKED_DZ = 0.01  # m: a touching box whose centre is this much higher rides on the held one
RIDER_DZ = 0.01  # m: a box the lift raised this much rides on the load


@dc.dataclass
class HandMotion:
    """The held box's scene name (None: the grasp caught nothing) and its timed path."""

    held: str | None
    trajectory: PiecewisePolynomial | None = None  # hand q, starting at the held box's pose
    t_lift: float = 0.0
    t_release: float = 0.0
    t_above: float = 0.0  # end of the lateral carry, above the release point
    kinematic: bool = False  # nothing rides on the held box: skip simulating the carry
    struck: list[str] = dc.field(default_factory=list)  # what the arm's wrist or fingers would hit
    pinched: bool = False  # the arm's fingers would close on the source and a rider at once
    by_arm: bool = False  # the arm twin ran the action (hand_pick_place)


def carry_duration(distance: float, steps: int) -> float:
    """Minimum carry time: >= 0.6 s per 30 cm so that boxes stacked on the load ride along
    (no faster than the arm's carry at its TCP acceleration limit, skills/timing.py)."""
    return 0.6 * distance / 0.3 + 0.05 * steps


def plan_hand(
    station: Station, action: Action, beliefs: dict[str, ObjectState],
    allow_kinematic: bool = True, as_arm: bool = True,
) -> HandMotion:
    """Decides what the grasp catches (ground truth) and the hand's path from the beliefs:
    the action's points, or with `as_arm` the careful carry's where the arm carries
    carefully (it grasps clear of the riders and lowers the load onto what lies under it)."""
    arm, carry = arm_geometry(action, beliefs)
    g = arm if as_arm and carry == "careful" else action_geometry(action, beliefs)
    poses = station.object_poses()
    half = {n: np.array(HALF_EXTENTS[station.types[n]]) for n in poses}
    held = grasp_catches(poses, half, g.grasp)
    struck = wrist_strikes(poses, half, arm.grasp)
    struck += [n for n in finger_strikes(poses, half, arm.grasp, arm.yaw_grasp, held)
               if n not in struck]
    if held is not None:  # the palm beside what it carries, at the grasp and the release
        load = {held, *riders(held, station.object_states())}
        struck += [n for n in palm_strikes(poses, half, arm.grasp, arm.yaw_grasp, load)
                   + palm_strikes(poses, half, arm.release, arm.yaw_release, load)
                   + wrist_strikes(poses, half, arm.release)
                   + release_strikes(action, beliefs, arm.grasp, arm.release,
                                     arm.yaw_release - arm.yaw_grasp)
                   if n not in struck and n not in load]
    pinched = carry == "pinched"
    if held is None:
        return HandMotion(None, struck=struck, pinched=pinched)
    X_WT0 = RigidTransform(RotationMatrix.MakeZRotation(g.yaw_grasp), g.grasp)
    X_TB = X_WT0.inverse().multiply(poses[held])

    lift = np.array([g.grasp[0], g.grasp[1], g.carry_z])
    above = np.array([g.release[0], g.release[1], g.carry_z])
    tcp = [(g.grasp, g.yaw_grasp, 0.0),
           (lift, g.yaw_grasp, _vertical_time(g.carry_z - g.grasp[2]))]
    dist = float(np.linalg.norm(above[:2] - lift[:2]))
    steps = max(1, int(np.ceil(dist / CARRY_STEP)))
    for k in range(1, steps + 1):
        f = k / steps
        tcp.append((lift + (above - lift) * f, g.yaw_grasp + (g.yaw_release - g.yaw_grasp) * f,
                    carry_duration(dist, steps) / steps))
    tcp.append((g.release, g.yaw_release, _vertical_time(g.carry_z - g.release[2])))

    times = np.cumsum([dt for _, _, dt in tcp])
    q = np.array([
        hand_q_of_pose(RigidTransform(RotationMatrix.MakeZRotation(yaw), p).multiply(X_TB))
        for p, yaw, _ in tcp
    ])
    q[:, 3:] = np.unwrap(q[:, 3:], axis=0)
    trajectory = PiecewisePolynomial.CubicShapePreserving(
        times, q.T, zero_end_point_derivatives=True)
    kinematic = allow_kinematic and not _carries_others(station, held)
    return HandMotion(held, trajectory, float(times[1]), float(times[-1]), float(times[-2]),
                      kinematic, struck, pinched)


def _carries_others(station: Station, held: str) -> bool:
    """Whether another box touches the held one from above its centre (rests or leans on it)."""
    z = station.object_poses()
    for a, b in station.contact_graph():
        if held in (a, b):
            other = b if a == held else a
            if z[other].translation()[2] > z[held].translation()[2] + STACKED_DZ:
                return True
    return False


def _place(station: Station, name: str, q: np.ndarray) -> None:
    """Kinematically puts the hand at q and the welded object with it, at rest."""
    station.set_robot_positions(q)
    station.set_object_pose(name, _pose_of_hand_q(q))
    station.hold(q)


def _pose_of_hand_q(q: np.ndarray) -> RigidTransform:
    return RigidTransform(RollPitchYaw(q[5], q[4], q[3]), q[:3])


def _vertical_time(dz: float) -> float:
    return max(MIN_VERTICAL_TIME, abs(dz) / VERTICAL_SPEED)


def hand_pick_place(
    station: Station,
    action: Action,
    beliefs: dict[str, ObjectState],
    at_lift: Callable[[], object] | None = None,
    allow_kinematic: bool = True,
    twin: ArmTwin | None = None,
) -> tuple[HandMotion, object]:
    """Executes the action from the station's current time; returns (motion, at_lift()).

    `at_lift` is called once the lift has ended (the held box is up), e.g. to perceive.
    With nothing caught nothing moves, and `at_lift` is called on the unchanged scene.
    `allow_kinematic=False` simulates every carry in full physics (no kinematic carry of
    a free box, no rigid carry of a loaded one). With a `twin` the hand carries as the arm
    does: at the careful carry's points where the arm carries carefully, and an action
    where the arm would strike or pinch something (`HandMotion.struck`, `pinched`) is the
    twin arm's (InfeasibleAction where the arm cannot reach); without one, as before the
    twin existed (the published data sets).
    """
    if station.config.robot != "hand":
        raise ValueError("hand_pick_place needs a station built with StationConfig(robot='hand')")
    motion = plan_hand(station, action, beliefs, allow_kinematic, as_arm=twin is not None)
    if (motion.struck or motion.pinched) and twin is not None:
        lifted = twin.run(station, action, beliefs, at_lift)
        station.hold(station.robot_positions())
        settle_until_rest(station, HAND_SETTLE_MIN, HAND_SETTLE_MAX)
        return dc.replace(motion, by_arm=True), lifted
    if motion.held is None:
        return motion, at_lift() if at_lift else None
    station.grasp(motion.held)
    if motion.kinematic:
        riders = []
        _move_load(station, motion, riders, 0.0, motion.t_lift)
    else:
        z_before = {n: X.translation()[2] for n, X in station.object_poses().items()}
        station.follow(motion.trajectory, 0.0, motion.t_lift)
        riders = _riders(station, z_before) if allow_kinematic else None
    lifted = at_lift() if at_lift else None
    if riders is None:
        station.follow(motion.trajectory, motion.t_lift, motion.t_release)
    else:
        _move_load(station, motion, riders, motion.t_lift, motion.t_release)
        if station.clearance([motion.held, *riders]) < RELEASE_MIN_CLEARANCE:
            # Something is in the way of the release pose: come down on it in physics, as
            # the arm would, from where the carry ends.
            _move_load(station, motion, riders, motion.t_release, motion.t_above)
            station.follow(motion.trajectory, motion.t_above, motion.t_release)
    station.release()
    station.hold(station.robot_positions())
    settle_until_rest(station, HAND_SETTLE_MIN, HAND_SETTLE_MAX)
    return motion, lifted


def _riders(station: Station, z_before: dict[str, float]) -> list[str]:
    """The objects besides the held one that the lift raised by more than RIDER_DZ."""
    return [n for n, X in station.object_poses().items()
            if n != station.held and X.translation()[2] - z_before[n] >= RIDER_DZ]


def _move_load(station: Station, motion: HandMotion, riders: list, t_from: float,
               t_to: float) -> None:
    """Moves the load (held box and riders) rigidly from path time t_from to t_to, at rest.

    Used between knots where the path is at rest (the end of the lift, above the release
    point, the release): a carry no faster than the arm's keeps a rider where it sits, so
    the load moves as one rigid body, as the hand's path moves between the two knots.
    """
    q_from = motion.trajectory.value(t_from).ravel()
    q_to = motion.trajectory.value(t_to).ravel()
    X_move = _pose_of_hand_q(q_to).multiply(_pose_of_hand_q(q_from).inverse())
    poses = station.object_poses()
    for name in riders:
        station.set_object_pose(name, X_move.multiply(poses[name]))
    _place(station, station.held, q_to)
