"""A goal of relations' steady atoms: the atoms its structure reads wherever it stands.

The example of a goal of relations is one placement of the structure, and the learned
relation bits also say where on a box another sits (they help predict effects): a cube at
a long block's end reads other bits than one at its middle. Those bits are incidental to
"on", yet a goal that asks for them makes the planner rebuild the example's placement.
The steady atoms are the example's goal atoms read again with each named box (and what
rests on it) shifted along x and y to every place where the relations still hold
(relations.unmet), kept only where every such reading agrees (a pair none of whose atoms
is steady keeps the example's). The learned model reads
the shifted features; nothing is simulated, and the relations are the person's words.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from drake_symplan.relations import riders, unmet

SHIFTS = (-0.075, -0.05, -0.025, 0.025, 0.05, 0.075)  # m along world x, then along y


def _shifted(features: np.ndarray, rows: list[int], offset: np.ndarray) -> np.ndarray:
    out = features.copy()
    out[rows, :2] += offset
    return out


def placements(boxes, relations, names) -> list[np.ndarray]:
    """Features [n, d] of the scene `boxes` (continuous.Boxes) with one of `names` and its
    riders shifted by each of SHIFTS along x or y, where `relations` all still hold."""
    states = boxes.object_states()
    out = []
    for name in names:
        rows = [boxes.names.index(n) for n in (name, *riders(name, states))]
        for axis in (0, 1):
            for d in SHIFTS:
                offset = np.zeros(2)
                offset[axis] = d
                moved = boxes.moved(_shifted(boxes.features, rows, offset)[:, :3])
                if not unmet(relations, moved.object_states()):
                    out.append(moved.features)
    return out


def steady_atoms(abstraction, example, relations, reading) -> tuple[frozenset, int]:
    """(the goal atoms of `reading` (a goal of relations' Reading, with its pairs) that
    every placement of the structure reads, how many placements were read): `example`
    is the whole example scene's Boxes, `relations` what it was built for."""
    example_atoms = atoms = abstraction.goal_atoms(reading)
    named = sorted({n for pair in reading.pairs for n in pair})
    variants = placements(example, relations, named)
    for features in variants:
        again = abstraction.read(example.names, features, reading.contacts)
        atoms &= abstraction.goal_atoms(replace(again, pairs=reading.pairs,
                                                touching=reading.touching))
    for pair in reading.pairs:  # a pair no atom of which is steady keeps the example's
        if not _about(atoms, pair):
            atoms |= _about(example_atoms, pair)
    return atoms, len(variants)


def _about(atoms, pair) -> frozenset:
    """The relation atoms of `atoms` between the two boxes of `pair`, either way."""
    return frozenset(a for a in atoms if len(a) == 3 and {a[1], a[2]} == set(pair))
