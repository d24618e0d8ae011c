"""Bilevel planning: symbolic skeletons refined with the learned continuous model, and a
continuous search when no skeleton refines. No simulator: every check is a prediction.

As predicators' SeSamE and the paper's successor (Dogangun et al. 2026): the symbolic
planner proposes a skeleton (the focus objects' plan, then the plan over every object,
then, asked for, alternatives that avoid the moves of those before); the continuous level
(refiner.py) refines it, choosing the offsets the symbols leave open, or rejects it, and
the next skeleton is tried. With a receding `horizon` (`--planning receding`) a skeleton
longer than it is refined only over its first steps, to the skeleton's subgoal there
(SeSamE's expected atoms, with positions): the learned model checks one or two steps well
and ten badly, so a long plan is checked piecewise, and the agent plans again from what it
sees. When no skeleton refines (or the planner finds none) the refiner's weighted
best-first search over every pick/place move is the fallback. A goal more than LONG_GOAL
moves away by the goal's order (goal_order.py), whose skeletons the model cannot check,
is searched first and its skeletons are the fallback (without a receding horizon).
Budgets are CPU seconds with a wall-clock cap (planning/budget.py), so a problem gets the
same answer on a busy host as on a quiet one: one budget per plan, of which the skeletons
(planner calls and refinement) may use half, the continuous search the rest (a long goal:
the search 90 %, the skeletons the rest).

`plan_bilevel(abstraction, refiner, start, goal, budget, Search(...))` plans from one
Observation (abstraction.py: a perceived scene, its symbols, its boxes) to another;
agent/planning_modes.py's bilevel and continuous modes call it.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field, replace

import numpy as np

from drake_symplan.abstraction.abstraction import Observation, Plan
from drake_symplan.abstraction.continuous import Boxes, goal_errors
from drake_symplan.abstraction.refiner import Refined, Refiner, nearer
from drake_symplan.abstraction.refusals import allows
from drake_symplan.abstraction.relation_goal import unheld_in
from drake_symplan.planning.budget import Budget
from drake_symplan.symbolic.structs import Step

# Of the CPU budget left: the symbolic planner's call for a skeleton, then the share kept for
# the continuous search when no skeleton refines (so a planner timeout leaves it time).
SKELETON_SHARE = 0.5
SEARCH_SHARE = 0.5
PENALTY = 1000  # cost added to a move for each skeleton before that made it and did not refine
SEARCH = "continuous"  # the Candidate.source of the continuous search
# Goals more moves away than this (the goal's order, goal_order.py) are searched before any
# skeleton: beyond it none of 31 six-box first plans refined a skeleton.
LONG_GOAL = 4
# The share of a long goal's budget the search has before the skeletons: on the towers
# sets no skeleton's plan was the one run, and with 60 % the search missed plans it
# finds with the whole budget
SEARCH_FIRST = 0.9


@dataclass(frozen=True)
class Search:
    """How `plan_bilevel` plans: `skeletons`, refine the symbolic planner's skeletons
    first (bilevel), else the continuous search alone; `planner`, the symbolic planner's
    back-end (planning.planners.PLANNERS); `alternatives`, skeletons asked for beyond the
    first two (`skeletons`); `horizon`, refine a longer skeleton only that far, to its
    subgoal (None: whole skeletons)."""

    def __post_init__(self):
        if self.horizon is not None and self.horizon < 1:
            raise ValueError(f"the receding horizon must be 1 or more, got {self.horizon}")

    skeletons: bool = True
    planner: str = "fd"
    alternatives: int = 0
    horizon: int | None = None  # steps of a longer skeleton refined to its subgoal

    @property
    def level(self) -> str:
        """The level of a plan that is not found (abstraction.LEVELS)."""
        return "bilevel" if self.skeletons else SEARCH


@dataclass
class Candidate:
    """A plan the search looked at: its steps, whether it was accepted, why not, the
    predicted distance (cm) of each box to its goal at its end, and the wall seconds it
    took (a skeleton: the planner call and the refinement; SEARCH: the search)."""

    source: str  # "skeleton 1", SEARCH
    steps: list[str]
    accepted: bool
    why: str
    errors_cm: dict[str, float] = field(default_factory=dict)
    seconds: float = 0.0
    rest: list[str] = field(default_factory=list)  # a subgoal's: the skeleton's steps after it

    @property
    def searched(self) -> bool:
        """Did the continuous search make it (else a skeleton)?"""
        return self.source == SEARCH

    def to_json(self) -> dict:
        out = {"source": self.source, "steps": self.steps, "accepted": self.accepted,
               "why": self.why, "errors_cm": self.errors_cm,
               "seconds": round(self.seconds, 4)}
        return {**out, "rest": self.rest} if self.rest else out



class _LookedAt:
    """The candidates looked at, each with the wall seconds since the one before."""

    def __init__(self):
        self.candidates: list[Candidate] = []
        self.began = time.perf_counter()

    def restart(self) -> None:
        self.began = time.perf_counter()

    def __call__(self, candidate: Candidate) -> None:
        now = time.perf_counter()
        candidate.seconds, self.began = now - self.began, now
        self.candidates.append(candidate)


def plan_bilevel(abstraction, refiner: Refiner, start: Observation, goal: Observation,
                 budget: Budget, search: Search | None = None,
                 penalties: dict[tuple[str, ...], int] | None = None) -> Plan:
    """A plan from the perceived `start` to `goal` (abstraction.Observation) within
    `budget`: with `search.skeletons` the symbolic planner's skeletons refined, then the
    continuous search (a goal more than LONG_GOAL moves away: the search, then the
    skeletons); else the search alone (Search). An abstraction.Plan whose `level`
    says which found it, with the scene predicted after each step and the candidates
    looked at (the rejected ones with why). `penalties`: costs added to the skeletons'
    moves of (source, target) pairs (planning/grounding.py)."""
    t0 = time.perf_counter()
    search = search or Search()
    target = goal.boxes.where()
    refiner.relations = goal.relations
    looked_at = _LookedAt()
    unverified = None  # the first skeleton, run on its symbols if nothing else is found
    searched = None  # the search's (plan, nearest), where it went before the skeletons
    if search.skeletons and search.horizon is None \
            and refiner.moves_left(start.boxes, target) > LONG_GOAL:
        searched = refiner.search(start.boxes, target, budget.share(SEARCH_FIRST))
        looked_at(_candidate(SEARCH, [], searched[0], refiner, start.boxes, target))
    if search.skeletons and (searched is None or searched[0] is None):
        refined, unverified = _refine_skeletons(
            abstraction, refiner, start, goal, budget, search, looked_at, penalties,
            share=1.0 if searched is not None else 1 - SEARCH_SHARE)
        if refined is not None:
            shorter = _shorter(refiner, refined, start.boxes, target, budget, looked_at)
            if shorter is not None:
                return Plan("solved", shorter.steps, time.perf_counter() - t0, "",
                            search.planner, level=SEARCH, predicted=shorter.predicted,
                            candidates=looked_at.candidates)
            level = "receding" if refined.subgoal else "bilevel"
            return Plan("solved", refined.steps, time.perf_counter() - t0, "", search.planner,
                        level=level, predicted=refined.predicted,
                        candidates=looked_at.candidates)
    looked_at.restart()  # a planner call that gave no new skeleton is not counted
    if searched is None:
        refined, nearest = refiner.search(start.boxes, target, budget)
        looked_at(_candidate(SEARCH, [], refined, refiner, start.boxes, target))
    else:
        refined, nearest = searched
    return _after_search(refined, nearest, unverified, refiner, start.boxes, target,
                         Plan("solved", [], time.perf_counter() - t0, "", search.planner,
                              level=SEARCH, candidates=looked_at.candidates), search.level)


def _after_search(refined: Refined | None, nearest: Refined, unverified: Plan | None,
                  refiner: Refiner, start: Boxes, target: dict[str, np.ndarray],
                  base: Plan, level: str) -> Plan:
    """The plan once the search has run: its plan (`refined`); where it found none, the
    first skeleton on its symbols, the steps predicted nearest the goal, those that clear
    a refused grasp, the empty plan where the goal's symbols hold, or none (a timeout).
    `base`: the Plan's seconds, planner and candidates."""
    def found(steps, message: str, level: str, predicted=(), status="solved") -> Plan:
        return replace(base, status=status, steps=list(steps), message=message, level=level,
                       predicted=list(predicted))

    if refined is not None:
        return found(refined.steps, "", SEARCH, refined.predicted)
    missed = "no plan reaches the goal " + ("relations" if refiner.relations else "positions") \
        + " in prediction"
    if unverified is not None and unverified.steps \
            and allows(unverified.steps[0].action, refiner.refusals.barred(start)):
        # Predictions are not the world (`symplan eval rollout`): the symbolic plan still
        # has its chance, completed and monitored as a symbolic plan is; not where the arm
        # refuses its first step (a skeleton with no other way found it again and again).
        return found(unverified.steps, f"{missed}; the first skeleton runs on its symbols",
                     "symbolic")
    if nearer(nearest, start, target):
        # Nothing reaches the goal, but these steps are predicted to bring the boxes
        # nearer it; the monitor replans from what is perceived at their end.
        return found(nearest.steps, f"{missed}; the steps predicted nearest it run, then "
                     "a replan", "nearest", nearest.predicted)
    if refiner.clears_way(start, nearest):
        # Nor nearer, but they move a box in the way of a refused grasp: once it is seen
        # moved, the grasp is planned again.
        return found(nearest.steps, f"{missed}; the steps that move a box in the way of a "
                     "refused grasp run, then a replan", "nearest", nearest.predicted)
    if unverified is not None and not unverified.steps:  # the goal's symbols hold already
        return found([], missed, "symbolic")
    return found([], missed, level, status="timeout")


def _refine_skeletons(abstraction, refiner: Refiner, start: Observation, goal: Observation,
                      budget: Budget, search: Search, looked_at: _LookedAt,
                      penalties: dict[tuple[str, ...], int] | None = None,
                      share: float = 1 - SEARCH_SHARE) -> tuple[Refined | None, Plan | None]:
    """The skeletons' part of `plan_bilevel`, in `share` of what is left of `budget`:
    (the first skeleton refined or None, the first skeleton the planner found or None)."""
    believed = abstraction.believed(start.reading)
    goal_atoms = abstraction.goal_atoms(goal.reading)
    target = goal.boxes.where()
    symbolic = budget.share(share)
    unverified = None
    for i, found in enumerate(skeletons(abstraction, start.reading, goal.reading,
                                        search.planner, symbolic, search.alternatives,
                                        penalties, unheld_in(start, goal)), 1):
        if not found.solved:
            looked_at(Candidate(f"skeleton {i}", [], False, f"planner: {found.status}"))
            continue
        unverified = unverified or found
        horizon = search.horizon if search.horizon is not None \
            and len(found.steps) > search.horizon else None
        refined = refiner.refine(found.steps, start.boxes, believed, goal_atoms, target,
                                 symbolic, horizon)
        if refined is not None:
            refined.subgoal = horizon is not None
        looked_at(_candidate(f"skeleton {i}", found.steps, refined, refiner, start.boxes,
                             target, horizon))
        if refined is not None:
            return refined, unverified
        if symbolic.spent():
            break
    return None, unverified


def _shorter(refiner: Refiner, refined: Refined, start: Boxes, goal: dict[str, np.ndarray],
             budget: Budget, looked_at: _LookedAt) -> Refined | None:
    """A plan of the continuous search with no more steps than the goal's order asks for
    (goal_order.py), when the refined skeleton takes more (one that builds a tower's top on
    a box and carries it over, where placing each box once would do: every extra step and
    every carried load is a chance for the arm to depart from the prediction), or None."""
    needed = refiner.moves_left(start, goal)
    if refined.subgoal or len(refined.steps) <= needed:
        return None
    looked_at.restart()
    found, _ = refiner.search(start, goal, budget, max_depth=needed)
    if found is not None:
        looked_at(_candidate(SEARCH, [], found, refiner, start, goal))
        n = len(found.steps)
        looked_at.candidates[-1].why = (f"{n} step{'s' * (n != 1)} where the refined "
                                        f"skeleton takes {len(refined.steps)}")
    return found



def skeletons(abstraction, start, goal, planner: str, budget: Budget,
              alternatives: int = 0, given: dict[tuple[str, ...], int] | None = None,
              unheld_pairs: frozenset = frozenset()):
    """The symbolic planner's plans: the focus objects' first, then over every object
    when that gives another, then up to `alternatives` more over every object, each with
    the moves of the plans so far made dearer by PENALTY per plan (diverse planning by
    penalties: the next plan moves other boxes, or onto others, where the domain allows;
    the refiner already tries other offsets of the same moves). Each call has
    SKELETON_SHARE of the budget left; no further call after a timeout, an unsolved call
    or a plan seen before. `given`: penalties every call starts from; `unheld_pairs`: a
    goal of relations' pairs the perceived start does not hold (Abstraction.task)."""
    base = dict(given or {})
    penalties: Counter = Counter(base)

    def call(**options):
        options.setdefault("penalties", base or None)
        found = abstraction.plan(start, goal, planner, budget.share(SKELETON_SHARE),
                                 unheld=unheld_pairs, **options)
        if found.subgoal:  # a skeleton is refined to the goal: a plan of first stages is none
            return replace(found, status="unsolvable", steps=[])
        return found

    first = call()
    yield first
    if first.status == "timeout" or budget.spent():
        return
    seen: set[tuple[str, ...]] = set()

    def remember(plan):
        seen.add(tuple(map(str, plan.steps)))
        penalties.update({s.args[:2]: PENALTY for s in plan.steps if isinstance(s, Step)})

    if first.solved:
        remember(first)
    found = call(focus=False)
    for n in range(alternatives + 1):
        new = tuple(map(str, found.steps)) not in seen
        if (found.solved and new) or (n == 0 and (new or not first.solved)):
            yield found
        if not found.solved or (n > 0 and not new) or budget.spent():
            return
        if new:
            remember(found)
        if n < alternatives:
            found = call(focus=False, penalties=dict(penalties))


def _candidate(source: str, skeleton, refined: Refined | None, refiner: Refiner,
               start: Boxes, target, horizon: int | None = None) -> Candidate:
    """The candidate record of a refinement or search (rejected when `refined` is None:
    the skeleton's own predicted end, or its subgoal's with a `horizon`, is what
    missed)."""
    if refined is not None:
        end = refined.predicted[-1] if refined.predicted else start
        why = f"the first {horizon} of {len(skeleton)} steps, to their subgoal" \
            if refined.subgoal else ""
        rest = [str(s) for s in skeleton[horizon:]] if refined.subgoal else []
        return Candidate(source, [str(s) for s in refined.steps], True, why,
                         _cm(goal_errors(end, target)), rest=rest)
    if not skeleton:
        return Candidate(source, [], False, "no plan within the budget")
    if horizon is not None:
        return Candidate(source, [str(s) for s in skeleton], False,
                         f"no choice of offsets for the first {horizon} steps reaches the "
                         "subgoal", _cm(goal_errors(refiner.rollout(start, skeleton[:horizon]),
                                                    target)))
    errors = _cm(goal_errors(refiner.rollout(start, skeleton), target))
    far = {n: e for n, e in errors.items() if e > 100 * refiner.limit}
    return Candidate(source, [str(s) for s in skeleton], False,
                     f"predicted off the goal by more than {100 * refiner.limit:g} cm: "
                     f"{far}" if far else "no choice of offsets and moves reaches the goal",
                     errors)


def _cm(errors: dict[str, float]) -> dict[str, float]:
    return {n: round(100 * e, 1) for n, e in errors.items()}
