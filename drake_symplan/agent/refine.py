"""Choosing a plan step's offsets so the placed object lands where the goal scene has it.

The learned symbols say that a box ends on another, not where along it: a plan step
`pick o3 at its centre, release on o1's right` and the same step released at o1's centre
can predict the same symbolic effect. The planner picks either; the 5 cm check cannot
accept both. Before a step runs, `refine_step` looks for the domain's operators that are
interchangeable with it here (same arguments, preconditions that hold in the believed
state, and from its predicted successor the rest of the plan still applies and reaches the
goal's atoms) and takes the one whose offsets
put the source nearest its perceived goal position, as an NSRT's sampler picks the
continuous parameters of a step (here: among the three discrete offsets per hand).

Where the source rests on the target in the goal scene, the position that counts is the
one relative to the target (the target may move later); otherwise it is absolute.
"""

from __future__ import annotations

import numpy as np

from drake_symplan.structs import OFFSET_METRES
from drake_symplan.symbolic.effect_operators import ground_slots

MIN_GAIN = 0.01  # m: a change of offsets must bring the source this much nearer its goal


def _ground(atoms, args) -> set:
    return set(ground_slots(atoms, args))


def _successor(op, args, state: set) -> set:
    return (state - _ground(op.delete, args)) | _ground(op.add, args)


def advance(bundle, step: str, state: set) -> set:
    """The state the step's operator predicts from `state`."""
    from drake_symplan.symbolic.pddl import plan_step_action

    return _successor(bundle.operator_of(step), plan_step_action(step).args, state)


def reaches(bundle, steps: list[str], state: set, goal: set) -> bool:
    """Do `steps` apply one after the other from `state` and end in a state holding `goal`?"""
    from drake_symplan.symbolic.pddl import plan_step_action

    for step in steps:
        if not _ground(bundle.operator_of(step).pre, plan_step_action(step).args) <= state:
            return False
        state = advance(bundle, step, state)
    return goal <= state


def equivalents(bundle, step: str, rest: list[str], state: set, goal: set) -> list[str]:
    """`step`, then the steps with the same arguments whose operators apply in `state` (a
    set of ground atoms) and after which `rest` still reaches `goal`."""
    from drake_symplan.symbolic.pddl import plan_step_action

    args = plan_step_action(step).args
    op = bundle.operator_of(step)
    out = [step]
    for other in bundle.operators:
        if other.n_params != op.n_params or other is op:
            continue
        if _ground(other.pre, args) <= state and \
                reaches(bundle, rest, _successor(other, args, state), goal):
            out.append(f"({other.name} {' '.join(args)})")
    return out


def landing_error(step: str, bundle, now: dict[str, np.ndarray], goal: dict[str, np.ndarray],
                  goal_contacts) -> float:
    """How far (m, along world y, the offsets' axis) the step's source would land from its
    goal position, with the source's grasp point released over the target's release point."""
    action = bundle.action_of(step)
    shift = OFFSET_METRES[action.release] - OFFSET_METRES[action.grasp]
    src, tgt = action.source, action.target
    if tuple(sorted((src, tgt))) in goal_contacts:
        want = goal[src][1] - goal[tgt][1]
    else:
        want = goal[src][1] - now[tgt][1]
    return abs(shift - want)


def refine_step(bundle, step: str, rest: list[str], state: set, goal_atoms: set,
                now: dict[str, np.ndarray], goal: dict[str, np.ndarray], goal_contacts) -> str:
    """`step`, or the interchangeable step (see `equivalents`) that lands its source at
    least MIN_GAIN nearer its goal; `now` and `goal` are perceived positions by name."""
    options = equivalents(bundle, step, rest, state, goal_atoms)
    if len(options) == 1:
        return step
    contacts = {tuple(sorted(p)) for p in goal_contacts}
    errors = [landing_error(s, bundle, now, goal, contacts) for s in options]
    best = int(np.argmin(errors))
    return options[best] if errors[0] - errors[best] >= MIN_GAIN else step
