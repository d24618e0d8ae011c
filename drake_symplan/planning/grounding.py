"""A symbolic task grounded on lifted operators here, written as Fast Downward's SAS+
input, so that a plan costs only FD's search binary: its translator (an interpreter
start, PDDL parsing, Datalog grounding, invariant synthesis) is most of a small task's
call (tools/bench_planner.py).

Grounding keeps what the translator keeps: the actions reachable from the initial state
in the delete relaxation, parameters bound to distinct objects (the PDDL's `different`
facts). An atom no reachable action adds or deletes is static and leaves the task; every
other atom is a variable of two values, true and false (the translator would merge an
atom with its explicit `not_` twin; the search's heuristics read the same relaxed task
either way, since no precondition or goal asks for an atom to be false). A goal atom
that is not reachable proves the task unsolvable before any search.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from drake_symplan.planning.planners import (
    DEFAULT_TIMEOUT,
    FD_SEARCH,
    PlanResult,
    fast_downward_sas,
)
from drake_symplan.symbolic.structs import Atom, LiftedOperator, Task, goal_of

TRUE, FALSE = 0, 1  # variable values, as the translator numbers an atom's


@dataclass(frozen=True)
class GroundAction:
    name: str  # "pick_center_place_right_n736_op19 o3 o1", as a plan step reads it
    pre: frozenset
    add: frozenset
    delete: frozenset
    cost: int


@dataclass
class GroundTask:
    """The reachable part of a task: its variables (non-static atoms), actions, initial
    state and goal; `unreachable`: the goal atoms no action can make true; `choices`: of
    a goal's choices (structs.Goal), the sets still reachable, each cut to its variables
    (empty: a set that holds for good), with the cost of taking it."""

    variables: list[Atom]
    actions: list[GroundAction]
    init: frozenset
    goal: frozenset
    unreachable: frozenset
    choices: list[list[tuple[frozenset, int]]] = field(default_factory=list)

    def solved(self) -> bool:
        """Does the goal hold in the initial state?"""
        return self.goal <= self.init and all(any(a <= self.init for a, _ in alternatives)
                                              for alternatives in self.choices)


def _slot_order(op: LiftedOperator) -> list[list[tuple[str, tuple[int, ...]]]]:
    """The operator's precondition atoms by the last slot they bind, so a binding is
    checked as soon as its slots are filled: (predicate, slots) per atom."""
    by_slot: list[list[tuple[str, tuple[int, ...]]]] = [[] for _ in range(op.n_params)]
    for atom in op.pre:
        by_slot[max(atom[1:])].append((atom[0], tuple(atom[1:])))
    return by_slot


def _bindings(n_params: int, by_slot: list[list[tuple[str, tuple[int, ...]]]],
              objects: Sequence[str], facts: set) -> Iterable[tuple[str, ...]]:
    """Every binding of an operator's slots to distinct objects under which its
    preconditions (`by_slot`, _slot_order) are in `facts`."""
    args: list[str] = []

    def extend(i: int):
        if i == n_params:
            yield tuple(args)
            return
        for obj in objects:
            if obj in args:
                continue
            args.append(obj)
            # a plain tuple hashes and compares as the Atom it grounds
            if all((p, *[args[j] for j in slots]) in facts for p, slots in by_slot[i]):
                yield from extend(i + 1)
            args.pop()

    yield from extend(0)


def _grounder(atoms: Sequence[Atom]):
    """args -> the frozenset of `atoms` with their slots bound to args (Atom.ground)."""
    spec = [(a[0], a[1:]) for a in atoms]
    make = tuple.__new__
    return lambda args: frozenset([make(Atom, (p, *[args[i] for i in slots]))
                                   for p, slots in spec])


class OutOfTime(Exception):
    """Grounding ran past its plan's budget."""


_REACHED: dict[tuple, tuple[dict, frozenset]] = {}  # the last CACHED tasks' reachability
CACHED = 8
# (operator, args) -> its ground (pre, add, delete): the same whatever the state, and
# building them was half of grounding; the stages and replans of a goal ground the same
# boxes again and again. Emptied at ATOMS_KEPT entries (sixteen boxes: 170,000 actions).
_ATOMS: dict[tuple, tuple[frozenset, frozenset, frozenset]] = {}
ATOMS_KEPT = 400_000
# Operators grounded between two asks of the budget: a CPU clock read costs 0.2 ms on a
# busy host, and asked per operator it took 8 % of the plans of eight boxes
TIME_CHECKS = 16


def _reachable(operators: tuple[LiftedOperator, ...], objects: tuple[str, ...],
               init: frozenset, out_of_time=lambda: False) -> tuple[dict, frozenset]:
    """({(operator, args): (pre, add, delete)} of the actions reachable from `init` in the
    delete relaxation, the facts reached); OutOfTime where `out_of_time()` says so, asked
    every TIME_CHECKS operators a round (sixteen boxes ground 170,000 actions in 15 to
    30 s). The
    skeletons of one plan ground the same task twice (with other penalties): cached."""
    key = (operators, objects, init)
    if key in _REACHED:
        return _REACHED[key]
    if len(_ATOMS) > ATOMS_KEPT:
        _ATOMS.clear()
    ops = [(op, _slot_order(op), _grounder(op.pre), _grounder(op.add), _grounder(op.delete))
           for op in operators if op.n_params <= len(objects)]
    facts = set(init)
    found: dict[tuple[LiftedOperator, tuple[str, ...]], tuple] = {}
    grown = True
    while grown:  # relaxed reachability to a fixpoint
        grown = False
        for k, (op, by_slot, pre, add, delete) in enumerate(ops):
            if k % TIME_CHECKS == 0 and out_of_time():
                raise OutOfTime
            for args in list(_bindings(op.n_params, by_slot, objects, facts)):
                if (op, args) in found:
                    continue
                atoms = _ATOMS.get((op, args))
                if atoms is None:
                    adds = add(args)
                    atoms = _ATOMS[op, args] = (pre(args), adds, delete(args) - adds)
                found[op, args] = atoms
                grown |= not atoms[1] <= facts
                facts |= atoms[1]
    if len(_REACHED) >= CACHED:
        del _REACHED[next(iter(_REACHED))]
    _REACHED[key] = found, frozenset(facts)
    return _REACHED[key]


def ground(operators: Sequence[LiftedOperator], task: Task,
           penalties: Mapping[tuple[str, ...], int] | None = None,
           carry_cost: int = 0, out_of_time=lambda: False) -> GroundTask:
    """The task's reachable actions and variables (module docstring); `penalties`: cost
    added to every action whose arguments begin with the key: (source, target) for every
    move of the pair whatever its offsets, longer keys for those that also name the
    others (a carry's riders); `carry_cost`: added per rider an action carries;
    OutOfTime where `out_of_time()` says so while the reachable actions are found."""
    penalties = penalties or {}
    lengths = sorted({len(key) for key in penalties})
    found, facts = _reachable(tuple(operators), tuple(task.objects), frozenset(task.init),
                              out_of_time)
    changing = set().union(*(add | delete for _, add, delete in found.values())) & facts
    kept = []
    for (op, args), (pre, add, delete) in found.items():
        act = GroundAction(f"{op.name} {' '.join(args)}", pre & changing, add - pre,
                           delete & changing,
                           op.cost + carry_cost * op.carried
                           + sum(penalties.get(args[:n], 0) for n in lengths
                                 if n <= len(args)))
        if act.add or act.delete:
            kept.append(act)
    kept = undominated(kept)
    goal = goal_of(task.goal)
    choices = [[(a & changing, 0 if k == 0 else OTHER_READING_COST)
                for k, a in enumerate(alternatives) if a <= facts]
               for _, alternatives in goal.choices]
    unreachable = frozenset(goal) - facts
    for (_, alternatives), reachable in zip(goal.choices, choices, strict=True):
        if not reachable:  # no set of the choice can hold: report the first's atoms
            unreachable |= alternatives[0] - facts if alternatives else frozenset()
    return GroundTask(sorted(changing), kept, frozenset(task.init) & changing,
                      frozenset(goal) & changing, unreachable, choices)


def undominated(actions: Sequence[GroundAction]) -> list[GroundAction]:
    """`actions` without those another dominates: the same effects (adds and deletes),
    preconditions it holds a subset of, a cost no higher (the first of equals stays). A
    plan with a dominated action is no cheaper with it, so a cost-optimal search finds
    a plan as cheap without; operators learned with their offsets share effects (a
    quarter of a bridge stage's 4,100 actions at eight boxes go), and the search's
    heuristic costs grow with the actions."""
    groups: dict[tuple[frozenset, frozenset], list[GroundAction]] = {}
    for act in sorted(actions, key=lambda a: (a.cost, len(a.pre))):
        kept = groups.setdefault((act.add, act.delete), [])
        if not any(k.pre <= act.pre for k in kept):
            kept.append(act)
    stays = {id(a) for kept in groups.values() for a in kept}
    return [a for a in actions if id(a) in stays]


CHOICE = "goal-choice"  # the plan steps that pick a choice's set (no operator's name)
# A goal choice's set other than its first (a pair read by a kept pattern of its kind,
# not as the example reads it: structs.Goal) costs half a sure move (the task's action
# costs are the operators' doubled, CHOICE_SCALE; an operator's own cost is at least 1):
# of plans of equal moves, the one to the example's reading; a shorter one to a kept
# pattern. With no preference, the planner set a cube 7.5 cm off a block's centre, an
# operator whose unreliable effect reads a kept pattern of "on", where a centred
# placement gives the example's reading: the written towers of four fell from 8 to 5
# of 10 with the symbols alone.
OTHER_READING_COST = 1
CHOICE_SCALE = 2


def sas_text(task: GroundTask) -> str:
    """The task in FD's SAS+ format, version 3, with action costs. A goal's choices are
    compiled as disjunctive goals are: a variable `acting`, true at the start and asked
    by every action, and per choice a variable its goal; per set of a choice an action
    (named CHOICE) that asks for the set, makes the choice's variable true and `acting`
    false, so no action follows it and the sets hold at the plan's end: of cost 0 for a
    choice's first set, OTHER_READING_COST for the others (the actions' costs then
    CHOICE_SCALE times their own)."""
    index = {atom: i for i, atom in enumerate(task.variables)}
    names = [f"Atom {a[0]}({', '.join(a[1:])})" for a in task.variables]
    acting = len(names) if task.choices else None
    if task.choices:
        names += ["Atom acting()"] + [f"Atom chosen{i}()" for i in range(len(task.choices))]
    lines = ["begin_version", "3", "end_version", "begin_metric", "1", "end_metric",
             str(len(names))]
    for i, text in enumerate(names):
        lines += ["begin_variable", f"var{i}", "-1", "2", text, "Negated" + text,
                  "end_variable"]
    init = [TRUE if atom in task.init else FALSE for atom in task.variables]
    if task.choices:
        init += [TRUE] + [FALSE] * len(task.choices)
    goal = [index[a] for a in sorted(task.goal)]
    goal += [acting + 1 + i for i in range(len(task.choices))]
    lines += ["0", "begin_state", *map(str, init), "end_state", "begin_goal", str(len(goal))]
    lines += [f"{v} {TRUE}" for v in goal]
    actions = [(act.name, sorted(index[a] for a in act.pre - act.delete),
                [(index[a], -1, TRUE) for a in act.add]
                + [(index[a], TRUE if a in act.pre else -1, FALSE) for a in act.delete],
                act.cost * (CHOICE_SCALE if task.choices else 1)) for act in task.actions]
    if task.choices:
        actions = [(n, sorted([*prevail, acting]), effects, cost)
                   for n, prevail, effects, cost in actions]
        actions += [(f"{CHOICE} {i} {k}", sorted(index[a] for a in alternative),
                     [(acting + 1 + i, -1, TRUE), (acting, -1, FALSE)], cost)
                    for i, alternatives in enumerate(task.choices)
                    for k, (alternative, cost) in enumerate(alternatives)]
    lines += ["end_goal", str(len(actions))]
    for name, prevail, effects, cost in actions:
        lines += ["begin_operator", name, str(len(prevail))]
        lines += [f"{v} {TRUE}" for v in prevail]
        lines += [str(len(effects))]
        lines += [f"0 {v} {pre} {post}" for v, pre, post in sorted(effects)]
        lines += [str(cost), "end_operator"]
    lines += ["0"]
    return "\n".join(lines) + "\n"


def fast_downward_task(operators: Sequence[LiftedOperator], task: Task,
                       wall_seconds: float = DEFAULT_TIMEOUT, search: str = FD_SEARCH,
                       cpu_seconds: float | None = None,
                       penalties: Mapping[tuple[str, ...], int] | None = None,
                       carry_cost: int = 0) -> PlanResult:
    """Fast Downward's search on `task` grounded here (with `penalties`, see `ground`);
    the grounding's CPU time (this thread's: `eval operators` plans in threads) counts
    against `cpu_seconds` and its seconds against `wall_seconds`."""
    start, cpu0 = time.perf_counter(), time.thread_time()

    def result(status, message=""):
        return PlanResult(status, [], time.perf_counter() - start, message, "fd")

    def out_of_time() -> bool:
        return time.perf_counter() - start > wall_seconds or (
            cpu_seconds is not None and time.thread_time() - cpu0 > cpu_seconds)

    try:
        grounded = ground(operators, task, penalties, carry_cost, out_of_time)
    except OutOfTime:
        return result("timeout", "grounding out of time")

    if grounded.unreachable:
        atoms = ", ".join(Atom.of(a).text() for a in sorted(grounded.unreachable)[:3])
        return result("unsolvable", f"unsolvable (proved by grounding: no action reaches "
                                    f"{atoms})")
    if grounded.solved():
        return result("solved")
    used = time.perf_counter() - start
    found = fast_downward_sas(sas_text(grounded), max(wall_seconds - used, 1e-3), search,
                              None if cpu_seconds is None else
                              max(cpu_seconds - (time.thread_time() - cpu0), 1e-3))
    found.seconds += used
    found.plan = [step for step in found.plan if not step.startswith(f"({CHOICE}")]
    return found
