"""A collision-free simulated hand: the fast stand-in for the UR10 and its gripper.

The hand is an invisible body without geometry, moved by six PD-actuated joints
(prismatic x, y, z, then revolute yaw, pitch, roll: Drake's RollPitchYaw order), with
gravity off. Every pool body has one weld constraint to the hand (identity frames),
inactive unless that body is held. To grasp, the simulator puts the hand exactly at the
held body's pose and activates its weld, so a grasp never makes the body jump; the hand
then tracks a joint trajectory and the held body, with whatever rests on it, comes along
through the physics (contact and friction). Releasing deactivates the weld.

Which body a grasp catches is the simulator's business, decided on ground truth as the
arm's fingers decide it physically: the box whose extent, inflated by the fingers' slack,
contains the grasp point (`GRASP_SLACK`). A grasp beside a cube catches nothing.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.tree import (
    PdControllerGains,
    PrismaticJoint,
    RevoluteJoint,
    SpatialInertia,
)
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_symplan.actions import GRASP_SLACK

# Joint order of the hand's configuration q = [x, y, z, yaw, pitch, roll].
HAND_JOINTS = ("hand_x", "hand_y", "hand_z", "hand_yaw", "hand_pitch", "hand_roll")
HAND_KP = [2e4, 2e4, 2e4, 300.0, 300.0, 300.0]
HAND_KD = [600.0, 600.0, 600.0, 3.0, 3.0, 3.0]
HAND_PARK = np.array([0.0, 0.0, 1.5, 0.0, 0.0, 0.0])



def hand_q_of_pose(X: RigidTransform) -> np.ndarray:
    """Hand joint positions that put the hand frame at pose X."""
    rpy = RollPitchYaw(X.rotation()).vector()
    return np.concatenate([X.translation(), [rpy[2], rpy[1], rpy[0]]])


def grasp_catches(
    poses: dict[str, RigidTransform],
    half_extents: dict[str, np.ndarray],
    point: np.ndarray,
    slack: np.ndarray = GRASP_SLACK,
) -> str | None:
    """The name of the box the fingers close on at `point`, or None.

    A box is caught if `point`, in the box's frame, lies within its half extents inflated
    by `slack`; among several, the one whose centre is nearest the point.
    """
    best, best_d = None, np.inf
    for name, X in poses.items():
        local = np.abs(X.inverse().multiply(np.asarray(point, float)))
        h = np.asarray(half_extents[name], float)
        if np.all(local <= h + slack):
            d = float(np.linalg.norm(X.translation() - point))
            if d < best_d:
                best, best_d = name, d
    return best


# The arm's wrist above its gripper (models/ur10/ur10.urdf), which the hand does not have:
# wrist_3_link's cylinder about the tool axis (4.5 cm radius) from 8.7 cm above the TCP,
# and at the wrist_3 joint, 17.7 cm above the TCP, wrist_2_link's cylinder sticking out
# sideways up to 16.5 cm from the axis (towards the robot's base; any side, to be safe).
# The palm below them, over the load, is left out: a rider it presses is pinched and kept
# on both (beside the load: palm_strikes).
WRIST_ZONES = (  # (height above the TCP from which, radius about the tool axis), m
    (0.087, 0.045),
    (0.132, 0.165),
)
WRIST_MARGIN = 0.01  # m added to each zone's radius


def _top(X: RigidTransform, half: np.ndarray) -> float:
    """The highest point of a box of half extents `half` at pose X (tilted or not)."""
    return float(X.translation()[2] + np.abs(X.rotation().matrix()[2]) @ half)


def wrist_strikes(
    poses: dict[str, RigidTransform],
    half_extents: dict[str, np.ndarray],
    tcp: np.ndarray,
    zones: tuple[tuple[float, float], ...] = WRIST_ZONES,
    margin: float = WRIST_MARGIN,
) -> list[str]:
    """The boxes that the arm's wrist, coming straight down to the TCP point `tcp`, would
    strike: those reaching above a zone's height within its radius (grown by `margin`) of
    the tool axis (`zones`: WRIST_ZONES, or some of them)."""
    struck = []
    for name, X in poses.items():
        h = np.asarray(half_extents[name], float)
        local = X.inverse().multiply(np.array([tcp[0], tcp[1], X.translation()[2]]))
        reach = float(np.linalg.norm(np.maximum(np.abs(local[:2]) - h[:2], 0.0)))
        top = _top(X, h)
        if any(top > tcp[2] + above and reach < radius + margin
               for above, radius in zones):
            struck.append(name)
    return struck


# The arm's open fingers (models/ur10/ur10.urdf): 1.5 x 2 cm pads whose inner faces stand
# 8.5 cm apart across the finger axis, reaching from 1.5 cm below the TCP upwards.
FINGER_CENTRE = 0.05  # m from the TCP along the finger axis
FINGER_HALF = np.array([0.0075, 0.01])  # m: half thickness (finger axis), half width
FINGER_BELOW_TCP = 0.015  # m
FINGER_MARGIN = 0.003  # m


def finger_strikes(
    poses: dict[str, RigidTransform],
    half_extents: dict[str, np.ndarray],
    tcp: np.ndarray,
    yaw: float,
    skip: str | None = None,
) -> list[str]:
    """The boxes (but `skip`, the one the fingers close on) that the arm's open fingers,
    coming straight down to the TCP point `tcp` with the finger axis at `yaw`, would land
    on or push: those reaching above the pads' lowest point under either pad."""
    axis, R_f = _finger_frame(yaw)
    pads = [np.asarray(tcp[:2], float) + side * FINGER_CENTRE * axis for side in (-1.0, 1.0)]
    return _reaching(poses, half_extents, tcp[2] - FINGER_BELOW_TCP, pads, R_f,
                     FINGER_HALF + FINGER_MARGIN, () if skip is None else (skip,))


def _finger_frame(yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """The finger axis at `yaw` in world xy, and the finger frame's axes as rows."""
    axis = np.array([np.cos(yaw), np.sin(yaw)])
    return axis, np.array([axis, [-axis[1], axis[0]]])


def _reaching(poses: dict[str, RigidTransform], half_extents: dict[str, np.ndarray],
              floor: float, centres, R: np.ndarray, half: np.ndarray, skip) -> list[str]:
    """The boxes (but those in `skip`) reaching above the height `floor` whose footprint
    overlaps one of the rectangles at `centres` (axes the rows of R, half extents `half`)."""
    struck = []
    for name, X in poses.items():
        h = np.asarray(half_extents[name], float)
        if name in skip or _top(X, h) <= floor:
            continue
        R_b = X.rotation().matrix()[:2, :2].T  # rows: the box's x, y axes in world xy
        if any(_rectangles_overlap(c, R, half, X.translation()[:2], R_b, h[:2])
               for c in centres):
            struck.append(name)
    return struck


# The arm's palm (models/ur10/ur10.urdf): a 15 x 4 cm box along the finger axis whose
# underside is 4.5 cm above the TCP. Coming down beside a stack taller than that, at the
# grasp or at the release, it strikes the stack's top.
PALM_HALF = np.array([0.075, 0.02])  # m: half length (finger axis), half width
PALM_ABOVE_TCP = 0.045  # m
PALM_MARGIN = 0.005  # m


def palm_strikes(poses: dict[str, RigidTransform], half_extents: dict[str, np.ndarray],
                 tcp: np.ndarray, yaw: float, skip=(), margin: float = PALM_MARGIN) -> list[str]:
    """The boxes (but those in `skip`) that the arm's palm, coming straight down to the
    TCP point `tcp` with the finger axis at `yaw`, would strike: those reaching above its
    underside under its footprint grown by `margin`."""
    return _reaching(poses, half_extents, tcp[2] + PALM_ABOVE_TCP, [np.asarray(tcp[:2], float)],
                     _finger_frame(yaw)[1], PALM_HALF + margin, skip)


def _rectangles_overlap(c1, R1, h1, c2, R2, h2) -> bool:
    """Separating-axis test of two rectangles (centre, rows = unit axes, half extents)."""
    d = np.asarray(c2, float) - np.asarray(c1, float)
    for u in (*R1, *R2):
        r1 = np.abs(R1 @ u) @ h1
        r2 = np.abs(R2 @ u) @ h2
        if abs(d @ u) > r1 + r2:
            return False
    return True


class Hand:
    """Handles to the hand's model instance, joints, weld constraints and command source."""

    def __init__(self, plant, bodies: list):
        self.plant = plant
        self.instance = plant.AddModelInstance("hand")
        links = []
        for i in range(len(HAND_JOINTS)):
            links.append(plant.AddRigidBody(
                f"hand_link{i}", self.instance,
                SpatialInertia.SolidBoxWithMass(0.5, 0.05, 0.05, 0.05)))
        self.body = links[-1]
        parent = plant.world_frame()
        axes = [(PrismaticJoint, [1, 0, 0]), (PrismaticJoint, [0, 1, 0]),
                (PrismaticJoint, [0, 0, 1]), (RevoluteJoint, [0, 0, 1]),
                (RevoluteJoint, [0, 1, 0]), (RevoluteJoint, [1, 0, 0])]
        self.joints = []
        for name, (kind, axis), link, kp, kd in zip(
                HAND_JOINTS, axes, links, HAND_KP, HAND_KD, strict=True):
            joint = plant.AddJoint(kind(name, parent, link.body_frame(), axis))
            plant.AddJointActuator(name + "_motor", joint).set_controller_gains(
                PdControllerGains(p=kp, d=kd))
            self.joints.append(joint)
            parent = link.body_frame()
        plant.set_gravity_enabled(self.instance, False)
        self.welds = {
            b.index(): plant.AddWeldConstraint(self.body, RigidTransform(), b, RigidTransform())
            for b in bodies
        }
        self.held = None  # the pool body held now
        self.command_source = None

    def add_command_source(self, builder) -> TrajectorySource:
        """After Finalize: the desired-state source driving the hand's PD actuators."""
        self.command_source = builder.AddSystem(TrajectorySource(hold(HAND_PARK), 1))
        builder.Connect(self.command_source.get_output_port(),
                        self.plant.get_desired_state_input_port(self.instance))
        return self.command_source

    def positions(self, plant_context) -> np.ndarray:
        return np.array([j.GetOnePosition(plant_context) for j in self.joints])

    def set_positions(self, plant_context, q: np.ndarray) -> None:
        for j, qj in zip(self.joints, q, strict=True):
            if isinstance(j, PrismaticJoint):
                j.set_translation(plant_context, float(qj))
                j.set_translation_rate(plant_context, 0.0)
            else:
                j.set_angle(plant_context, float(qj))
                j.set_angular_rate(plant_context, 0.0)

    def reset(self, plant_context) -> None:
        """Nothing held, hand parked above the table, holding still."""
        for cid in self.welds.values():
            self.plant.SetConstraintActiveStatus(plant_context, cid, False)
        self.held = None
        self.set_positions(plant_context, HAND_PARK)
        self.command_source.UpdateTrajectory(hold(HAND_PARK))

    def grasp(self, plant_context, body) -> np.ndarray:
        """Puts the hand at `body`'s pose and welds them; returns that hand q."""
        q = hand_q_of_pose(self.plant.EvalBodyPoseInWorld(plant_context, body))
        self.set_positions(plant_context, q)
        self.plant.SetConstraintActiveStatus(plant_context, self.welds[body.index()], True)
        self.held = body
        return q

    def release(self, plant_context) -> None:
        if self.held is not None:
            self.plant.SetConstraintActiveStatus(
                plant_context, self.welds[self.held.index()], False)
        self.held = None


def hold(q: np.ndarray) -> PiecewisePolynomial:
    q = np.asarray(q, float)
    return PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.column_stack([q, q]))


def AddHand(plant, bodies: list) -> Hand:
    """Adds the hand and one (inactive) weld constraint per body; call before Finalize."""
    return Hand(plant, bodies)
