"""The abstraction the agent plans with: perceived scene -> symbols -> atoms -> task -> plan.

`Abstraction(bundle)` holds the verbs over a model bundle's data (symbolic/bundle.py):
`read` a perceived scene's symbols (learning's read-out), its `atoms` under the bundle's
semantics, the `task` from a start to a goal reading, the `focus` objects, `plan` (Fast
Downward on the task grounded in process, or a back-end on the bundle's PDDL domain) into
typed steps parsed once where the planner returns them, and the checks the closed loop
makes on a step (`mismatches`). The solve loop, `symplan inspect`, the demo, bench_solve
and `eval operators` all use it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.goal_plans import plan_goal
from drake_symplan.abstraction.relation_goal import pair_choices, pair_of, unheld_readings
from drake_symplan.boxes import CONTACT_TOLERANCE, neighbour_pairs
from drake_symplan.learning.readout import read_symbols
from drake_symplan.planning.budget import Budget
from drake_symplan.planning.grounding import fast_downward_task
from drake_symplan.planning.planners import DEFAULT_TIMEOUT, PlanResult, plan_pddl, search_binary
from drake_symplan.symbolic.bundle import ModelBundle
from drake_symplan.symbolic.pddl import problem_from_atoms
from drake_symplan.symbolic.states import SymbolicState, check_name
from drake_symplan.symbolic.structs import (
    Atom,
    Goal,
    PlanStep,
    Step,
    Task,
    flat,
    goal_of,
    parse_step,
)

# A move's plan cost per box it carries, where a goal of relations leaves the order of
# the moves free: the arm keeps a rider on 26 of 45 carries (the carry suite,
# tools/bench_carry.py), -ln(26/45) at the operators' cost scale of 10. A whole-scene
# goal is planned without it, as it always was.
CARRY_COST = 5


@dataclass
class Reading:
    """The symbols of one perceived scene, with the bits read too close to call and the
    pairs perceived in contact."""

    state: SymbolicState
    unary_uncertain: np.ndarray  # [n, P] bool
    relational_uncertain: np.ndarray  # [K, n, n] bool
    contacts: set = field(default_factory=set)  # {(a, b)} related: the relevance graph
    # A goal of relations (relations.py): the (upper, lower) pairs they name, each
    # with (the layer its lower box stands in in the example, 0 on the table; the index of
    # its relation; its place in a row); its goal atoms are those pairs' relation atoms
    # alone (goal_atoms, stages).
    # None: a whole-scene goal.
    pairs: dict | None = None
    # The pairs in contact, which the degree atoms count, where the relevance graph is
    # wider (vicinity); None: `contacts`.
    touching: set | None = None
    # A goal of relations: the kind of each of its pairs (relations.PAIR_KINDS)
    kinds: dict | None = None

    @property
    def objects(self) -> tuple[str, ...]:
        return self.state.objects

    def contact_matrix(self, touching: bool = False) -> np.ndarray:
        """[n, n] bool of the related pairs, or with `touching` of the pairs in contact."""
        names = {n: i for i, n in enumerate(self.objects)}
        c = np.zeros((len(names), len(names)), bool)
        pairs = self.touching if touching and self.touching is not None else self.contacts
        for a, b in pairs:
            c[names[a], names[b]] = c[names[b], names[a]] = True
        return c


@dataclass(frozen=True)
class Observation:
    """One perceived scene as planning sees it, each view made once: the scene
    (perception's PerceivedScene: names, features(), contacts, objects), its symbols
    (`reading`) and the continuous model's view of it (`boxes`). `Abstraction.observe`
    makes one."""

    scene: object
    reading: Reading | None
    boxes: Boxes
    relations: tuple = ()  # a goal of relations (relations.Relation); (): a whole scene


@dataclass(frozen=True)
class Level:
    """What the level that found a plan implies for running it: `predicts_positions`, the
    plan carries the scene predicted after each step and is monitored on positions (else
    on its symbols); `symbolic`, a plan on symbols alone, which the agent completes as it
    runs: offsets (abstraction/offsets.py, the geometric scorer) and repositionings
    (agent/reposition.py); `subgoal`, the plan reaches a subgoal on the way (a skeleton's
    first steps, bilevel.py's receding horizon): at its end the agent plans again from
    what it sees, a replan the plan scheduled rather than a departure."""

    name: str
    predicts_positions: bool
    symbolic: bool
    subgoal: bool = False


# Plan.level's values: the symbolic planner's plan, its plan of a goal of relations' first
# stages (the rest planned from what is seen then: goal_plans.plan_stages), a refined
# skeleton, a skeleton's first steps refined to its subgoal, the continuous search's
# plan, the steps predicted nearest the goal (bilevel.py), the oracle's replay.
LEVELS = {level.name: level for level in (
    Level("symbolic", predicts_positions=False, symbolic=True),
    Level("staged", predicts_positions=False, symbolic=True, subgoal=True),
    Level("bilevel", predicts_positions=True, symbolic=False),
    Level("receding", predicts_positions=True, symbolic=False, subgoal=True),
    Level("continuous", predicts_positions=True, symbolic=False),
    Level("nearest", predicts_positions=True, symbolic=False),
    Level("oracle", predicts_positions=False, symbolic=False))}


@dataclass
class Plan:
    """What planning gives: the status (planning.planners.STATUSES), the typed steps,
    seconds; the level that found it (LEVELS); from bilevel planning (bilevel.py) also the
    scene predicted after each step and the candidate plans looked at."""

    status: str
    steps: list[PlanStep] = field(default_factory=list)
    seconds: float = 0.0
    message: str = ""
    planner: str = ""
    level: str = "symbolic"
    predicted: list = field(default_factory=list)
    candidates: list = field(default_factory=list)

    def __post_init__(self):
        if self.level not in LEVELS:
            raise ValueError(f"unknown plan level {self.level!r}; one of {tuple(LEVELS)}")

    @property
    def solved(self) -> bool:
        return self.status == "solved"

    @property
    def predicts_positions(self) -> bool:
        """Was it checked in continuous space (else: on its symbols)? (Level)"""
        return LEVELS[self.level].predicts_positions

    @property
    def symbolic(self) -> bool:
        """Is it a plan on symbols alone, for the agent to complete? (Level)"""
        return LEVELS[self.level].symbolic

    @property
    def subgoal(self) -> bool:
        """Does it end at a subgoal, where the agent plans on? (Level)"""
        return LEVELS[self.level].subgoal


def problem_text(task: Task, costs: bool) -> str:
    """The PDDL problem of `task` (minimising total cost with `costs`)."""
    return problem_from_atoms(task.objects, sorted(task.init), sorted(flat(task.goal)),
                              task.name, costs=costs)


def plan_task(operators, domain: Callable[[], str], task: Task, planner: str = "fd",
              wall_seconds: float = DEFAULT_TIMEOUT, cpu_seconds: float | None = None,
              penalties: Mapping[tuple[str, ...], int] | None = None,
              carry_cost: int = 0) -> PlanResult:
    """Plans `task` with `operators`: Fast Downward's search on the task grounded here
    (planning/grounding.py, where `penalties` make moves of (source, target) pairs dearer)
    where its build has a search binary, else the planner on the PDDL `domain()` text
    (with action costs for Fast Downward; no penalties). `cpu_seconds`: a CPU budget,
    `wall_seconds` then the wall-clock cap (planning/planners.py); `carry_cost`: added per
    rider a move carries (grounded here only)."""
    if planner == "fd" and search_binary() is not None:
        return fast_downward_task(operators, task, wall_seconds, cpu_seconds=cpu_seconds,
                                  penalties=penalties, carry_cost=carry_cost)
    options = {} if cpu_seconds is None else {"cpu_seconds": cpu_seconds}
    return plan_pddl(domain(), problem_text(task, costs=planner == "fd"), planner, wall_seconds,
                     **options)


def reliability(steps) -> float:
    """The product of the steps' operators' reliabilities (a repositioning counts 1)."""
    return math.prod(s.operator.reliability for s in steps if isinstance(s, Step))


class Abstraction:
    """A model bundle's view of perceived scenes (module docstring)."""

    def __init__(self, bundle: ModelBundle):
        self.bundle = bundle

    # --- symbols and atoms ------------------------------------------------------------

    def read(self, names, features: np.ndarray, contacts=()) -> Reading:
        """The symbols of a perceived scene: object names, features [n, d_o], the pairs of
        the relevance graph."""
        names = [check_name(n) for n in names]
        unary, unary_unc, rel, rel_unc = read_symbols(self.bundle.model, features,
                                                      margin=self.bundle.margin)
        return Reading(SymbolicState(tuple(names), unary, rel), unary_unc.astype(bool),
                       rel_unc.astype(bool), {tuple(p) for p in contacts})

    def read_scene(self, scene) -> Reading:
        """`read` of a perceived scene (names, features(), contacts)."""
        radius = self.bundle.relevance_radius
        reading = self.read(scene.names, scene.features(), neighbour_pairs(scene, radius))
        if radius <= CONTACT_TOLERANCE:
            return reading
        return replace(reading, touching={tuple(p) for p in scene.contacts})

    def observe(self, scene) -> Observation:
        """A perceived scene with its symbols and its boxes (Observation)."""
        return Observation(scene, self.read_scene(scene), Boxes.of(scene))

    def atoms(self, reading: Reading, guess: bool = False, contacts_only: bool | None = None
              ) -> tuple[frozenset, frozenset]:
        """(atoms, unknown keys) of a reading under the bundle's semantics; with `guess` (a
        problem's initial state) uncertain bits are read by their sign where the semantics
        says so."""
        s = reading.state
        atoms, unknown = self.bundle.semantics.read(
            s.unary, reading.unary_uncertain, s.relational, reading.relational_uncertain,
            reading.contact_matrix(), guess=guess, contacts_only=contacts_only,
            degree=reading.contact_matrix(touching=True).sum(-1))
        names = s.objects
        return (frozenset(Atom(a[0], *(names[i] for i in a[1:])) for a in atoms),
                frozenset((k[0], *(names[i] for i in k[1:])) for k in unknown))

    def believed(self, reading: Reading) -> frozenset:
        """The atoms a plan starts from: uncertain bits read as a problem reads them."""
        return self.atoms(reading, guess=True)[0]

    def goal_atoms(self, goal: Reading) -> frozenset:
        """Unary atoms, and relation atoms only between related objects (paper IV-C: in
        contact, or near under relevance by vicinity); of a goal of relations
        (Reading.pairs), the relation atoms of the related pairs they name (pair_of): the
        paper's contact-graph filter on the structure a person asked for, not the scene.
        A model without relations (Attentive: unary symbols alone) says of such a goal only
        what its atoms of the named objects say."""
        atoms = self.atoms(goal, contacts_only=True)[0]
        if goal.pairs is None:
            return atoms
        if not self.bundle.n_relations:
            named = {n for pair in goal.pairs for n in pair}
            return frozenset(a for a in atoms if set(a[1:]) <= named)
        both = self.bundle.relevance_radius > CONTACT_TOLERANCE
        named = frozenset(a for a in atoms if len(a) == 3 and pair_of(goal.pairs, a, both))
        if not both or not self.bundle.patterns or goal.kinds is None:
            return Goal(named)
        return pair_choices(goal.kinds, named, self.bundle.patterns)

    def goal_holds(self, reading: Reading, goal: frozenset) -> bool:
        """Do the goal's atoms hold in `reading` (the planner's own criterion)?"""
        return goal_of(goal) <= self.atoms(reading)[0]

    # --- tasks and plans --------------------------------------------------------------

    def task(self, start: Reading, goal: Reading, name: str = "goal",
             unheld: frozenset = frozenset()) -> Task:
        """The planning task from `start` to `goal`; `unheld`: a goal of relations' pairs
        whose relation the perceived start does not hold (relation_goal.unheld), whose
        readings the start's atoms hold already are no goal (unheld_readings)."""
        if set(start.objects) != set(goal.objects):
            raise ValueError(f"start and goal name different objects: {sorted(start.objects)} "
                             f"vs {sorted(goal.objects)}")
        init, atoms = self.believed(start), self.goal_atoms(goal)
        if unheld and isinstance(atoms, Goal):
            atoms = unheld_readings(atoms, init, unheld)
        return Task(start.objects, init, atoms, name)

    def focus(self, task: Task, start: Reading, goal: Reading,
              touching: bool = False) -> tuple[str, ...]:
        """The objects a plan most likely needs: those in a goal atom (or an open choice)
        that does not hold at the start, and the objects related to them (with
        `touching`: in contact with them) at the start or in the goal. The planner tries
        these first (as PLOI, Silver et al. 2021, with a rule for the score): grounding
        grows with the cube of the object count."""
        changed = {n for atom in task.goal - task.init for n in atom[1:]}
        changed |= {n for key, _ in goal_of(task.goal).open_choices(task.init) for n in key}
        pairs = set()
        for reading in (start, goal):
            held = reading.touching if touching and reading.touching is not None \
                else reading.contacts
            pairs |= {tuple(p) for p in held}
        near = {b for a, b in pairs if a in changed} | {a for a, b in pairs if b in changed}
        return tuple(n for n in task.objects if n in changed | near)

    def plan(self, start: Reading, goal: Reading, planner: str = "fd",
             budget: Budget | None = None, focus: bool = True,
             penalties: Mapping[tuple[str, ...], int] | None = None,
             unheld: frozenset = frozenset()) -> Plan:
        """Plans from start to goal within `budget` (planning.budget.Budget, from now;
        default DEFAULT_TIMEOUT CPU seconds): a goal of relations stage by stage, else
        at once (abstraction/goal_plans.py); each planner call on the `focus` objects
        first, all of them where that proves unsolvable (`plan_focused`; `focus=False`:
        all of them). The empty plan, without a planner call, when the goal's atoms hold
        already. `penalties`: see `plan_task`; `unheld`: see `task`."""
        t0 = time.perf_counter()
        budget = budget or Budget.of_cpu(DEFAULT_TIMEOUT)
        found = plan_goal(self, self.task(start, goal, unheld=unheld), start, goal, budget,
                          planner, focus, penalties)
        found.seconds = time.perf_counter() - t0
        return found

    def plan_focused(self, task: Task, start: Reading, goal: Reading, planner: str = "fd",
                     budget: Budget | None = None, focus: bool = True,
                     penalties=None) -> Plan:
        """`task` planned on its focus objects in contact, then its focus objects (`focus`:
        the related ones too), then all (`plan`), each where the one before proves
        unsolvable, within `budget` (default DEFAULT_TIMEOUT CPU seconds from now): one
        stage of a goal of relations. A plan over some objects applies to the whole task:
        an operator's preconditions and effects name its parameters alone. (Under
        vicinity a stage of sixteen boxes relates nine boxes, grounded in 6 CPU s; four
        touch. Only the boxes the goal changes, a cube set on a tower's top could not
        name the box under the target, and the plans of towers of three went astray.)"""
        budget = budget or Budget.of_cpu(DEFAULT_TIMEOUT)
        objects = self.focus(task, start, goal)
        if objects and not focus:
            objects = task.objects
        if not objects:
            return Plan("solved", [], 0.0, "", planner)
        smaller = [s for s in dict.fromkeys([self.focus(task, start, goal, True), objects])
                   if s and len(s) < len(task.objects)] if focus else []
        for subset in [*smaller, None]:
            sub = task if subset is None else task.restricted(subset)
            domain = partial(self.bundle.domain_for, len(sub.objects), planner == "fd")
            found = plan_task(self.bundle.planned, domain, sub, planner,
                              max(budget.wall_left(), 1e-3), max(budget.cpu_left(), 1e-3),
                              penalties, CARRY_COST if goal.pairs is not None else 0)
            if found.status != "unsolvable":
                break
        steps = [self.step(s) for s in found.plan] if found.solved else []
        return Plan(found.status, steps, 0.0, found.message, planner)

    def step(self, text: str) -> PlanStep:
        """A plan step as the planner (or a record) writes it, parsed on the bundle's
        operators."""
        try:
            return parse_step(text, self.bundle.by_name)
        except ValueError as e:
            raise ValueError(f"{e} ({self.bundle.path})") from e

    # --- checks on executed steps ------------------------------------------------------

    def mismatches(self, after: Reading, step: Step) -> list[Atom]:
        """Predicted atoms that did not come true (an add that is absent, a delete still
        present); bits read as uncertain after the step are no evidence either way."""
        atoms, unknown = self.atoms(after)
        missing = [a for a in sorted(step.add) if a not in atoms and a.key not in unknown]
        kept = [a for a in sorted(step.delete) if a in atoms]
        return missing + kept
