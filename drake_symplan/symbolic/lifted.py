"""The symbolic layer's vocabulary: atoms (a predicate with its arguments; lifted ones name
parameter slots) and the lifted operator both learners produce. structs.py builds on them."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property


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

    @cached_property
    def carried(self) -> int:
        """The parameters past the target that the preconditions relate to the source (a
        relation atom between them holds): the boxes the move may carry along. One related
        to the target alone (a bridge's second support, the box under a tower's top) is
        not carried."""
        return sum(any(len(a) == 3 and not a[0].startswith("not_") and {a[1], a[2]} == {0, k}
                       for a in self.pre) for k in range(2, self.n_params))

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
