"""What the arm's wrist and forearm would strike on the way down to a grasp or a release:
their collision cylinders, placed by the IK plant's forward kinematics along the planned
waypoints, against the believed boxes.

A careful robot checks its motion against the scene it perceives before it moves: the
fingers and the palm come straight down where the action says, but the UR10's wrist sticks
out 16 cm sideways above them and sweeps the top of a tall tower beside the grasp
(docs/world.md). The arm refuses such a motion (InfeasibleAction) and the planner goes
another way; the hand, whose own wrist test is coarser (world/hand.py's `wrist_strikes`),
hands such actions to the arm twin, which refuses them the same way.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.datasets import ObjectState
from drake_symplan.skills.ik import ArmIK
from drake_symplan.world.station import FINGER_OPEN

# The collision cylinders of models/ur10/ur10.urdf: link -> (centre and axis in the link
# frame, half length, radius), m.
LINK_CYLINDERS = {
    "forearm_link": ((0.0, 0.0, 0.286), (0.0, 0.0, 1.0), 0.286, 0.05),
    "wrist_1_link": ((0.0, 0.06, 0.0), (0.0, 1.0, 0.0), 0.06, 0.045),
    "wrist_2_link": ((0.0, 0.0, 0.06), (0.0, 0.0, 1.0), 0.06, 0.045),
    "wrist_3_link": ((0.0, 0.05, 0.0), (0.0, 1.0, 0.0), 0.04, 0.045),
}
CLEARANCE = 0.0  # m: a link touching a believed box (the oracle replays pass 3 mm beside towers)
SPACING = 0.01  # m between the points sampled on a cylinder's surface
SEGMENT_SAMPLES = 6  # configurations checked between two waypoints (joint-space straight line)


def cylinder_points(centre, axis, half: float, radius: float) -> np.ndarray:
    """Points (3 x N) on a cylinder's surface, SPACING apart: its side and its two ends."""
    axis = np.asarray(axis, float)
    u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    points = []
    for r in np.arange(radius, 0.0, -SPACING):  # the side (r = radius) and rings on the ends
        angles = np.linspace(0, 2 * np.pi, max(6, int(np.ceil(2 * np.pi * r / SPACING))),
                             endpoint=False)
        ring = np.outer(u, np.cos(angles) * r) + np.outer(v, np.sin(angles) * r)
        heights = (np.linspace(-half, half, int(np.ceil(2 * half / SPACING)) + 1)
                   if r == radius else np.array([-half, half]))
        points += [ring + axis[:, None] * h for h in heights]
    points.append(np.outer(axis, [-half, half]))
    return np.asarray(centre, float)[:, None] + np.hstack(points)


# Per link, the points on its cylinder (link frame, 3 x N): fixed, so made once.
LINK_POINTS = {link: cylinder_points(*cylinder) for link, cylinder in LINK_CYLINDERS.items()}


def _box_frames(objects: dict[str, ObjectState], skip: Iterable[str]):
    """(name, world-to-box transform, half extents) of the believed boxes but `skip`."""
    skip = set(skip)
    return [(n, RigidTransform(RotationMatrix.MakeZRotation(o.yaw), o.position).inverse(),
             np.array(HALF_EXTENTS[o.type])) for n, o in objects.items() if n not in skip]


def link_strikes(ik: ArmIK, waypoints: list[np.ndarray], objects: dict[str, ObjectState],
                 skip: Iterable[str] = ()) -> tuple[str, str] | None:
    """The first (link, box) where a link's cylinder comes within CLEARANCE of a believed
    box (but `skip`) between consecutive arm `waypoints` (6-vectors); None: clear."""
    boxes = _box_frames(objects, skip)
    if not boxes:
        return None
    links = {link: (ik.plant.GetBodyByName(link), points) for link, points in LINK_POINTS.items()}
    for q_a, q_b in zip(waypoints[:-1], waypoints[1:], strict=True):
        for f in np.linspace(0.0, 1.0, SEGMENT_SAMPLES):
            q = q_a + (q_b - q_a) * f
            ik.plant.SetPositions(ik.context, np.concatenate([q, [FINGER_OPEN] * 2]))
            for link, (body, points) in links.items():
                world = body.EvalPoseInWorld(ik.context).multiply(points)
                for name, X_BW, half in boxes:
                    inside = np.abs(X_BW.multiply(world)) <= half[:, None] + CLEARANCE
                    if inside.all(axis=0).any():
                        return link, name
    return None
