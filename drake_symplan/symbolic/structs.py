"""The symbolic layer's plain data: atoms, lifted operators, ground plan steps, tasks.

Everything that plans, checks or shows a plan speaks these types (as predicators'
structs.py). An atom is a predicate with its arguments, `Atom("r0", "o1", "o2")`; lifted
atoms name parameter slots by index (`Atom("r0", 0, 1)` is `(r0 ?o0 ?o1)`). A
`LiftedOperator` is what both learners produce (effect-first and the paper's); a
`PlanningOperator` is what the planner sees: the learned operators that differ in their
offsets only (`PlanningOperators` groups a list of them). A `Step` binds an operator to
objects, a `Reposition` is the agent's move that no operator names. Plan
steps are parsed once (`parse_step`), where they come back from the planner; `apply` is
the one place an effect is applied to a state.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property

from drake_symplan.actions import OFFSETS, Action


class Atom(tuple):
    """(predicate, arg, ...): a tuple, so atoms and plain tuples compare and hash alike."""

    __slots__ = ()

    def __new__(cls, predicate: str, *args):
        return super().__new__(cls, (predicate, *args))

    def __getnewargs__(self):  # pickle (Ray ships bundles) calls __new__(cls, *these)
        return tuple(self)

    @classmethod
    def of(cls, items: Iterable) -> Atom:
        """From any sequence (predicate, arg, ...), e.g. a row of operators.json."""
        return items if isinstance(items, Atom) else cls(*items)

    @property
    def predicate(self) -> str:
        return self[0]

    @property
    def args(self) -> tuple:
        return self[1:]

    key = property(lambda self: bit_key(self))

    def ground(self, args: Sequence[str]) -> Atom:
        """A lifted atom (slot indices) with its slots bound to `args`."""
        return tuple.__new__(Atom, (self[0], *(args[i] for i in self[1:])))

    def lifted(self) -> Atom:
        """A slot atom as PDDL parameters: ("r0", 0, 1) -> ("r0", "?o0", "?o1")."""
        return Atom(self[0], *(f"?o{i}" for i in self[1:]))

    def text(self) -> str:
        """'r0(o1, o2)', for people."""
        return f"{self[0]}({', '.join(map(str, self[1:]))})"

    def pddl(self) -> str:
        return "(" + " ".join(map(str, self)) + ")"


def bit_key(atom: tuple) -> tuple:
    """The bit an atom speaks of: (symbol, args), polarity dropped."""
    return (atom[0].removeprefix("not_"), *atom[1:])


def apply(state: frozenset | set, add: Iterable, delete: Iterable) -> frozenset:
    """The state after an effect: delete, then add (STRIPS)."""
    return (frozenset(state) - frozenset(delete)) | frozenset(add)


def parameter_names(n: int) -> tuple[str, ...]:
    """?o0 (the source), ?o1 (the target), ?o2, ..."""
    return tuple(f"?o{i}" for i in range(n))


def distinct_parameters(n: int) -> list[Atom]:
    """`(different ?oi ?oj)` for i < j: positive STRIPS keeps the parameters distinct."""
    return [Atom("different", f"?o{i}", f"?o{j}") for i in range(n) for j in range(i + 1, n)]


def operator_name(grasp: str, release: str, count: int, index: int) -> str:
    """Action schema name: offsets, group count and frequency rank, e.g.
    `pick_center_place_right_n736_op19` (see `parse_step`)."""
    return f"pick_{grasp}_place_{release}_n{count}_op{index}"


def _slot_atoms(atoms: Iterable) -> tuple[Atom, ...]:
    return tuple(Atom.of(a) for a in atoms)


@dataclass(eq=False)
class LiftedOperator:
    """A lifted pick/place operator over ?o0 (source), ?o1 (target), ?o2...: slot atoms
    for its preconditions, add and delete lists, and how it did on the training data.

    `reliability` is how often its effect followed where its preconditions held for its
    action (effect-first learner; 0 when not measured); `cost` = 1 + round(cost_scale *
    -ln reliability) is its plan cost. `outcomes` and `effect_count`: distinct effects in
    its group and how many transitions had this one (the paper's learner groups by
    preconditions, so a group has several); `example`: one transition with this effect
    and that transition's object slot per parameter."""

    index: int
    grasp: str
    release: str
    n_params: int
    pre: tuple[Atom, ...]
    add: tuple[Atom, ...]
    delete: tuple[Atom, ...]
    count: int  # transitions in the group
    applicable: int = 0
    succeeded: int = 0
    cost_scale: float = 10.0
    outcomes: int = 1
    effect_count: int | None = None
    example: int = -1
    example_slots: tuple[int, ...] = ()

    def __post_init__(self):
        self.pre, self.add, self.delete = (_slot_atoms(x) for x in (self.pre, self.add,
                                                                   self.delete))
        self.example_slots = tuple(self.example_slots)

    @property
    def reliability(self) -> float:
        return self.succeeded / self.applicable if self.applicable else 0.0

    @property
    def cost(self) -> int:
        return 1 + round(self.cost_scale * -math.log(max(self.reliability, 1e-3)))

    @property
    def name(self) -> str:
        return operator_name(self.grasp, self.release, self.count, self.index)

    @property
    def params(self) -> tuple[str, ...]:
        return parameter_names(self.n_params)

    def preconditions(self) -> list[Atom]:
        """PDDL preconditions: `different` for each parameter pair, then the slot atoms."""
        return distinct_parameters(self.n_params) + [a.lifted() for a in self.pre]

    def effects(self) -> tuple[list[Atom], list[Atom]]:
        return [a.lifted() for a in self.add], [a.lifted() for a in self.delete]

    def describe(self, n_transitions: int | None = None) -> str:
        of = f" of {n_transitions}" if n_transitions else ""
        if not self.applicable and self.effect_count is not None:
            return (f"rank {self.index}: {self.count}{of} transitions; this effect in "
                    f"{self.effect_count} ({self.outcomes} distinct effect(s))")
        return (f"rank {self.index}: {self.count}{of} transitions; reliability "
                f"{self.reliability:.2f} ({self.succeeded}/{self.applicable}), cost {self.cost}")

    def to_dict(self) -> dict:
        """The operator's entry in operators.json (symbolic/bundle.py: operators_json)."""
        add, delete = self.effects()
        return {
            "index": self.index, "name": self.name, "grasp": self.grasp,
            "release": self.release, "count": self.count, "n_params": self.n_params,
            "params": list(self.params),
            "preconditions": [" ".join(a) for a in self.preconditions()],
            "add": [" ".join(a) for a in add], "delete": [" ".join(a) for a in delete],
            "pre_slots": [list(a) for a in self.pre], "add_slots": [list(a) for a in self.add],
            "delete_slots": [list(a) for a in self.delete],
            "reliability": self.reliability, "applicable": self.applicable,
            "succeeded": self.succeeded, "cost": self.cost, "cost_scale": self.cost_scale,
            "outcomes": self.outcomes, "effect_count": self.effect_count,
            "example": self.example, "example_slots": list(self.example_slots),
        }

    @classmethod
    def from_dict(cls, d: Mapping, cost_scale: float = 10.0) -> LiftedOperator:
        return cls(d["index"], d["grasp"], d["release"], d["n_params"], d["pre_slots"],
                   d["add_slots"], d["delete_slots"], d["count"], d.get("applicable", 0),
                   d.get("succeeded", 0), d.get("cost_scale", cost_scale),
                   d.get("outcomes", 1), d.get("effect_count"), d.get("example", -1),
                   d.get("example_slots", ()))


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


def reaches(steps: Iterable[PlanStep], state, goal) -> bool:
    """Do `steps` apply one after the other from `state` and end where `goal` holds?"""
    state = frozenset(state)
    for step in steps:
        if not step.applicable(state):
            return False
        state = step.apply(state)
    return set(goal) <= state


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

        def kept(atoms):
            return frozenset(a for a in atoms if set(a[1:]) <= keep)

        return Task(tuple(o for o in self.objects if o in keep), kept(self.init),
                    kept(self.goal), self.name, self.unknown)

    @property
    def solved(self) -> bool:
        return self.goal <= self.init
