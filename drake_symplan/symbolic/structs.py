"""The symbolic layer's plain data: atoms, lifted operators, ground plan steps, tasks.

Everything that plans, checks or shows a plan speaks these types (as predicators'
structs.py). An atom is a predicate with its arguments, `Atom("r0", "o1", "o2")`; lifted
atoms name parameter slots by index (`Atom("r0", 0, 1)` is `(r0 ?o0 ?o1)`). A
`LiftedOperator` is what both learners produce (effect-first and the paper's); a
`PlanningOperator` is what the planner sees: the learned operators that differ in their
offsets only (`PlanningOperators` groups a list of them). A `Step` binds an operator to
objects, a `Reposition` is the agent's move that no operator names. Plan
steps are parsed once (`parse_step`), where they come back from the planner; `apply` is
the one place an effect is applied to a state. Atoms and lifted operators are made in
lifted.py; their names stay importable from here.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property

from drake_symplan.actions import OFFSETS, Action
from drake_symplan.symbolic.lifted import Atom as Atom
from drake_symplan.symbolic.lifted import LiftedOperator as LiftedOperator
from drake_symplan.symbolic.lifted import apply as apply
from drake_symplan.symbolic.lifted import bit_key as bit_key
from drake_symplan.symbolic.lifted import distinct_parameters as distinct_parameters
from drake_symplan.symbolic.lifted import operator_name as operator_name
from drake_symplan.symbolic.lifted import parameter_names as parameter_names


@dataclass(frozen=True, eq=False)
class Step:
    """A ground plan step: `operator` bound to `args` (source and target first)."""

    operator: LiftedOperator
    args: tuple[str, ...]

    @property
    def action(self) -> Action:
        return Action(self.args[0], self.operator.grasp, self.args[1], self.operator.release)

    # Ground once per step: the offset choice checks a plan's rest many times.
    @cached_property
    def pre(self) -> frozenset:
        return frozenset(a.ground(self.args) for a in self.operator.pre)

    @cached_property
    def add(self) -> frozenset:
        return frozenset(a.ground(self.args) for a in self.operator.add)

    @cached_property
    def delete(self) -> frozenset:
        return frozenset(a.ground(self.args) for a in self.operator.delete)

    def applicable(self, state) -> bool:
        return self.pre <= state

    def apply(self, state) -> frozenset:
        return apply(state, self.add, self.delete)

    def with_operator(self, operator: LiftedOperator) -> Step:
        return Step(operator, self.args)

    def __str__(self) -> str:
        return f"({self.operator.name} {' '.join(self.args)})"

    def __eq__(self, other) -> bool:
        return isinstance(other, Step) and str(self) == str(other)

    def __hash__(self) -> int:
        return hash(str(self))


def _signature(op: LiftedOperator) -> tuple:
    """What the planner tells operators apart by: arity, preconditions and effects."""
    return op.n_params, frozenset(op.pre), frozenset(op.add), frozenset(op.delete)


@dataclass(frozen=True, eq=False)
class PlanningOperator:
    """An operator over objects only: the learned operators (`variants`, most frequent
    first) with the same preconditions and effects, which differ in their offsets only.
    The planner sees it as its `planned` variant (the cheapest, the more frequent on a
    tie), whose name its plan steps carry; the offsets a step runs with are chosen among
    the variants (abstraction/offsets.py)."""

    variants: tuple[LiftedOperator, ...]

    @cached_property
    def planned(self) -> LiftedOperator:
        return min(self.variants, key=lambda op: op.cost)  # the first of the cheapest

    def fits(self, args, rest: Sequence, state, goal) -> bool:
        """Does it apply to `args` in `state`, and does `rest` then still reach `goal`?"""
        step = Step(self.planned, tuple(args))
        return step.applicable(state) and reaches(rest, step.apply(state), goal)


class PlanningOperators:
    """A list of learned operators as the planner sees them: one PlanningOperator per
    preconditions and effects (`operators`, in the order of their planned variants), and
    the offset variants a step may run with (`variants`)."""

    def __init__(self, learned: Iterable[LiftedOperator]):
        self.learned = list(learned)
        groups: dict[tuple, list[int]] = {}  # positions in `learned` (no ids: it pickles)
        for i, op in enumerate(self.learned):
            groups.setdefault(_signature(op), []).append(i)
        members = [(PlanningOperator(tuple(self.learned[i] for i in g)), g)
                   for g in groups.values()]
        members.sort(key=lambda pair: self.learned.index(pair[0].planned))
        self.operators = [p for p, _ in members]
        self._group = [0] * len(self.learned)  # each learned operator's in `operators`
        for k, (_, positions) in enumerate(members):
            for i in positions:
                self._group[i] = k

    @property
    def planned(self) -> list[LiftedOperator]:
        """The operators the planner's domain has (pddl.domain_pddl, grounding)."""
        return [p.planned for p in self.operators]

    def variants(self, step: Step, rest: Sequence, state, goal) -> list[Step]:
        """`step`, then its objects bound to every other learned operator of its arity
        whose planning operator `fits` there (its own variants among them), in the
        learned operators' order: the candidates for the step's offsets."""
        fits: dict[int, bool] = {}
        out = [step]
        for op, k in zip(self.learned, self._group, strict=True):
            if op.n_params != step.operator.n_params or op is step.operator:
                continue
            if k not in fits:
                fits[k] = self.operators[k].fits(step.args, rest, state, goal)
            if fits[k]:
                out.append(step.with_operator(op))
        return out


MOVE_KINDS = ("reposition", "move")


@dataclass(frozen=True)
class Reposition:
    """A step no operator names: the pick/place `action` chosen for where it puts the
    boxes, not for a symbolic effect, so it predicts none. `kind` "reposition": a box put
    down beside another at its goal spot (agent/reposition.py, bilevel extra moves); "move": a
    step of a plan found in continuous space (abstraction/bilevel.py)."""

    action: Action
    kind: str = "reposition"

    def __post_init__(self):
        if self.kind not in MOVE_KINDS:
            raise ValueError(f"unknown move kind {self.kind!r}; one of {MOVE_KINDS}")

    def applicable(self, state) -> bool:
        return True

    def apply(self, state) -> frozenset:
        return frozenset(state)

    def __str__(self) -> str:
        a = self.action
        return f"({self.kind}_{a.grasp}_{a.release} {a.source} {a.target})"


PlanStep = Step | Reposition

_STEP = re.compile(
    r"^pick_(?P<grasp>[a-z]+)_place_(?P<release>[a-z]+)_n(?P<count>\d+)_op(?P<index>\d+)$")
_MOVE = re.compile(r"^(?P<kind>reposition|move)_(?P<grasp>[a-z]+)_(?P<release>[a-z]+)$")


def parse_step(text: str, operators: Mapping[str, LiftedOperator]) -> PlanStep:
    """`(pick_center_place_right_n736_op19 o3 o1 o2)` -> the Step of that operator (by
    name in `operators`) on o3, o1, o2; `(reposition_center_right o1 o0)` or
    `(move_center_right o1 o0)` -> a Reposition of that kind. ValueError otherwise."""
    tokens = text.strip().strip("()").lower().split()
    if len(tokens) < 3:
        raise ValueError(f"plan step {text!r} has no source and target arguments")
    name, args = tokens[0], tuple(tokens[1:])
    m = _MOVE.match(name)
    if m and m["grasp"] in OFFSETS and m["release"] in OFFSETS and len(args) == 2:
        return Reposition(Action(args[0], m["grasp"], args[1], m["release"]), m["kind"])
    m = _STEP.match(name)
    if not m or m["grasp"] not in OFFSETS or m["release"] not in OFFSETS:
        raise ValueError(f"{tokens[0]!r} is not a learned pick/place operator name")
    if name not in operators:
        raise ValueError(f"plan step {text!r} names no operator of the domain")
    op = operators[name]
    if len(args) != op.n_params:
        raise ValueError(f"plan step {text!r} has {len(args)} arguments, {name} takes "
                         f"{op.n_params}")
    return Step(op, args)


def other_outcomes(steps: Sequence[PlanStep], init, operators: Iterable[LiftedOperator]
                   ) -> list[list[Step]]:
    """Per plan step, what else the training data saw after the same action where the
    step applies: the other learned operators with its offsets that apply to its objects
    (its first n_params ones) in the state the plan reaches there, one per effect (other
    than the step's), most reliable first.
    Where an action's symbolic outcome branches, these are the branches; the planner
    took the step's own. None are known after a move no operator names."""
    operators = list(operators)
    state, out = frozenset(init), []
    for step in steps:
        if state is None or isinstance(step, Reposition):
            out.append([])
            state = None
            continue
        op = step.operator
        others = [Step(o, step.args[:o.n_params]) for o in operators
                  if o is not op and (o.grasp, o.release) == (op.grasp, op.release)
                  and o.n_params <= len(step.args)]
        branches, seen = [], {(step.add, step.delete)}
        for s in sorted((s for s in others if s.applicable(state)),
                        key=lambda s: (-s.operator.reliability, s.operator.index)):
            if (s.add, s.delete) not in seen:  # one row per effect: its likeliest operator
                seen.add((s.add, s.delete))
                branches.append(s)
        out.append(branches)
        state = step.apply(state)
    return out


class Goal(frozenset):
    """Goal atoms, all wanted, and `choices`: per named pair (its key, the pair of
    objects) alternative sets of atoms, any one of which will do (a goal relation read in
    the discovered symbols, symbolic/relation_patterns.py; the example's own reading
    first). `goal <= state` holds where the atoms and one set of each choice do; a plain
    frozenset is a Goal without choices. The planners compile the choices
    (planning/grounding.py); where one cannot, it plans the first of each (`flat`)."""

    choices: tuple = ()

    def __new__(cls, atoms: Iterable = (), choices: Iterable = ()):
        out = super().__new__(cls, atoms)
        out.choices = tuple((tuple(key), tuple(frozenset(a) for a in alternatives))
                            for key, alternatives in choices)
        return out

    def __reduce__(self):
        return Goal, (frozenset(self), self.choices)

    def __le__(self, other) -> bool:
        return frozenset(self) <= other and not self.open_choices(other)

    issubset = __le__

    def open_choices(self, state) -> list[tuple]:
        """The choices none of whose sets holds in `state`."""
        return [(key, alts) for key, alts in self.choices if not any(a <= state for a in alts)]

    def describe(self) -> list[str]:
        """The goal as lines: each atom, then each choice as its sets, "one of" them."""
        def text(atoms) -> str:
            return ", ".join(sorted(Atom.of(a).text() for a in atoms)) or "(nothing)"

        return sorted(Atom.of(a).text() for a in self) + [
            "one of: " + " | ".join(text(a) for a in alternatives)
            for _, alternatives in self.choices]

    def restricted(self, keep) -> Goal:
        """The goal over the objects in `keep` only."""
        return Goal((a for a in self if set(a[1:]) <= keep),
                    [(k, alts) for k, alts in self.choices if set(k) <= keep])


def goal_of(atoms) -> Goal:
    """`atoms` as a Goal (itself where it is one)."""
    return atoms if isinstance(atoms, Goal) else Goal(atoms)


def flat(goal) -> frozenset:
    """A goal's atoms with the first set of each choice (the example's reading)."""
    return frozenset(goal).union(*(alts[0] for _, alts in goal_of(goal).choices if alts))


def reaches(steps: Iterable[PlanStep], state, goal) -> bool:
    """Do `steps` apply one after the other from `state` and end where `goal` holds?"""
    state = frozenset(state)
    for step in steps:
        if not step.applicable(state):
            return False
        state = step.apply(state)
    return (goal if isinstance(goal, frozenset) else frozenset(goal)) <= state


@dataclass(frozen=True)
class Task:
    """A planning task: objects, the initial atoms, the goal atoms."""

    objects: tuple[str, ...]
    init: frozenset
    goal: frozenset
    name: str = "goal"
    unknown: frozenset = field(default=frozenset())  # keys of bits read as uncertain

    def restricted(self, objects: Iterable[str]) -> Task:
        """The task over `objects` only (in this task's order), atoms over others left out."""
        keep = set(objects)
        return Task(tuple(o for o in self.objects if o in keep),
                    frozenset(a for a in self.init if set(a[1:]) <= keep),
                    goal_of(self.goal).restricted(keep), self.name, self.unknown)

    @property
    def solved(self) -> bool:
        return goal_of(self.goal) <= self.init
