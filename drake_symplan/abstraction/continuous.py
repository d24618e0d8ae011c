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

from drake_symplan.abstraction.stability import (
    COVER_INSET,
    FOOTPRINTS,
    LEVEL,
    footprint_points,
    over_top,
    over_tops,
    under_of,
)
from drake_symplan.actions import LIFT_TOL, Action, encode_action, release_centre, relevant_objects
from drake_symplan.boxes import CONTACT_TOLERANCE, HALF_EXTENTS, contact_graph
from drake_symplan.datasets import ObjectState
from drake_symplan.features import box_of, shape_state
from drake_symplan.relations import riders


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
            object.__setattr__(self, "known_contacts", frozenset(contact_graph(self._geometry)))
        return self.known_contacts

    @cached_property
    def _geometry(self) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """name -> (centre, R, half extents), as boxes.contact_graph reads them."""
        return {name: (centre, R, np.asarray(HALF_EXTENTS[kind]))
                for name, (kind, centre, R) in zip(self.names, self.shapes, strict=True)}

    @cached_property
    def _neighbourhoods(self) -> dict[float, frozenset]:
        # radius -> relevance graph: the search predicts hundreds of moves from one scene
        return {}

    @property
    def positions(self) -> np.ndarray:
        return self.features[:, :3]

    def where(self) -> dict[str, np.ndarray]:
        return dict(zip(self.names, self.features[:, :3].astype(float), strict=True))

    def moved(self, positions: np.ndarray, spread: np.ndarray | None = None) -> Boxes:
        """The same boxes at `positions` [n, 3], their contacts from the geometry; `spread`
        [n] is added to the uncertainty they had (root sum of squares)."""
        features = self.features.copy()
        features[:, :3] = positions
        if spread is not None:
            spread = np.sqrt(self.uncertainty() ** 2 + np.asarray(spread) ** 2)
        out = Boxes(self.names, features, None, spread if spread is not None else self.spread)
        # only the centres move: the types and axes, and what is computed of them alone,
        # are this scene's (a search predicts thousands of scenes from a few)
        for known in ("_frames", "index", "_flat"):
            if known in self.__dict__:
                out.__dict__[known] = self.__dict__[known]
        return out

    def kinds(self) -> dict[str, str]:
        """Each box's type by name."""
        return {n: shape[0] for n, shape in zip(self.names, self.shapes, strict=True)}

    def object_states(self) -> dict[str, ObjectState]:
        """The boxes as the skills read them (type, centre, yaw; upright)."""
        return dict(self._states)

    @cached_property
    def _states(self) -> dict[str, ObjectState]:
        # the planner asks the skills' rules of a scene once per step it predicts from it
        return {name: shape_state(name, *shape)
                for name, shape in zip(self.names, self.shapes, strict=True)}

    @cached_property
    def shapes(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Each box's (type, centre, axes R) as features.box_of reads its row, read once:
        the skills' rules, the contacts and the stability rules ask them of a scene over
        and over."""
        centres = self.features[:, :3].astype(float)
        return [(kind, centre, R) for (kind, R), centre in zip(self._frames, centres,
                                                               strict=True)]

    @cached_property
    def _frames(self) -> list[tuple[str, np.ndarray]]:
        # each box's type and axes (features.box_of), which a moved scene keeps
        return [(kind, R) for kind, _, R in map(box_of, self.features)]

    @cached_property
    def index(self) -> dict[str, int]:
        """Each box's row by name."""
        return {n: i for i, n in enumerate(self.names)}

    @cached_property
    def _flat(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What `rest` reads of each box: its yaw's 2x2 rotation [n, 2, 2], its top's
        half extents [n, 2], its half height [n], whether it lies level [n]."""
        turns = np.array([R[:2, :2] for _, R in self._frames])
        tops = np.array([HALF_EXTENTS[kind][:2] for kind, _ in self._frames])
        heights = np.array([HALF_EXTENTS[kind][2] for kind, _ in self._frames])
        return turns, tops, heights, self.features[:, 3] >= LEVEL

    def half_length(self, name: str) -> float:
        """Half the length of box `name` along its long axis (local y), by its type."""
        return HALF_EXTENTS[self.shapes[self.names.index(name)][0]][1]

    @cached_property
    def levels(self) -> tuple[np.ndarray, np.ndarray]:
        """Each box's bottom and top heights, upright (relations.bottom, relations.meets)."""
        z = np.array([centre[2] for _, centre, _ in self.shapes])
        half = np.array([HALF_EXTENTS[kind][2] for kind, _, _ in self.shapes])
        return z - half, z + half

    @cached_property
    def reach(self) -> np.ndarray:
        """Each box's footprint's half diagonal: nothing of it is farther from its centre."""
        return np.array([np.linalg.norm(HALF_EXTENTS[kind][:2]) for kind, _, _ in self.shapes])

    def riding(self, name: str) -> set[str]:
        """The boxes on box `name`, and on those, and so on (relations.riders)."""
        if name not in self._riders:
            self._riders[name] = frozenset(riders(name, self.object_states()))
        return set(self._riders[name])

    @cached_property
    def _riders(self) -> dict[str, frozenset]:
        return {}

    def covered(self) -> set[str]:
        """The boxes with another resting on their top, wholly or in part (a block's end
        over a cube, more than COVER_INSET inside its edges): nothing is set down on them."""
        out = set()
        for i in range(len(self.names)):
            under = under_of(self, i)
            if under:
                points = footprint_points(self, i)
                out |= {self.names[j] for j, *top in under
                        if over_top(points, top, COVER_INSET).any()}
        return out

    def neighbours(self, radius: float) -> frozenset:
        """The relevance graph at `radius` (boxes.neighbour_pairs): the contacts, and with
        a radius above the contact rule's every pair whose surfaces are within it."""
        if radius <= CONTACT_TOLERANCE:
            return self.contacts
        if radius not in self._neighbourhoods:
            self._neighbourhoods[radius] = self.contacts | frozenset(
                contact_graph(self._geometry, radius))
        return self._neighbourhoods[radius]

    def involved(self, action: Action, radius: float = CONTACT_TOLERANCE) -> list[int]:
        """The indices, in scene order, of the objects the action involves
        (actions.relevant_objects), related by the relevance graph at `radius`."""
        pairs = self.neighbours(radius)
        return sorted(self.names.index(n) for n in relevant_objects(self, action, pairs))


class ContinuousModel:
    """`predict(boxes, actions)`: the scene after each action, from trained effect models
    (learning/models.py) run without sampling (bits read by their sign). With several
    (an ensemble trained on other seeds) the positions are the members' mean and each
    box's spread is the members' largest distance from it: where the robot's data leave
    the outcome open, the members disagree."""

    def __init__(self, models: torch.nn.Module | list[torch.nn.Module], snap: float | None = None,
                 radius: float = CONTACT_TOLERANCE):
        members = models if isinstance(models, (list, tuple)) else [models]
        if not members:
            raise ValueError("a continuous model needs at least one effect model")
        self.members = [m.eval() for m in members]
        # a carried box predicted to land nearer its release than this lands at it
        # (_positions; 0: where the members put it, as an explorer asks them)
        self.snap = SNAP if snap is None else snap
        self.radius = radius  # the relevance the models were trained with (boxes.VICINITY)

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
        rows = [boxes.involved(a, self.radius) for a in actions]
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
        steps), where the model's own guess is 6 mm off, and up to 8 cm for a long block."""
        out = boxes.positions.astype(float)
        land = release_centre(out[boxes.index[action.target], :2], action)
        carry = np.array([*(land - out[boxes.index[action.source], :2]), 0.0])
        for i, e in zip(row, effect, strict=True):
            shift = e[:3] + e[3:]
            if e[2] > LIFT_TOL and i in carried:
                if np.linalg.norm(shift[:2]) < snap:
                    shift[:2] = 0.0
                shift = shift + carry
            elif snap > 0 and np.linalg.norm(shift) <= SETTLE_MOVED:
                continue  # not moved: a shift this small is the regression's jitter
            out[i] = out[i] + shift
        gone = out[row] - boxes.positions[row]
        moved = [i for i, far in zip(row, np.sqrt(np.einsum("ij,ij->i", gone, gone)),
                                     strict=True) if far > SETTLE_MOVED]
        return rest(out, boxes, moved, carried)


SNAP = 0.10  # m: a carried box predicted to land nearer its release lands at it (_positions)
SETTLE_MOVED = 0.01  # m: a box predicted to move this far comes to rest (`rest`)
MOVED = 0.02  # m: a box predicted to go this far has moved (a rider too)


def rest(positions: np.ndarray, boxes: Boxes, moved: list[int],
         carried=frozenset()) -> np.ndarray:
    """`positions` of the boxes of `boxes` (their types, yaws and tilts as there) with
    each `moved` box (lowest first, those the hand `carried` last: they come down on what
    the others came to) whose centre is over another box resting flat on the highest
    such box. The effect model regresses the mean of what its
    data did after an action, and where a release sometimes ends on top and sometimes
    beside, that mean is a height no box rests at (a cube put on a tower of three
    predicted 9 cm low); the centre's place is predicted well, and what is under it says
    the height. A level box over no box at all, not even in part, rests on the table (a
    cube released beside a tower falls there; predicted 4.5 cm up, median of 65 such
    eight-box steps); one over another only in part keeps the predicted height (it may lean or lie
    across two)."""
    out = positions.copy()
    turns, tops, heights, level = boxes._flat
    settled = [i for i in range(len(out)) if i not in moved]
    for i in sorted(moved, key=lambda k: (k in carried, out[k][2])):
        kind, R = boxes._frames[i]
        at = np.array(settled, int)
        under = at[over_tops(out[i][None, :2], out[at, :2], turns[at], tops[at])]
        if len(under):
            out[i][2] = max(out[j][2] + heights[j] for j in under) + heights[i]
        elif level[i] and not over_tops(
                out[i][:2] + FOOTPRINTS[kind] @ R[:2, :2].T, out[at, :2], turns[at],
                tops[at]).any():
            out[i][2] = heights[i]
        settled.append(i)
    return out


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
    distance plus the prediction's spread (zero for a perceived scene): boxes.goal_distances
    at once for all of them (the search's heuristic asks it of every scene it predicts)."""
    if not goal:
        return {}
    rows = [boxes.index[n] for n in goal]
    gap = boxes.features[rows, :3].astype(float) - np.array(list(goal.values()), float)
    far = np.sqrt(np.einsum("ij,ij->i", gap, gap)) + boxes.uncertainty()[rows]
    return dict(zip(goal, far.tolist(), strict=True))
