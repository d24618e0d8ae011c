"""Why the symbols plan a goal of relations, or do not: its stages planned one by one on the
learned operators (goal_plans.stages), and for the first stage that finds no plan, the
ground steps nearest to reaching it with the atoms each lacks.

A stage the symbols cannot plan is either one no operator's effect reaches (the nearest
steps still leave goal atoms unmet) or one whose operators ask for what the plan before
it does not give (they reach the goal atoms but lack preconditions): a bridge's operator
that asks its supports to stand side by side, a contact degree the stages before left
otherwise. `symplan inspect --stages` prints it; no simulator, the symbols alone.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field, replace

from drake_symplan.abstraction.goal_plans import stages
from drake_symplan.abstraction.relation_goal import BASES, stage_keys
from drake_symplan.planning.budget import Budget
from drake_symplan.symbolic.structs import Goal, Step, flat, goal_of

NEAREST = 3  # steps named for a stage with no plan
MOST_GROUNDINGS = 50_000  # ground steps looked at for them, at most


@dataclass
class Near:
    """A ground step and what it lacks: preconditions not in the state, goal atoms of the
    stage not holding after it (applied as if it could be)."""

    step: str
    missing_pre: list[str]
    missing_goal: list[str]

    @property
    def lacks(self) -> int:
        return len(self.missing_pre) + len(self.missing_goal)

    def to_json(self) -> dict:
        return {"step": self.step, "missing_pre": self.missing_pre,
                "missing_goal": self.missing_goal}


@dataclass
class StageReport:
    """One stage: the relations it adds, its new goal atoms, how its planning ended, the
    steps found, and for a stage with no plan the nearest steps (Near)."""

    relations: list[str]
    atoms: list[str]
    status: str
    seconds: float
    steps: list[str] = field(default_factory=list)
    nearest: list[Near] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"relations": self.relations, "atoms": self.atoms, "status": self.status,
                "seconds": round(self.seconds, 3), "steps": self.steps,
                "nearest": [n.to_json() for n in self.nearest]}


def diagnose(abstraction, start, goal, planner: str = "fd",
             cpu_seconds: float = 10.0) -> list[StageReport]:
    """The stages of the goal of relations `goal` (abstraction.Observation with its
    relations, as relation_goal makes it) from the reading `start`, each planned from the
    state the plans before it predict within `cpu_seconds`, up to the first that finds no
    plan (with its nearest steps)."""
    if goal.reading is None or goal.reading.pairs is None:
        raise ValueError("a stage diagnosis needs a goal of relations (relation_goal)")
    task = abstraction.task(start, goal.reading)
    parts = stages(goal.reading, task.goal)
    state, before, out = task.init, frozenset(), []
    for key, atoms in zip(stage_keys(goal.reading), parts, strict=False):
        t0 = time.perf_counter()
        stage = replace(task, init=state, goal=atoms)
        found = abstraction.plan_focused(stage, start, goal.reading, planner,
                                         Budget.of_cpu(cpu_seconds))
        new = Goal(atoms - before,
                   [c for c in goal_of(atoms).choices if c not in goal_of(before).choices])
        report = StageReport(_relations(goal, key), new.describe(),
                             found.status, time.perf_counter() - t0,
                             [str(s) for s in found.steps])
        out.append(report)
        if not found.solved:
            objects = abstraction.focus(stage, start, goal.reading) or task.objects
            report.nearest = nearest_steps(abstraction.bundle.planned, state, flat(atoms),
                                           objects)
            break
        for step in found.steps:
            state = step.apply(state)
        before = atoms
    return out


def _relations(goal, key: tuple) -> list[str]:
    """The text of the relation whose pairs make the stage `key` (layer, relation index,
    place in a row); the bridges' towers' bottoms (relation_goal.BASES): "bases of" each
    bridge."""
    if key[1] == BASES:
        return [f"bases of {r.text()}" for r in goal.relations if r.word == "bridge"]
    return [goal.relations[key[1]].text()] if key[1] < len(goal.relations) else []


def nearest_steps(operators, state: frozenset, goal: frozenset, objects,
                  most: int = NEAREST) -> list[Near]:
    """The `most` ground steps, over `objects`, that lack the fewest atoms (Near.lacks):
    of each operator, the bindings that make one of its add atoms a goal atom not in
    `state`, the rest of its parameters any of `objects` (at most MOST_GROUNDINGS)."""
    wanted = [a for a in sorted(goal) if a not in state]
    steps = (Step(op, args) for op in operators for args in _bindings(op, wanted, objects))
    seen, found = set(), []
    for step in itertools.islice(steps, MOST_GROUNDINGS):
        if str(step) in seen:
            continue
        seen.add(str(step))
        after = step.apply(state)
        found.append(Near(str(step), sorted(a.text() for a in step.pre - state),
                          sorted(a.text() for a in goal - after)))
    found.sort(key=lambda n: (n.lacks, n.step))
    return found[:most]


def _bindings(op, wanted, objects: tuple):
    """Argument tuples of `op` (distinct objects) under which one of its add atoms is one
    of the `wanted` atoms, its other parameters over `objects`."""
    for target in wanted:
        for lifted in op.add:
            if lifted[0] != target[0] or len(lifted) != len(target):
                continue
            bound = dict(zip(lifted[1:], target[1:], strict=True))
            if len(set(bound.values())) != len(bound):
                continue
            free = [i for i in range(op.n_params) if i not in bound]
            rest = [o for o in objects if o not in bound.values()]
            for chosen in itertools.permutations(rest, len(free)):
                args = {**bound, **dict(zip(free, chosen, strict=True))}
                yield tuple(args[i] for i in range(op.n_params))
