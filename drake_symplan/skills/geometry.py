"""Where the gripper goes for an action by the believed boxes, and what the arm's own rules
refuse there: a grasp under a stack, a palm or wrist that would strike a box, a source
driven into one at the release. Shared by the arm (skills/pick_place.py), the simulated hand
(skills/hand_place.py) and the planner's checks (abstraction/refusals.py); no simulator.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from drake_symplan.actions import Action, grasp_point, release_point
from drake_symplan.boxes import HALF_EXTENTS, YAW_PERIOD, fold_yaw
from drake_symplan.datasets import ObjectState
from drake_symplan.perception.segmentation import CROP_X, CROP_Y
from drake_symplan.relations import riders, top
from drake_symplan.relations import turn as rotate
from drake_symplan.skills.carry import (
    STRIKE_DEPTH,
    careful_points,
    holds,
    landing,
    landing_height,
    release_strikes,
    unpinchable,
)
from drake_symplan.world.hand import (
    PALM_ABOVE_TCP,
    WRIST_ZONES,
    finger_strikes,
    palm_strikes,
    wrist_strikes,
)

MIN_CARRY_HEIGHT = 0.20  # m, TCP height while carrying
CARRY_CLEARANCE = 0.10  # m above the highest object top while carrying
RELEASE_CLEARANCE = 0.004  # m gap between the held box's bottom and the target's top
# m the palm may reach past a box's edge coming down (half its width): the long sets'
# own steps brush 13 mm past a tower's edge and it stands; a palm squarely under a block
# (4-5 cm in) brought a tower of three down
PALM_BRUSH = 0.02
# m between the centres of a source and a box its palm can reach: the palm's half length
# (7.5 cm), a grasp offset (7.5 cm), a long box's half diagonal (12.7 cm) and a margin
PALM_REACH = 0.31
# m between a release point and a box a source set down there can strike: a long box's
# half diagonal twice and a grasp offset
SET_DOWN_REACH = 0.33
# m: a source's centre is set down no nearer the edge of what the cameras keep (perception's
# crop): a cube centred 1 cm inside it is seen 0.8 cm off, one past it is lost
VIEW_MARGIN = 0.015
# A long block released over its target lines up with the one box beside it as high
# (span_turn): tops this near, its centre this near the block's axis, this much of it under
# the block.
SPAN_LEVEL = 0.01  # m
SPAN_OFFSET = 0.02  # m
SPAN_OVERLAP = 0.02  # m
LOWER_STEP = 0.005  # m: the heights tried, from the landing up, for a release beside the target


class InfeasibleAction(Exception):
    """The arm will not run the action from the believed scene (no IK solution for a
    waypoint, a grasp under a stack, a link that would strike a box); `obstacles`: the
    believed boxes in its way, where it knows them (with them moved it might run it); `at`:
    "grasp" or "release", the side of the action it fails at (the source's, the target's)."""

    def __init__(self, message: str, obstacles: tuple[str, ...] = (), at: str = "grasp"):
        super().__init__(message)
        self.obstacles, self.at = tuple(obstacles), at


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


def _boxes(objects: dict[str, ObjectState]) -> tuple[dict, dict]:
    """The believed boxes as world/hand.py's strike tests take them: poses, half extents."""
    return ({n: RigidTransform(RotationMatrix.MakeZRotation(o.yaw), o.position)
             for n, o in objects.items()},
            {n: np.array(HALF_EXTENTS[o.type]) for n, o in objects.items()})


def gripper_strikes(objects: dict[str, ObjectState], tcp: np.ndarray, yaw: float,
                    skip: set[str]) -> list[str]:
    """The boxes of the beliefs `objects` (but `skip`) that the palm or the open fingers,
    coming straight down to `tcp` with the finger axis at `yaw`, would strike
    (world/hand.py's palm_strikes, finger_strikes)."""
    poses, half = _boxes(objects)
    struck = palm_strikes(poses, half, tcp, yaw, skip)
    return struck + [n for n in finger_strikes(poses, half, tcp, yaw)
                     if n not in skip and n not in struck]


def _clear_turn(yaw: float, tcp: np.ndarray, objects: dict[str, ObjectState],
                skip: set[str], near: float) -> float:
    """`yaw`, or where the gripper strikes fewer boxes turned a quarter (the palm is 15 cm
    long along the finger axis, 4 cm across), the quarter turn nearer `near`."""
    turned = min(yaw + np.pi / 2, yaw - np.pi / 2, key=lambda y: abs(y - near))
    if len(gripper_strikes(objects, tcp, turned, skip)) < len(
            gripper_strikes(objects, tcp, yaw, skip)):
        return float(turned)
    return yaw


def action_geometry(action: Action, objects: dict[str, ObjectState],
                    turn: bool = True) -> ActionGeometry:
    """`turn`: a cube with nothing on it is grasped, and released, with the wrist turned
    a quarter where the gripper strikes fewer neighbours that way (a tower beside the
    source or the target; a cube held either way is the same cube)."""
    for name in (action.source, action.target):
        if name not in objects:
            raise ValueError(f"unknown object {name!r} (objects: {sorted(objects)})")
    src = objects[action.source]
    grasp, release, turn_r = nominal_points(action, objects)
    carry_z = max(MIN_CARRY_HEIGHT, max(top(o) for o in objects.values()) + CARRY_CLEARANCE)
    yaw_g = grasp_yaw(src)
    yaw_r = yaw_g + turn_r  # any quarter turn lines up faces
    plain = not riders(action.source, objects)
    if turn and src.type == "cube" and plain:
        skip = {action.source}
        yaw_g, yaw_r = (_clear_turn(yaw_g, grasp, objects, skip, yaw_g),
                        _clear_turn(yaw_r, release, objects, skip, yaw_g))
    if plain:
        release[2] = _lowered(objects, action.source, grasp, release, yaw_g, yaw_r)
    return ActionGeometry(grasp, release, float(carry_z), yaw_g, yaw_r)


def _lowered(objects: dict[str, ObjectState], source: str, grasp: np.ndarray,
             release: np.ndarray, yaw_g: float, yaw_r: float) -> float:
    """The release height of a box with nothing on it: where the target's top is not under
    it (a release beside a raised target), lowered toward what is (the table), as far as
    the palm and the open fingers strike nothing they would not strike at the target's
    top; a careful robot sets a box down rather than drop it."""
    if not holds(objects[source], grasp):  # nothing to set down
        return float(release[2])
    skip = {source}
    low = landing_height(objects, source, grasp, release, yaw_r - yaw_g, skip)
    if low >= release[2] - LOWER_STEP:
        return float(release[2])
    nominal = set(gripper_strikes(objects, release, yaw_r, skip))
    for z in np.arange(low, release[2], LOWER_STEP):
        if set(gripper_strikes(objects, np.array([*release[:2], z]), yaw_r, skip)) <= nominal:
            return float(z)
    return float(release[2])


def arm_geometry(action: Action, objects: dict[str, ObjectState],
                 turn: bool = True) -> tuple[ActionGeometry, str]:
    """Where the arm's TCP goes for `action` by the believed `objects`, and how it carries:
    "plain" (nothing rides on the source: the action's points), "careful" (the careful
    carry's points, skills/carry.py) or "pinched" (a load with no point clear of it, which
    the fingers close on together with the source). `turn`: as action_geometry."""
    g = action_geometry(action, objects, turn)
    if not riders(action.source, objects):
        return g, "plain"
    over = unpinchable(action, objects)
    if over:
        raise InfeasibleAction(f"the grasp on {action.source} is under a stack of "
                               f"{len(over)} ({', '.join(over)})")
    grasp, release, careful = careful_points(action, objects, g.grasp, g.release,
                                             g.yaw_release - g.yaw_grasp)
    return dc.replace(g, grasp=grasp, release=release), "careful" if careful else "pinched"


def palm_reach(source: str, objects: dict[str, ObjectState]) -> list[str]:
    """The boxes near `source` that rise past the palm's underside at its centre: the
    only ones the palm can strike coming down to a grasp on it (its riders among them)."""
    src = objects[source]
    floor = src.position[2] + PALM_ABOVE_TCP
    return [n for n, o in objects.items() if n != source
            and o.position[2] + HALF_EXTENTS[o.type][2] > floor
            and np.linalg.norm(o.position[:2] - src.position[:2]) < PALM_REACH]


def grasp_struck(action: Action, objects: dict[str, ObjectState]) -> list[str]:
    """The boxes the palm or the wrist would strike coming down to `action`'s grasp by the
    arm's geometry (arm_geometry, as refuse_strikes tests the palm;
    skills/arm_clearance.py tests the links on the arm's own motion); [] at once where
    palm_reach finds none."""
    if not palm_reach(action.source, objects):
        return []
    g, _ = arm_geometry(action, objects)
    load = {action.source, *riders(action.source, objects)}
    poses, half = _boxes({n: o for n, o in objects.items() if n not in load})
    struck = palm_strikes(poses, half, g.grasp, g.yaw_grasp, margin=-PALM_BRUSH)
    return struck + [n for n in _wrist_strikes(poses, half, g.grasp) if n not in struck]


def _wrist_strikes(poses: dict, half: dict, tcp: np.ndarray) -> list[str]:
    """The boxes (`poses`, `half` extents: _boxes) the wrist would strike coming down to
    the TCP point `tcp`: about the tool axis, wrist_3's cylinder, at every turn of the
    gripper the same (a tower of three beside a cube on the table); higher up, wrist_1 and
    wrist_2, which stand out towards the robot's base (at the world's origin), on that
    side only. The links' own radii, no margin: the arm's test passes a tower of three 2 cm
    beside."""
    inward = {n: X for n, X in poses.items()
              if float((X.translation()[:2] - tcp[:2]) @ -tcp[:2]) > 0.0}
    struck = wrist_strikes(poses, half, tcp, WRIST_ZONES[:1], margin=0.0)
    return struck + [n for n in wrist_strikes(inward, half, tcp, WRIST_ZONES[1:], margin=0.0)
                     if n not in struck]


def _palm_strikes(objects: dict[str, ObjectState], g: ActionGeometry,
                  load: set[str]) -> list[str]:
    """The boxes (not in the `load`) the palm coming down to `g`'s grasp reaches more than
    PALM_BRUSH into."""
    return palm_strikes(*_boxes(objects), g.grasp, g.yaw_grasp, load, margin=-PALM_BRUSH)


def nominal_points(action: Action, objects: dict[str, ObjectState], span: bool = True
                   ) -> tuple[np.ndarray, np.ndarray, float]:
    """`action`'s TCP points by the believed `objects` (grasp, release over the target's
    top) and the gripper's turn between them, before the quarter turn clear of neighbours
    and a careful carry's shifts (action_geometry, arm_geometry); without `span`, the
    turn to the target's faces even where a block would be lined up (span_turn: the
    search's hot path asks this where the turn changes nothing it reads)."""
    src, tgt = objects[action.source], objects[action.target]
    release = release_point(tgt.position, action)
    release[2] = top(tgt) + HALF_EXTENTS[src.type][2] + RELEASE_CLEARANCE
    grasp = grasp_point(src.position, action)
    turn = fold_yaw(tgt.yaw - src.yaw, YAW_PERIOD["cube"])
    lined_up = span_turn(action, objects, grasp, release, turn) if span else None
    return grasp, release, turn if lined_up is None else lined_up


def span_turn(action: Action, objects: dict[str, ObjectState], grasp: np.ndarray,
              release: np.ndarray, turn: float) -> float | None:
    """The gripper's turn that lays a long block, with nothing on it, across its target
    and the one box beside the target whose top is as high (within SPAN_LEVEL), where the
    block turned to its target's faces (`turn`) would come down partly over that box
    without bearing on it, and lined up with the two it bears on both (`over`); else
    None. A person laying a plank across two posts lines it up with them: turned to its
    target's faces, a block set on a cube knocked askew lay 36 degrees across its
    supports and missed one."""
    src, tgt = objects[action.source], objects[action.target]
    if src.type != "long":
        return None
    # the cheap tests first: the search asks this of every move of a block
    reach, xy = HALF_EXTENTS["long"][1], tgt.position[:2]
    boxes = list(objects.values())
    far = np.hypot(*(np.array([o.position[:2] for o in boxes]) - xy).T) > reach
    height = top(tgt)
    beside = [o for o, f in zip(boxes, far, strict=True) if not f
              and o.name not in (action.source, action.target)
              and abs(top(o) - height) <= SPAN_LEVEL]
    if len(beside) != 1:
        return None
    support = beside[0]
    grazes = HALF_EXTENTS["long"][0] + HALF_EXTENTS[support.type][0]
    if over(src, grasp, release, turn, support) \
            or not over(src, grasp, release, turn, support, grazes) \
            or riders(action.source, objects):
        return None
    d = support.position[:2] - tgt.position[:2]
    lined_up = fold_yaw(np.arctan2(-d[0], d[1]) - src.yaw, YAW_PERIOD["long"])
    return lined_up if over(src, grasp, release, lined_up, support) else None


def over(src: ObjectState, grasp: np.ndarray, release: np.ndarray, turn: float,
         support: ObjectState, offset: float = SPAN_OFFSET) -> bool:
    """Does the block `src`, held at `grasp` and released at `release` turned by `turn`,
    come down over `support`: its centre within `offset` of the block's axis, and
    SPAN_OVERLAP of it or more under the block's end?"""
    # the support's centre in the block's frame, whose length lies along its local y
    across, along = np.abs(rotate(support.position[:2] - landing(src, grasp, release, turn),
                                  -(src.yaw + turn)))
    reach = HALF_EXTENTS["long"][1] + HALF_EXTENTS[support.type][1] - SPAN_OVERLAP
    return along <= reach and across <= offset


def grasp_refused(action: Action, objects: dict[str, ObjectState]) -> bool:
    """Does the arm refuse `action`'s grasp by its own rules on the believed `objects`:
    under a stack it will not lift (carry.unpinchable), or where its palm or wrist would
    strike a box (grasp_struck)? What the planner and the agent's repositioning read."""
    return bool(unpinchable(action, objects) or grasp_struck(action, objects))


def set_down_at(action: Action, objects: dict[str, ObjectState]) -> np.ndarray:
    """Where `action` sets its source down by its nominal points: its centre, released
    over the target's top (the planner asks whether it would rest there). Held at its
    centre, a box lands centred under the release point however it turns."""
    grasp, release, turn = nominal_points(action, objects, span=action.grasp != "center")
    src = objects[action.source]
    return np.array([*landing(src, grasp, release, turn),
                     release[2] - (grasp[2] - src.position[2])])


def set_down_unseen(action: Action, objects: dict[str, ObjectState]) -> bool:
    """Would `action` set its source down where the cameras lose it: its centre within
    VIEW_MARGIN of the edge of the workspace perception keeps (perception/segmentation.py's
    crop) or past it? The agent would lose it from view, and every name after it."""
    x, y = set_down_at(action, objects)[:2]
    return not (CROP_X[0] + VIEW_MARGIN < x < CROP_X[1] - VIEW_MARGIN
                and CROP_Y[0] + VIEW_MARGIN < y < CROP_Y[1] - VIEW_MARGIN)


def release_refused(action: Action, objects: dict[str, ObjectState]) -> bool:
    """Is `action`'s release refused on the believed `objects`: its source set down where
    the cameras lose it (set_down_unseen, the agent's rule) or driven into a box
    (set_down_struck, the arm's)? What the planner and the offset chooser read."""
    return set_down_unseen(action, objects) or bool(set_down_struck(action, objects))


def set_down_struck(action: Action, objects: dict[str, ObjectState]) -> list[str]:
    """The boxes the source would be driven into at `action`'s release by its nominal
    points (refuse_strikes tests the arm's own); [] at once where no box near the
    release rises past the source's bottom there. A source with riders by the careful
    carry's points: it lowers a load beside the target, riders and all."""
    if riders(action.source, objects):
        try:
            g, _ = arm_geometry(action, objects)
        except InfeasibleAction:
            return []  # the arm refuses its grasp (grasp_refused)
        return release_strikes(action, objects, g.grasp, g.release,
                               g.yaw_release - g.yaw_grasp)
    grasp, release, _ = nominal_points(action, objects, span=False)
    bottom = release[2] - HALF_EXTENTS[objects[action.source].type][2]
    if not any(n not in (action.source, action.target)
               and o.position[2] + HALF_EXTENTS[o.type][2] > bottom + STRIKE_DEPTH
               and np.linalg.norm(o.position[:2] - release[:2]) < SET_DOWN_REACH
               for n, o in objects.items()):
        return []
    return release_strikes(action, objects, *nominal_points(action, objects))


def refuse_strikes(action: Action, objects: dict[str, ObjectState], g: ActionGeometry,
                    load: set[str]) -> None:
    """InfeasibleAction where the palm coming down to the grasp would strike a box not in
    the `load` (a block bridging over the source, a tower beside it), or where the source
    would be driven into one at the release (skills/carry.py's release_strikes): the arm
    knocks such boxes over. The palm may brush PALM_BRUSH past a box's edge; an open
    finger landing on a cube's edge slides it (the quarter turn, action_geometry, avoids
    what it can)."""
    struck = _palm_strikes(objects, g, load)
    if struck:
        raise InfeasibleAction(f"the palm would strike {', '.join(struck)} coming down "
                               f"to {action.source}", tuple(struck), "grasp")
    struck = release_strikes(action, objects, g.grasp, g.release,
                             g.yaw_release - g.yaw_grasp)
    if struck:
        raise InfeasibleAction(f"{action.source} would be driven into {', '.join(struck)} "
                               f"set down on {action.target}", tuple(struck), "release")
