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
other objects), stay as learned. The planner's cost (-log reliability) is remeasured.
"""

from __future__ import annotations

import dataclasses

from drake_symplan.symbolic.effect_operators import Lifted, action_of, by_action, counted
from drake_symplan.symbolic.lifted import LiftedOperator

DEFAULT_TOLERANCE = 0.02  # reliability an operator may lose with an atom dropped


def droppable(op: LiftedOperator) -> list:
    """The precondition atoms `generalize` tries to drop, in the order it tries them: the
    unary atoms of every slot but the source's (0), the highest slot first. A relation
    names which objects an operator's effect reaches and is kept: an operator of three
    objects that lost them would claim its effect on any third box."""
    atoms = [a for a in op.pre if len(a) == 2 and a[1] != 0]
    return sorted(atoms, key=lambda a: (-a[1], a[0]))


def _measured(op: LiftedOperator, pre: tuple, transitions: list[Lifted]) -> LiftedOperator:
    """`op` with preconditions `pre`, its counts measured on `transitions`."""
    out = dataclasses.replace(op, pre=pre)
    out.applicable, out.succeeded = counted(out, transitions)
    return out


def generalize_one(op: LiftedOperator, transitions: list[Lifted],
                   tolerance: float = DEFAULT_TOLERANCE) -> LiftedOperator:
    """`op` with the atoms the data gives no evidence for dropped (module docstring);
    `transitions`: those of its action."""
    best = _measured(op, op.pre, transitions)
    floor = best.reliability - tolerance
    for atom in droppable(op):
        trial = _measured(best, tuple(a for a in best.pre if a != atom), transitions)
        if trial.applicable and trial.reliability >= floor:
            best = trial
    return best


def generalize(operators: list[LiftedOperator], lifted: list[Lifted],
               tolerance: float = DEFAULT_TOLERANCE) -> list[LiftedOperator]:
    """Every operator generalized on the transitions `lifted` (`generalize_one`)."""
    actions = by_action(lifted)
    return [generalize_one(op, actions.get(action_of(op), []), tolerance) for op in operators]
