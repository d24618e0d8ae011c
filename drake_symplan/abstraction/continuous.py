"""A learned continuous model of the world: where each box goes under a pick/place, from the
effect model the robot trained on its own exploration data, rolled forward.

The effect model predicts, for the objects an action involves (its source and target and
whatever touches them, as in training: data/exploration.py), each one's displacement at
the end of the lift and after the release relative to where the carry put it (the effect,
actions.py). The source, and what rides on it, predicted to rise with the hand is carried
with it: the source's centre to the release point (the target's centre shifted along y,
actions.release_centre), its riders by the same vector, and it comes down there unless
predicted to fall off (SNAP); a box the hand leaves keeps its place unless predicted
pushed. A box that moved and whose centre is then over another comes to rest on it, one
over no box on the table (`rest`: the network regresses a mean height, which for an
outcome that goes either way is no height a box rests at). Orientations are kept (a
tipped box is predicted lying as it was), positions change, and the predicted scene's
contacts come from the box geometry (boxes.contact_graph). Objects out of the action's
reach stay. No simulator: what the planner knows, the robot learned, and what its own hand
does (what it holds, where it lets go).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import torch

from drake_symplan.actions import LIFT_TOL, Action, encode_action, release_centre, relevant_objects
from drake_symplan.boxes import HALF_EXTENTS, MASS, contact_graph, goal_distances
from drake_symplan.datasets import ObjectState
from drake_symplan.features import box_of


@dataclass(frozen=True)
class Boxes:
    """A scene as the continuous model sees it: named objects, their features [n, d_o]
    (position first, features.py), the pairs in contact, and how uncertain each position
    is (`spread` [n], m: the ensemble's disagreement accumulated along a rollout; zero for
    a perceived scene). A predicted scene's contacts come from the geometry when first
    asked for: a search predicts many scenes and looks into few."""

    names: tuple[str, ...]
    features: np.ndarray
    known_contacts: frozenset | None = None  # None: from the box geometry, when asked
    spread: np.ndarray | None = None

    def uncertainty(self) -> np.ndarray:
        return np.zeros(len(self.names)) if self.spread is None else self.spread

    @classmethod
    def of(cls, scene) -> Boxes:
        """From a perceived scene (names, features(), contacts)."""
        return cls(tuple(scene.names), np.asarray(scene.features(), np.float32),
                   frozenset(tuple(sorted(p)) for p in scene.contacts))

    @property
    def contacts(self) -> frozenset:
        """The sorted name pairs in contact."""
        if self.known_contacts is None:
            geometry = {name: (centre, R, np.asarray(HALF_EXTENTS[kind]))
                        for name, (kind, centre, R) in zip(self.names, self.shapes, strict=True)}
            object.__setattr__(self, "known_contacts", frozenset(contact_graph(geometry)))
        return self.known_contacts

    @property
    def positions(self) -> np.ndarray:
        return self.features[:, :3]

    def where(self) -> dict[str, np.ndarray]:
        return {n: self.features[i, :3].astype(float) for i, n in enumerate(self.names)}

    def moved(self, positions: np.ndarray, spread: np.ndarray | None = None) -> Boxes:
        """The same boxes at `positions` [n, 3], their contacts from the geometry; `spread`
        [n] is added to the uncertainty they had (root sum of squares)."""
        features = self.features.copy()
        features[:, :3] = positions
        if spread is not None:
            spread = np.sqrt(self.uncertainty() ** 2 + np.asarray(spread) ** 2)
        return Boxes(self.names, features, None, spread if spread is not None else self.spread)

    def kinds(self) -> dict[str, str]:
        """Each box's type by name."""
        return {n: shape[0] for n, shape in zip(self.names, self.shapes, strict=True)}

    def object_states(self) -> dict[str, ObjectState]:
        """The boxes as the skills read them (type, centre, yaw; upright)."""
        return dict(self._states)

    @cached_property
    def _states(self) -> dict[str, ObjectState]:
        # the planner asks the skills' rules of a scene once per step it predicts from it
        return {name: ObjectState(name, kind, centre, float(np.arctan2(R[1, 0], R[0, 0])))
                for name, (kind, centre, R) in zip(self.names, self.shapes, strict=True)}

    @cached_property
    def shapes(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Each box's (type, centre, axes R) as features.box_of reads its row, read once:
        the skills' rules, the contacts and the stability rules ask them of a scene over
        and over."""
        return [box_of(row) for row in self.features]

    def half_length(self, name: str) -> float:
        """Half the length of box `name` along its long axis (local y), by its type."""
        return HALF_EXTENTS[self.shapes[self.names.index(name)][0]][1]

    def riding(self, name: str) -> set[str]:
        """The boxes on box `name`: those whose centre is over its top face and higher than
        it, and those on them, and so on."""
        found, frontier = set(), [name]
        while frontier:
            below = self.names.index(frontier.pop())
            kind, centre, R = self.shapes[below]
            top = centre[2] + HALF_EXTENTS[kind][2]
            for j, other in enumerate(self.names):
                if other != name and other not in found and self.positions[j][2] > top \
                        and _inside(kind, R, centre, self.positions[j]):
                    found.add(other)
                    frontier.append(other)
        return found

    def covered(self) -> set[str]:
        """The boxes with another resting on their top, wholly or in part (a block's end
        over a cube, more than COVER_INSET inside its edges): nothing is set down on them."""
        out = set()
        for i in range(len(self.names)):
            under = _under(self, i)
            if under:
                points = _footprint_points(self, i)
                out |= {self.names[j] for j, *top in under
                        if _over_top(points, top, COVER_INSET).any()}
        return out

    def involved(self, action: Action) -> list[int]:
        """The indices, in scene order, of the objects the action involves
        (actions.relevant_objects)."""
        return sorted(self.names.index(n) for n in relevant_objects(self, action))


class ContinuousModel:
    """`predict(boxes, actions)`: the scene after each action, from trained effect models
    (learning/models.py) run without sampling (bits read by their sign). With several
    (an ensemble trained on other seeds) the positions are the members' mean and each
    box's spread is the members' largest distance from it: where the robot's data leave
    the outcome open, the members disagree."""

    def __init__(self, models: torch.nn.Module | list[torch.nn.Module], snap: float | None = None):
        members = models if isinstance(models, (list, tuple)) else [models]
        if not members:
            raise ValueError("a continuous model needs at least one effect model")
        self.members = [m.eval() for m in members]
        # a carried box predicted to land nearer its release than this lands at it
        # (_positions; 0: where the members put it, as an explorer asks them)
        self.snap = SNAP if snap is None else snap

    def predict(self, boxes: Boxes, actions: list[Action]) -> list[Boxes]:
        """The predicted scene after each of `actions` from `boxes`, in one batch."""
        out = []
        for each in self._member_positions(boxes, actions):
            mean = each.mean(axis=0)
            spread = np.linalg.norm(each - mean, axis=-1).max(axis=0) \
                if len(each) > 1 else None
            out.append(boxes.moved(mean, spread))
        return out

    def disagreement(self, boxes: Boxes, actions: list[Action]) -> np.ndarray:
        """[len(actions)] m: for each action, the largest distance of a member's predicted
        position of a box from the members' mean (0 with one member)."""
        return np.array([np.linalg.norm(each - each.mean(axis=0), axis=-1).max()
                         for each in self._member_positions(boxes, actions)])

    def _member_positions(self, boxes: Boxes, actions: list[Action]) -> list[np.ndarray]:
        """Per action, each member's predicted positions [members, n, 3], in one batch."""
        if not actions:
            return []
        rows = [boxes.involved(a) for a in actions]
        width = max(len(r) for r in rows)
        d = boxes.features.shape[1]
        state = np.zeros((len(actions), width, d), np.float32)
        code = np.zeros((len(actions), width, 8), np.float32)
        mask = np.zeros((len(actions), width), bool)
        for b, (action, row) in enumerate(zip(actions, rows, strict=True)):
            state[b, :len(row)] = boxes.features[row]
            code[b, :len(row)] = encode_action(action, [boxes.names[i] for i in row])
            mask[b, :len(row)] = True
        with torch.no_grad():
            inputs = (torch.from_numpy(state), torch.from_numpy(code), torch.from_numpy(mask))
            effects = [m(*inputs).numpy() for m in self.members]
        carried = {}  # per source: its index and its riders', what the hand can carry
        for a in actions:
            if a.source not in carried:
                carried[a.source] = {boxes.names.index(n)
                                     for n in {a.source} | boxes.riding(a.source)}
        return [np.stack([self._positions(boxes, action, row, e[b, :len(row)],
                                          carried[action.source], self.snap)
                          for e in effects])
                for b, (action, row) in enumerate(zip(actions, rows, strict=True))]

    def rollout(self, boxes: Boxes, actions: list[Action]) -> list[Boxes]:
        """The scenes after each action of a sequence, one applied after the other."""
        return rollout(self.predict, boxes, actions)

    @staticmethod
    def _positions(boxes: Boxes, action: Action, row: list[int], effect: np.ndarray,
                   carried: set[int], snap: float) -> np.ndarray:
        """Positions after `action`: the effects of the involved objects `row` [m, 6]
        added to where they were, the carry added to those that rose with the hand. Only
        the source and what rides on it (`carried`, indices) can rise with it: placed on
        a tower of three, the model has the box under the target rising and carried 15 cm
        with the hand (traced, eight boxes), which no hand does. A carried box comes down
        where the hand releases it unless the model has it land `snap` or more from there
        (it falls off): the arm sets a box down 2 mm from its release (median, 256 six-box
        steps), where the model's own guess is 6 mm off, and up to 8 cm for a long block
        (docs/goals.md, "What the model predicts of the designed plans")."""
        where = boxes.where()
        land = release_centre(where[action.target][:2], action)
        carry = np.array([*(land - where[action.source][:2]), 0.0])
        out = boxes.positions.astype(float).copy()
        for i, e in zip(row, effect, strict=True):
            shift = e[:3] + e[3:]
            if e[2] > LIFT_TOL and i in carried:
                if np.linalg.norm(shift[:2]) < snap:
                    shift[:2] = 0.0
                shift = shift + carry
            elif snap > 0 and np.linalg.norm(shift) <= SETTLE_MOVED:
                continue  # not moved: a shift this small is the regression's jitter
            out[i] = out[i] + shift
        moved = [i for i in row if np.linalg.norm(out[i] - boxes.positions[i]) > SETTLE_MOVED]
        return rest(out, boxes.features, moved, carried)


SNAP = 0.10  # m: a carried box predicted to land nearer its release lands at it (_positions)
SETTLE_MOVED = 0.01  # m: a box predicted to move this far comes to rest (`rest`)
MOVED = 0.02  # m: a box predicted to go this far has moved (a rider too)


def rest(positions: np.ndarray, features: np.ndarray, moved: list[int],
         carried=frozenset()) -> np.ndarray:
    """`positions` with each `moved` box (lowest first, those the hand `carried` last: they
    come down on what the others came to) whose centre is over another box resting flat on
    the highest such box. The effect model regresses the mean of what its
    data did after an action, and where a release sometimes ends on top and sometimes
    beside, that mean is a height no box rests at (a cube put on a tower of three
    predicted 9 cm low); the centre's place is predicted well, and what is under it says
    the height. A level box over no box at all, not even in part, rests on the table (a
    cube released beside a tower falls there; predicted 4.5 cm up, median of 65 such
    eight-box steps); one over another only in part keeps the predicted height (it may lean or lie
    across two)."""
    out = positions.copy()
    settled = [i for i in range(len(out)) if i not in moved]
    for i in sorted(moved, key=lambda k: (k in carried, out[k][2])):
        kind, _, R = box_of(features[i])
        under = [j for j in settled if _covers(features[j], out[j], out[i])]
        if under:
            top = max(out[j][2] + HALF_EXTENTS[box_of(features[j])[0]][2] for j in under)
            out[i][2] = top + HALF_EXTENTS[kind][2]
        elif features[i][3] >= LEVEL and not any(
                _covers_any(features[j], out[j], out[i][:2] + _FOOTPRINTS[kind] @ R[:2, :2].T)
                for j in settled):
            out[i][2] = HALF_EXTENTS[kind][2]
        settled.append(i)
    return out


RAISED = 0.01  # m: a box whose bottom is this far above the table stands on something
STACK_GAP = 0.02  # m: a box's top this near another's bottom holds it up
HULL_TOL = 0.005  # m: a centre this far outside where a box is held still stands
EDGE_TOL = 0.001  # m: a footprint this near a top's edge rests on it (a block 15 cm off a cube)
COVER_INSET = 0.005  # m: a box over another's top this far inside its edges rests on it
LEVEL = np.cos(np.radians(10))  # cos tilt: a box tilted more leans (on the table too)
LOAD_INSET = 0.0105  # m: a load's centre of mass this far inside its one support's edges stands


def _footprint(kind: str, spacing: float = 0.00625) -> np.ndarray:
    """Points over a box's bottom face (local xy, m), `spacing` apart, its edges included."""
    hx, hy = HALF_EXTENTS[kind][:2]
    u = np.linspace(-hx, hx, int(round(2 * hx / spacing)) + 1)
    v = np.linspace(-hy, hy, int(round(2 * hy / spacing)) + 1)
    return np.array([(a, b) for a in u for b in v])


_FOOTPRINTS = {kind: _footprint(kind) for kind in HALF_EXTENTS}


# Directions in which a centre is compared with where a box is held: a hull of 32 sides
_DIRECTIONS = np.stack([np.cos(np.arange(32) * np.pi / 16), np.sin(np.arange(32) * np.pi / 16)],
                       axis=1)


def tips(boxes: Boxes, name: str) -> bool:
    """Does box `name`, as predicted, rest partly on boxes under it with its centre beyond
    where they hold it (outside the convex hull of its footprint's points over their tops,
    by more than HULL_TOL): a block released at its end over one cube, which topples? A box
    on the table, one held across two supports (a bridge) or centred over one, and one held
    up by nothing predicted (its height a regression's mean) are not judged, nor one that
    leans (tilted beyond LEVEL: held by the table or a side too)."""
    i = boxes.names.index(name)
    if boxes.features[i][3] < LEVEL:
        return False
    centre = boxes.features[i][:2].astype(float)
    under = _under(boxes, i)
    if any(_over_top(centre[None], top)[0] for _, *top in under):
        return False  # centred over a support
    points = _footprint_points(boxes, i)
    held = np.zeros(len(points), bool)
    for _, *top in under:
        held |= _over_top(points, top, -EDGE_TOL)
    if not held.any():
        return False
    reach = (points[held] @ _DIRECTIONS.T).max(axis=0)
    return bool(np.any(centre @ _DIRECTIONS.T > reach + HULL_TOL))


def overloaded(boxes: Boxes, name: str) -> bool:
    """Does box `name`, level and resting on one box alone, hold a load with a block in it
    (itself and what rides on it, by the catalogue's masses) with the load's centre of mass
    less than LOAD_INSET inside that box's top face? The contacts give a little, and a
    heavy load near an edge leans on them and falls where rigid boxes would stand: a block
    centred 1.8 cm off a cube, and one centred on it with a cube at its end (the load 1.5
    cm off), fell; a block 1.6 cm off stood, and so did towers of cubes 3 mm apart. Loads
    1.0-1.25 cm off stand in five of the thirty eight-box goals, and one 1.1 cm off (a
    cube at the end of two blocks on a cube) fell in a solve: statics cannot tell those
    apart, and the rule leaves them."""
    i = boxes.names.index(name)
    under = _supports(boxes, i)
    return len(under) == 1 and _overloaded(boxes, i, under[0])


def _overloaded(boxes: Boxes, i: int, support) -> bool:
    """overloaded, box i's one support given (as _under gives it)."""
    if boxes.features[i][3] < LEVEL:
        return False
    load = [i] + [boxes.names.index(n) for n in boxes.riding(boxes.names[i])]
    kinds = [boxes.shapes[k][0] for k in load]
    if "long" not in kinds:
        return False
    mass = np.array([MASS[k] for k in kinds])
    centre = mass @ boxes.positions[load, :2] / mass.sum()
    return not _over_top(centre[None], support[1:], LOAD_INSET)[0]


def on_overhang(boxes: Boxes, name: str) -> bool:
    """Does box `name` rest on a level block held up by one box alone, its centre beyond
    that box's top: on the block's free end? Set down there, its weight comes onto the
    end of a lever: a cube let down on the end of a block balanced on a cube, atop a
    tower, brought the tower down (traced, eight boxes), its load 1.25 cm off centre,
    which stands where it is built without the blow (overloaded)."""
    i = boxes.names.index(name)
    centre = boxes.positions[i, :2][None].astype(float)
    for j, *_ in _supports(boxes, i):
        if boxes.shapes[j][0] != "long" or boxes.features[j][3] < LEVEL:
            continue
        under = _supports(boxes, j)
        if len(under) == 1 and not _over_top(centre, under[0][1:])[0]:
            return True
    return False


def unstable(boxes: Boxes, names) -> bool:
    """Does one of `names` topple (tips), rest on a block's free end (on_overhang), or it
    or a box it rests on, down to the table, hold its load off its one support
    (overloaded)? Only a raised block loads a box."""
    raised = any(k == "long" and c[2] - HALF_EXTENTS[k][2] >= RAISED
                 for k, c, _ in boxes.shapes)
    for name in names:
        if tips(boxes, name) or raised and on_overhang(boxes, name):
            return True
        i, seen = boxes.names.index(name), set()
        while raised and i not in seen:
            seen.add(i)
            under = _supports(boxes, i)
            if len(under) != 1:
                break
            if _overloaded(boxes, i, under[0]):
                return True
            i = under[0][0]
    return False


def _under(boxes: Boxes, i: int) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """The boxes whose top is within STACK_GAP of box i's bottom, i raised off the table:
    (index, centre xy, yaw's 2x2 rotation, top's half extents) each."""
    kind, centre, _ = boxes.shapes[i]
    bottom = centre[2] - HALF_EXTENTS[kind][2]
    if bottom < RAISED:
        return []
    out = []
    for j, (kind_j, centre_j, R_j) in enumerate(boxes.shapes):
        if j != i and abs(centre_j[2] + HALF_EXTENTS[kind_j][2] - bottom) <= STACK_GAP:
            out.append((j, centre_j[:2], R_j[:2, :2], np.asarray(HALF_EXTENTS[kind_j][:2])))
    return out


def _supports(boxes: Boxes, i: int) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """The boxes under box i (_under) that its footprint is over, in part."""
    points = _footprint_points(boxes, i)
    return [u for u in _under(boxes, i) if _over_top(points, u[1:]).any()]


def _over_top(points: np.ndarray, top, inset: float = 0.0) -> np.ndarray:
    """Which xy `points` [m, 2] lie over a top face `top` (centre xy, yaw's 2x2 rotation,
    half extents: as _under gives), at least `inset` inside its edges."""
    centre, R, half = top
    return np.all(np.abs((points - centre) @ R) <= half - inset, axis=1)


def _footprint_points(boxes: Boxes, i: int) -> np.ndarray:
    """Points over box i's bottom face, world xy."""
    kind, centre, R = boxes.shapes[i]
    return centre[:2] + _FOOTPRINTS[kind] @ R[:2, :2].T


def _covers(row: np.ndarray, centre: np.ndarray, point: np.ndarray) -> bool:
    """Is `point`'s xy over the top face of the box of features `row` standing at
    `centre`?"""
    kind, _, R = box_of(row)
    return _inside(kind, R, centre, point)


def _inside(kind: str, R: np.ndarray, centre: np.ndarray, point: np.ndarray) -> bool:
    """Is `point`'s xy over the top face of a box of type `kind`, axes R, at `centre`?"""
    local = R[:2, :2].T @ (point - centre)[:2]
    return bool(np.all(np.abs(local) <= np.asarray(HALF_EXTENTS[kind][:2])))


def _covers_any(row: np.ndarray, centre: np.ndarray, points: np.ndarray) -> bool:
    """Is any of the xy `points` [m, 2] over the top face of the box of features `row`
    standing at `centre`?"""
    kind, _, R = box_of(row)
    local = (points - centre[:2]) @ R[:2, :2]
    return bool(np.any(np.all(np.abs(local) <= np.asarray(HALF_EXTENTS[kind][:2]), axis=1)))


def rollout(predict, boxes: Boxes, actions: list) -> list[Boxes]:
    """The scenes after each of `actions`, one applied after the other from `boxes`, by
    `predict(boxes, actions) -> [Boxes]` (a ContinuousModel's, or anything that predicts as
    one does)."""
    out = []
    for action in actions:
        boxes = predict(boxes, [action])[0]
        out.append(boxes)
    return out


def goal_errors(boxes: Boxes, goal: dict[str, np.ndarray]) -> dict[str, float]:
    """Each box's distance (m) to its goal position, as far as it may be: the predicted
    distance plus the prediction's spread (zero for a perceived scene)."""
    return goal_distances(boxes.where(), goal,
                          dict(zip(boxes.names, boxes.uncertainty(), strict=True)))
