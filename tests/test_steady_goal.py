"""A goal of relations' steady atoms (abstraction/steady.py): the placements where the
structure still holds, and the atoms every one of them reads."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_symplan.abstraction.abstraction import Reading
from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.steady import placements, steady_atoms
from drake_symplan.features import object_features
from drake_symplan.relations import parse
from drake_symplan.symbolic.states import SymbolicState

# A cube c on a long block b (its long axis along y), a cube d on the table apart.
NAMES = ("c", "b", "d")
FEATURES = np.stack([object_features("cube", np.array([0.6, 0.0, 0.075]), np.eye(3)),
                     object_features("long", np.array([0.6, 0.0, 0.025]), np.eye(3)),
                     object_features("cube", np.array([0.3, 0.3, 0.025]), np.eye(3))])
SCENE = Boxes(NAMES, FEATURES, frozenset()).moved(FEATURES[:, :3])


def test_a_cube_on_a_long_block_moves_along_the_block_and_the_block_carries_it():
    found = placements(SCENE, parse(["on c b"]), ["b", "c"])
    block = found[:12]  # b with c on it: every shift keeps c on b
    assert len(block) == 12
    assert all(np.allclose(f[0, :2] - f[1, :2], 0.0) for f in block)
    cube = [f[0, :2] - FEATURES[0, :2] for f in found[12:]]  # c alone: 2 cm across, 7.5 along
    assert sorted(round(float(d[0]), 3) for d in cube if d[0]) == [-0.025, 0.025]
    assert sorted(round(float(d[1]), 3) for d in cube if d[1]) == [
        -0.075, -0.05, -0.025, 0.025, 0.05, 0.075]
    assert all(np.allclose(f[2], FEATURES[2]) for f in found)  # d is never moved


@dataclass
class Seen(Reading):
    """A reading that keeps the features it was read from."""

    features: np.ndarray | None = None


def seen(features, pairs=None) -> Seen:
    return Seen(SymbolicState(NAMES, np.zeros((3, 1)), np.zeros((3, 3, 3))),
                np.zeros((3, 1), bool), np.zeros((3, 3, 3), bool), pairs=pairs,
                features=np.asarray(features))


class WhereOnTheBlock:
    """Stands in for a learned model: from c to b it reads r1 only while c sits on the
    block's +y half (where on it: incidental), and r0 always (or, `fickle`, as r1); from
    d to c it reads r2 while they are within 40 cm along x."""

    def __init__(self, fickle: bool = False):
        self.fickle = fickle

    def read(self, names, features, contacts=()):
        return seen(features)

    def goal_atoms(self, reading):
        f = reading.features
        plus = f[0, 1] - f[1, 1] > 0.01
        out = {("r1", "c", "b")} if plus else set()
        if plus or not self.fickle:
            out.add(("r0", "c", "b"))
        if abs(f[2, 0] - f[0, 0]) < 0.4:
            out.add(("r2", "d", "c"))
        return frozenset(out)


def test_the_steady_atoms_are_those_every_placement_reads():
    shifted = FEATURES.copy()
    shifted[0, 1] += 0.05  # the example has c at the block's +y end: r1 read there
    example = Boxes(NAMES, shifted, frozenset()).moved(shifted[:, :3])
    reading = seen(shifted, pairs={("c", "b"): (0, 0)})
    atoms, n = steady_atoms(WhereOnTheBlock(), example, parse(["on c b"]), reading)
    assert atoms == {("r0", "c", "b"), ("r2", "d", "c")} and n == 20
    # a pair none of whose atoms is steady keeps the example's
    atoms, _ = steady_atoms(WhereOnTheBlock(fickle=True), example, parse(["on c b"]), reading)
    assert atoms == {("r0", "c", "b"), ("r1", "c", "b"), ("r2", "d", "c")}
