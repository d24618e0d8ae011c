"""The careful carry: how the arm picks a box that, by the caller's beliefs, has others on it.

The gripper's palm sits 4.5 cm above the TCP (models/ur10/ur10.urdf) and spans the
finger gap, so a box resting over the grasp point is pressed by the palm and pinched by
the upper part of the pads, and the source below slips out of the fingers (the arm kept 26 of 45 riders on the
carry suite, tools/bench_carry.py, the hand 42). When the beliefs say something rests on
the source:

- the fingers close at the point of the source's top that is clear of the riders (the
  palm's footprint with a margin) nearest the load's centre of mass, and the release
  point moves with it, so the source lands where the action puts it (`careful_points`;
  a source with no clear point, a tower on a cube, is pinched with its rider as before);
- a grasp that misses the source (it catches nothing) comes down only as low as keeps
  the fingers above the riders;
- a load released where nothing the beliefs hold lies under the source (beside the
  target) is lowered to just above what does lie there (the table), not dropped;
- a load whose centre of mass would come to rest beyond the one box it lands on, or
  nearer its edge than STABLE_MARGIN (a block released with its centre past the target's
  end, one with a cube at its end released centred on a cube), is released nearer, with
  its centre of mass STABLE_MARGIN inside that box's top: a careful robot does not let go
  of a stack where it topples;
- the fingers squeeze harder (CAREFUL_FINGER), the carry accelerates more gently
  (CAREFUL_TCP_ACCELERATION, skills/timing.py) and the fingers let go at once
  (CAREFUL_OPEN_SECONDS).

Only the caller's beliefs are read here (object states), never the simulator.
"""

from __future__ import annotations

import numpy as np

from drake_symplan.actions import GRASP_SLACK, Action, grasp_point
from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.datasets import ObjectState
from drake_symplan.relations import FOOTPRINT_TOL, REST_TOL, covers, local_xy, riders, turn

PAD_BELOW_TCP = 0.015  # m: the finger pads reach this far below the TCP
PALM_HALF_WIDTH = 0.02  # m: the palm's half extent across the finger axis
PALM_MARGIN = 0.008  # m between the palm's footprint and a rider's
PAD_INSET = 0.015  # m: the pads' centre stays this far inside the source's end
MASS = {"cube": 0.1, "long": 0.4}  # kg, models/objects
RELEASE_GAP = 0.004  # m between the released source's bottom and what lies under it
STRIKE_DEPTH = 0.01  # m a box's top may reach above a released source's bottom (beliefs)
STABLE_MARGIN = 0.015  # m: a released load's centre of mass lies this far inside its support
CAREFUL_FINGER = -0.02  # finger command while carrying a load: 37.5 N on a 5 cm box
CAREFUL_OPEN_SECONDS = 0.05  # s: the fingers let go of a load at once (a tipping load)
CAREFUL_TCP_ACCELERATION = 2.0  # m/s^2 at the TCP while lifting, carrying, lowering a load
# Boxes stacked over the grasp point that the fingers pinch with the source: the palm
# presses one box down onto it (the carry suite: tools/bench_carry.py); over two or more
# it stops on the stack's top, the fingers close on the boxes above and the stack falls.
MAX_PINCHED = 1


def stacked_over(source: str, objects: dict[str, ObjectState], point: np.ndarray) -> list[str]:
    """The riders of `source` whose footprint holds the xy `point` (the grasp's): the
    stack the palm comes down on there."""
    return [n for n in riders(source, objects) if covers(objects[n], point, FOOTPRINT_TOL)]


def _half_along_y(o: ObjectState, yaw: float) -> float:
    """Half extent of `o`'s footprint along the axis at `yaw` turned by 90 degrees (local y)."""
    hx, hy, _ = HALF_EXTENTS[o.type]
    d = o.yaw - yaw
    return float(abs(np.cos(d)) * hy + abs(np.sin(d)) * hx)


def _clear_point(src: ObjectState, load: list[ObjectState], want: float) -> float | None:
    """The point along the source's long axis (local y), with the pads on it and the palm
    clear of every box in `load`, nearest `want`; None if there is none."""
    limit = HALF_EXTENTS[src.type][1] - PAD_INSET
    candidates = np.linspace(-limit, limit, int(round(2 * limit / 0.0025)) + 1)
    clear = np.ones(len(candidates), bool)
    for o in load:
        y = local_xy(src, o.position)[1]
        clear &= np.abs(candidates - y) >= _half_along_y(o, src.yaw) + PALM_HALF_WIDTH + PALM_MARGIN
    if not clear.any():
        return None
    ok = candidates[clear]
    return float(ok[np.argmin(np.abs(ok - want) + 1e-9 * ok)])


def _tops_under(objects: dict[str, ObjectState], skip: set[str], centre: np.ndarray,
                yaw: float, half: tuple) -> dict[str, float]:
    """The believed boxes (not in `skip`) under a footprint (centre xy, yaw, half
    extents), by the height of their top: those whose footprint holds one of a 5 x 5 grid
    of the footprint's points."""
    u = np.linspace(-1.0, 1.0, 5)
    g = np.array([(a * half[0], b * half[1]) for a in u for b in u])
    c, s = np.cos(yaw), np.sin(yaw)
    points = np.stack([centre[0] + (c * g[:, 0] - s * g[:, 1]),
                       centre[1] + (s * g[:, 0] + c * g[:, 1])], axis=1)
    reach = float(np.hypot(half[0], half[1]))
    out = {}
    for name, o in objects.items():
        if name in skip:
            continue
        hx, hy, hz = HALF_EXTENTS[o.type]
        if np.hypot(*(centre[:2] - o.position[:2])) > reach + np.hypot(hx, hy) + 1e-6:
            continue  # no point of the footprint can lie over it
        v = points - o.position[:2]
        co, so = np.cos(-o.yaw), np.sin(-o.yaw)  # the points in the box's frame, as _local
        if np.any((np.abs(co * v[:, 0] - so * v[:, 1]) <= hx)
                  & (np.abs(so * v[:, 0] + co * v[:, 1]) <= hy)):
            out[name] = float(o.position[2] + hz)
    return out


def _supports(objects: dict[str, ObjectState], skip: set[str], centre: np.ndarray,
              yaw: float, half: tuple) -> tuple[float, list[str]]:
    """The highest believed top under a footprint (centre xy, yaw, half extents) and the
    boxes (not in `skip`) whose top that is, or the table's (0, []) where none lies under it."""
    tops = _tops_under(objects, skip, centre, yaw, half)
    if not tops:
        return 0.0, []
    top = max(tops.values())
    return top, [n for n, t in tops.items() if t >= top - REST_TOL]


def holds(src: ObjectState, grasp: np.ndarray) -> bool:
    """Do the fingers, closing at the TCP point `grasp`, hold the source (by the beliefs:
    the point within its footprint, give or take GRASP_SLACK)?"""
    return covers(src, grasp, GRASP_SLACK[:2])


def unpinchable(action: Action, objects: dict[str, ObjectState]) -> list[str]:
    """The stack over `action`'s grasp that the arm will not lift (the boxes, bottom up), or
    [] where it will: more than MAX_PINCHED boxes over the grasp point of a source with no
    point clear of its load (careful_points), which the fingers would pinch together with
    it. The arm refuses such a grasp (skills/pick_place.py) and the planner plans none."""
    src = objects[action.source]
    load = [objects[n] for n in riders(action.source, objects)]
    grasp = grasp_point(src.position, action)
    if not load or not holds(src, grasp) or _clear_point(src, load, 0.0) is not None:
        return []
    over = stacked_over(action.source, objects, grasp)
    return over if len(over) > MAX_PINCHED else []


def landing(src: ObjectState, grasp: np.ndarray, release: np.ndarray,
            yaw_turn: float) -> np.ndarray:
    """Where (xy) the centre of `src`, held at the TCP point `grasp` and released at
    `release` (the gripper turned by `yaw_turn` between them), comes down."""
    return release[:2] + turn(src.position[:2] - grasp[:2], yaw_turn)


def landing_height(objects: dict[str, ObjectState], source: str, grasp: np.ndarray,
                   release: np.ndarray, yaw_turn: float, skip: set[str]) -> float:
    """The TCP height at which the source, held at `grasp` and released at `release`
    (xy; the gripper turned by `yaw_turn` between them), rests RELEASE_GAP above the
    highest believed top (not in `skip`) under where it lands, the table's where none."""
    src = objects[source]
    under, _ = _supports(objects, skip, landing(src, grasp, release, yaw_turn),
                         src.yaw + yaw_turn, HALF_EXTENTS[src.type])
    return under + HALF_EXTENTS[src.type][2] + RELEASE_GAP + (grasp[2] - src.position[2])


def release_strikes(action: Action, objects: dict[str, ObjectState], grasp: np.ndarray,
                    release: np.ndarray, yaw_turn: float) -> list[str]:
    """The boxes (not the source's load) that the source or a rider on it, held at the TCP
    point `grasp` and lowered to `release` (the gripper turned by `yaw_turn` between them),
    would be driven into: under where each lands, their top more than STRIKE_DEPTH above
    its bottom (a long block set on a cube beside a taller tower; a cube carrying a block,
    set down beside a tower of four that the block's end came down into, traced with
    eight boxes). The arm refuses such a release."""
    src = objects[action.source]
    if not holds(src, grasp):  # nothing is carried
        return []
    load = riders(action.source, objects)
    skip = {action.source, *load}
    drop = release[2] - grasp[2]  # how far the load comes down, as its source does
    centre = landing(src, grasp, release, yaw_turn)
    struck = []
    for box in [src] + [objects[n] for n in load]:
        bottom = box.position[2] + drop - HALF_EXTENTS[box.type][2]
        at = centre + turn(box.position[:2] - src.position[:2], yaw_turn)
        tops = _tops_under(objects, skip, at, box.yaw + yaw_turn, HALF_EXTENTS[box.type])
        struck += [n for n, top in tops.items() if top > bottom + STRIKE_DEPTH
                   and n not in struck]
    return struck


def _onto_support(support: ObjectState, com: np.ndarray) -> np.ndarray:
    """The xy shift that brings a load's centre of mass `com` (world xy), where it lies
    beyond the top of the one box it is released on or within STABLE_MARGIN of its edge,
    STABLE_MARGIN inside it (zero where it lies that far inside already)."""
    local = local_xy(support, com)
    half = np.array(HALF_EXTENTS[support.type][:2])
    limit = np.maximum(half - STABLE_MARGIN, 0.0)
    if np.all(np.abs(local) <= limit):
        return np.zeros(2)
    return turn(np.clip(local, -limit, limit) - local, support.yaw)


def careful_points(action: Action, objects: dict[str, ObjectState], grasp: np.ndarray,
                   release: np.ndarray, yaw_turn: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """The careful carry's TCP (grasp, release) points for the nominal ones of `action`
    (`yaw_turn`: how far the gripper turns from grasp to release), and whether to carry
    carefully (grip, accelerations, release): not where no point of the source is clear
    of its riders (a tower on a cube), which the fingers pinch together as in an ordinary
    pick (that holds the stack; only a release beside the target is lowered)."""
    src = objects[action.source]
    load = [objects[n] for n in riders(action.source, objects)]
    half = np.array(HALF_EXTENTS[src.type])
    if not holds(src, grasp):  # the grasp catches nothing
        top = max(o.position[2] + HALF_EXTENTS[o.type][2] for o in load)
        lifted = grasp.copy()
        lifted[2] = max(grasp[2], top + PALM_MARGIN + PAD_BELOW_TCP)
        return lifted, release, True
    masses = np.array([MASS[o.type] for o in [src, *load]])
    com = masses @ np.array([local_xy(src, o.position) for o in [src, *load]]) / masses.sum()
    y = _clear_point(src, load, float(com[1]))  # the load's centre of mass, source frame
    # the pads centred across the source at y; the release point moves with the grasp
    shift = np.zeros(2)
    if y is not None:
        shift = src.position[:2] + turn(np.array([0.0, y]), src.yaw) - grasp[:2]
    yaw = src.yaw + yaw_turn  # the source's yaw once released
    down = landing(src, grasp, release, yaw_turn)
    skip = {action.source, *(o.name for o in load)}
    placed = release + np.array([*turn(shift, yaw_turn), 0.0])
    under, below = _supports(objects, skip, down, yaw, HALF_EXTENTS[src.type])
    if len(below) == 1:  # one box under the source: keep the load's centre of mass over it
        move = _onto_support(objects[below[0]], down + turn(com, yaw))
        if np.any(move):
            placed[:2] += move
            under, _ = _supports(objects, skip, down + move, yaw, HALF_EXTENTS[src.type])
    placed[2] = min(release[2], under + half[2] + RELEASE_GAP)
    return grasp + np.array([*shift, 0.0]), placed, y is not None
