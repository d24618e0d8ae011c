"""Operators' preconditions cut to what the data shows matters to their effect.

Cluster-and-intersect (effect_operators.py) keeps every atom that held in a group's
transitions, so an operator also asks for whatever the exploration happened to meet: a
bridge learned over two cubes on the table asks that its supports stand at the table's
level, a place on a tower's top that the box under the target stands on the table,
because scenes of two to four boxes never showed otherwise. `generalize` drops such an
atom where the data gives no evidence that it matters: without it the operator's
reliability, measured on every transition of its action where the rest of its
preconditions hold, stays within `tolerance` of what it was. An atom whose absence lets in
transitions with other outcomes stays. Only the unary atoms (symbols and contact degrees)
of the target and the other objects are tried, the other objects' first: what an action
does to the box it moves, and which boxes its effect reaches (the relations that bind the
other objects), stay as learned. With `bystanders`, an object the effect does not name
(a parameter only because it stood near: the box under a tower's top, a second tower
beside the one a block is set on) is then tried as a whole, its parameter and every
precondition on it dropped, on the same test. The planner's cost (-log reliability) is
remeasured.
"""

from __future__ import annotations

import dataclasses

from drake_symplan.symbolic.effect_operators import Lifted, action_of, by_action, counted
from drake_symplan.symbolic.lifted import Atom, LiftedOperator

DEFAULT_TOLERANCE = 0.02  # reliability an operator may lose with an atom dropped


def droppable(op: LiftedOperator) -> list:
    """The precondition atoms `generalize` tries to drop, in the order it tries them: the
    unary atoms of every slot but the source's (0), the highest slot first. A relation
    names which objects an operator's effect reaches and is kept: an operator of three
    objects that lost them would claim its effect on any third box."""
    atoms = [a for a in op.pre if len(a) == 2 and a[1] != 0]
    return sorted(atoms, key=lambda a: (-a[1], a[0]))


def bystanders(op: LiftedOperator) -> list[int]:
    """The parameter slots beyond source and target that no effect names, highest first."""
    named = {s for a in (*op.add, *op.delete) for s in a[1:]}
    return [s for s in range(op.n_params - 1, 1, -1) if s not in named]


def without_slot(op: LiftedOperator, slot: int) -> LiftedOperator:
    """`op` without parameter `slot`: its preconditions on it dropped, the slots above it
    renumbered down by one."""
    def renamed(atoms) -> tuple:
        return tuple(Atom(a[0], *(s - (s > slot) for s in a[1:])) for a in atoms
                     if slot not in a[1:])

    kept = tuple(s for i, s in enumerate(op.example_slots) if i != slot)
    return dataclasses.replace(op, n_params=op.n_params - 1, pre=renamed(op.pre),
                               add=renamed(op.add), delete=renamed(op.delete),
                               example_slots=kept)


def _measured(op: LiftedOperator, pre: tuple, transitions: list[Lifted]) -> LiftedOperator:
    """`op` with preconditions `pre`, its counts measured on `transitions`."""
    out = dataclasses.replace(op, pre=pre)
    out.applicable, out.succeeded = counted(out, transitions)
    return out


def generalize_one(op: LiftedOperator, transitions: list[Lifted],
                   tolerance: float = DEFAULT_TOLERANCE,
                   bystanders_too: bool = False) -> LiftedOperator:
    """`op` with the atoms (and, `bystanders_too`, the objects) the data gives no evidence
    for dropped (module docstring); `transitions`: those of its action."""
    best = _measured(op, op.pre, transitions)
    floor = best.reliability - tolerance
    for atom in droppable(op):
        trial = _measured(best, tuple(a for a in best.pre if a != atom), transitions)
        if trial.applicable and trial.reliability >= floor:
            best = trial
    for slot in bystanders(best) if bystanders_too else ():
        trial = without_slot(best, slot)
        trial = _measured(trial, trial.pre, transitions)
        if trial.applicable and trial.reliability >= floor:
            best = trial
    return best


def generalize(operators: list[LiftedOperator], lifted: list[Lifted],
               tolerance: float = DEFAULT_TOLERANCE,
               bystanders_too: bool = False) -> list[LiftedOperator]:
    """Every operator generalized on the transitions `lifted` (`generalize_one`)."""
    actions = by_action(lifted)
    return [generalize_one(op, actions.get(action_of(op), []), tolerance, bystanders_too)
            for op in operators]
