"""The pick/place action every layer shares: its parameters, offsets, per-object encoding
and the effect layout it is learned with. No Drake and no torch here."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

# The paper's single action has four discrete parameters: pick `source` at a grasp
# offset, release it above `target` at a release offset. Offsets run along world y,
# the long blocks' long axis, as in the authors' setup.
OFFSETS: tuple[str, ...] = ("left", "center", "right")
OFFSET_METRES: dict[str, float] = {"left": -0.075, "center": 0.0, "right": 0.075}

# Per-object action encoding (one-hot, ACTION_DIM = 8):
#   [is_source, grasp=left, grasp=center, grasp=right,
#    is_target, release=left, release=center, release=right]
# A non-argument object is all zeros; the grasp bits are set only on the source and
# the release bits only on the target.
ACTION_DIM = 8
IS_SOURCE, IS_TARGET = 0, 4  # the role columns of the encoding

# Per-object effect (EFFECT_DIM = 6, metres): [dp at lift (3); dp after release
# relative to where the carry put it (3)]. The second half has the arm's lateral
# carry (source's lifted xy -> release xy) subtracted, so symbols need no global
# position (paper, Experiment Setup).
EFFECT_DIM = 6
LIFT_TOL = 0.05  # m of rise at the end of the lift: the object went up with the hand


@dataclass(frozen=True)
class Action:
    """pick(source, grasp) then place on target with release offset."""

    source: str
    grasp: str
    target: str
    release: str

    def __post_init__(self):
        if self.grasp not in OFFSETS:
            raise ValueError(f"unknown grasp offset {self.grasp!r}; expected one of {OFFSETS}")
        if self.release not in OFFSETS:
            raise ValueError(
                f"unknown release offset {self.release!r}; expected one of {OFFSETS}"
            )
        if self.source == self.target:
            raise ValueError(f"source and target are the same object {self.source!r}")

    @classmethod
    def parse(cls, pick: str, place: str) -> Action:
        """From CLI strings 'o1:center' and 'o2:left'."""
        try:
            source, grasp = pick.split(":")
            target, release = place.split(":")
        except ValueError as e:
            raise ValueError(
                f"expected NAME:OFFSET for --pick and --place, got {pick!r} and {place!r}"
            ) from e
        return cls(source, grasp, target, release)

    def __str__(self) -> str:
        return f"pick({self.source}:{self.grasp}) place({self.target}:{self.release})"

    @classmethod
    def from_text(cls, text: str) -> Action:
        """The inverse of str(): 'pick(o1:center) place(o0:left)' -> its Action."""
        m = re.fullmatch(r"pick\((\S+):(\w+)\) place\((\S+):(\w+)\)", text.strip())
        if m is None:
            raise ValueError(f"{text!r} is not an action 'pick(NAME:OFFSET) place(NAME:OFFSET)'")
        return cls(m[1], m[2], m[3], m[4])


# ---------------------------------------------------------------- where the hand goes
# The action's geometry, the one place every layer reads it from: the fingers close at the
# source's centre shifted along world y by the grasp offset (whatever the box's yaw), and
# that grasp point is released over the target's centre shifted along world y by the
# release offset, so the two offsets compose. Positions are numpy xy or xyz centres.


def along_y(metres: float, dims: int = 3) -> np.ndarray:
    """`metres` along world y as an xy (`dims` 2) or xyz vector."""
    v = np.zeros(dims)
    v[1] = metres
    return v

# How far (m, box frame) outside a box the grasp point may lie and still catch it: the
# open fingers are 8.5 cm apart across x (1.75 cm of slack on a 5 cm box), the finger pads
# are 2 cm wide along y and reach 1.5 cm below the grasp point.
GRASP_SLACK = np.array([0.0175, 0.008, 0.015])


def grasp_point(centre: np.ndarray, action: Action) -> np.ndarray:
    """Where the fingers close on the source whose centre (xy or xyz) is `centre`."""
    return centre + along_y(OFFSET_METRES[action.grasp], len(centre))


def release_point(centre: np.ndarray, action: Action) -> np.ndarray:
    """Where the grasp point is released over the target whose centre is `centre`."""
    return centre + along_y(OFFSET_METRES[action.release], len(centre))


def release_shift(action: Action) -> float:
    """How far along world y from the target's centre the source's centre is released: its
    grasp point goes over the target's release point (skills/pick_place.py)."""
    return OFFSET_METRES[action.release] - OFFSET_METRES[action.grasp]


def release_centre(centre: np.ndarray, action: Action) -> np.ndarray:
    """Where the source's centre is released over the target whose centre is `centre`: that
    centre shifted along world y by `release_shift`."""
    return centre + along_y(release_shift(action), len(centre))


def grasp_on_box(grasp: str, half_length: float) -> bool:
    """Does the grasp offset keep the grasp point on a box `half_length` long either side
    of its centre along the offsets' axis (the caller says which half length counts)?"""
    return abs(OFFSET_METRES[grasp]) < half_length


def relevant_objects(scene, action: Action, pairs=None) -> list[str]:
    """The objects a transition records and an effect model sees (the Relevance contract):
    [source, target] + the objects related to either in `scene`: by `pairs`, its relevance
    graph (boxes.neighbour_pairs), its `contacts` when not given."""
    args = (action.source, action.target)
    touching = set()
    for a, b in scene.contacts if pairs is None else pairs:
        if a in args and b not in args:
            touching.add(b)
        elif b in args and a not in args:
            touching.add(a)
    return [*args, *sorted(touching)]


def encode_action(action: Action, names: list[str]) -> np.ndarray:
    """The per-object action encoding [len(names), ACTION_DIM] for objects `names`."""
    if action.source not in names:
        raise ValueError(f"action source {action.source!r} is not among objects {names}")
    if action.target not in names:
        raise ValueError(f"action target {action.target!r} is not among objects {names}")
    a = np.zeros((len(names), ACTION_DIM), dtype=np.float32)
    s, t = names.index(action.source), names.index(action.target)
    a[s, IS_SOURCE] = 1.0
    a[s, IS_SOURCE + 1 + OFFSETS.index(action.grasp)] = 1.0
    a[t, IS_TARGET] = 1.0
    a[t, IS_TARGET + 1 + OFFSETS.index(action.release)] = 1.0
    return a
