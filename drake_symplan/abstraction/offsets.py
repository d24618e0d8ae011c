"""Choosing a plan step's offsets: one chooser, scorers that say how well each choice lands.

The learned symbols say that a box ends on another, not where along it: a plan step `pick
o3 at its centre, release on o1's right` and the same step released at o1's centre can
predict the same symbolic effect. The planner sees one operator over objects for them (a
symbolic/structs.py PlanningOperator, named after its planned variant); the 5 cm check
cannot accept both. `ranked(operators, step, rest, state, goal_atoms, scorer)` takes the
step's candidates (`PlanningOperators.variants`: the learned operators over the same
objects that apply in the believed `state` and after which the `rest` of the plan still
reaches the goal's atoms, the step itself first) and orders them by the scorer, best
first, as an NSRT's sampler picks a step's continuous parameters (here: among the three
discrete offsets per hand); `choose` takes the best. The planner's own choice stays first
unless another scores at least the scorer's `keep` better.

A scorer is called with the candidates and returns a `Scored` for each (lower is better):

- `GeometricScorer` (the agent, for a plan on symbols, before each step runs): how far
  along world y the source would land from its perceived goal position, its grasp point
  released over the target's release point (actions.release_shift); relative to the
  target where the two touch in the goal scene (the target may move later), else
  absolute. `keep` MIN_GAIN.
- `PredictedScorer` (bilevel planning, abstraction/refiner.py's Refiner, while it refines
  a skeleton): the summed distance of the boxes to their goal positions in the scene the
  learned continuous model predicts after the step (continuous.goal_errors); it keeps
  the prediction for the search to go on from. `keep` 0.

A new scorer is a class with `keep` and `__call__(options) -> [Scored]` (docs/layout.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drake_symplan.abstraction.continuous import Boxes, goal_errors
from drake_symplan.actions import OFFSET_METRES, release_shift
from drake_symplan.relations import unmet
from drake_symplan.symbolic.structs import PlanningOperators, PlanStep, Step

MIN_GAIN = 0.01  # m: the geometric scorer's change of offsets lands the source this much nearer


@dataclass(frozen=True)
class Scored:
    """A candidate step, its score (lower is better) and the scene a scorer predicted
    after it (None where it predicts none)."""

    step: Step
    score: float
    predicted: Boxes | None = None


class GeometricScorer:
    """How far (m, along world y, the offsets' axis) each candidate would land its source
    from its goal position; `now` and `goal`: perceived positions by name, `goal_contacts`
    the pairs in contact in the goal scene (module docstring)."""

    keep = MIN_GAIN

    def __init__(self, now: dict[str, np.ndarray], goal: dict[str, np.ndarray],
                 goal_contacts):
        self.now, self.goal = now, goal
        self.contacts = {tuple(sorted(p)) for p in goal_contacts}

    def landing_error(self, step: PlanStep) -> float:
        action = step.action
        src, tgt = action.source, action.target
        if tuple(sorted((src, tgt))) in self.contacts:
            want = self.goal[src][1] - self.goal[tgt][1]
        else:
            want = self.goal[src][1] - self.now[tgt][1]
        return abs(release_shift(action) - want)

    def __call__(self, options: list[Step]) -> list[Scored]:
        return [Scored(s, self.landing_error(s)) for s in options]


class PredictedScorer:
    """The summed distance (m) of the boxes to their `goal` positions in the scene that
    `predict(boxes, actions) -> [Boxes]` predicts after each candidate from `boxes`; with
    a goal of `relations`, a metre more for each of them the scene does not hold (where
    the structure stands does not matter, that it stands does)."""

    keep = 0.0

    def __init__(self, predict: Callable, boxes: Boxes, goal: dict[str, np.ndarray],
                 relations: tuple = ()):
        self.predict, self.boxes, self.goal, self.relations = predict, boxes, goal, relations

    def __call__(self, options: list[Step]) -> list[Scored]:
        after = self.predict(self.boxes, options)
        return [Scored(s, sum(goal_errors(b, self.goal).values())
                       + (len(unmet(self.relations, b.object_states())) if self.relations
                          else 0.0), b)
                for s, b in zip(options, after, strict=True)]


def ranked(operators: PlanningOperators, step: Step, rest: list[PlanStep], state,
           goal_atoms, scorer) -> list[Scored]:
    """The candidates for `step`'s offsets (module docstring), best first by `scorer`
    (ties in the candidates' order); `step` first unless another scores `scorer.keep`
    better."""
    scored = scorer(operators.variants(step, rest, state, goal_atoms))
    order = sorted(scored, key=lambda s: s.score)
    planned = scored[0]
    if order[0] is not planned and planned.score - order[0].score < scorer.keep:
        order.remove(planned)
        order.insert(0, planned)
    return order


def choose(operators: PlanningOperators, step: Step, rest: list[PlanStep], state,
           goal_atoms, scorer, unsafe: Callable | None = None,
           riding: Callable | None = None) -> Step:
    """The best of `ranked`: `step` with the offsets that score best, of those whose
    action is not `unsafe(action)` where any is not; `riding(name)` (the boxes on a box),
    where given: each held nearest its centre (`central`)."""
    order = [s.step for s in ranked(operators, step, rest, state, goal_atoms, scorer)]
    if riding is not None:
        order = central(order, riding)
    return next((s for s in order if unsafe is None or not unsafe(s.action)), order[0])


def central(items: list, riding: Callable, action: Callable = lambda s: s.action) -> list:
    """`items` (steps, or anything `action(item)` reads an Action from), each in its place
    replaced by the one that moves its source alike (the same target and release_shift)
    grasped nearest its centre, where nothing rides on the source (`riding(name)`), and
    without repeats. A block held at its end and set on a tower of four came down 1.5 cm
    off, tilted, and the tower leaned 0.07 rad (knocked over in a solve); held at its
    centre it landed level."""
    def alike(item) -> tuple:
        a = action(item)
        return a.source, a.target, round(release_shift(a), 6)

    best, loaded = {}, {}
    for item in items:
        a, key = action(item), alike(item)
        if a.source not in loaded:
            loaded[a.source] = bool(riding(a.source))
        if loaded[a.source]:
            continue
        if key not in best or abs(OFFSET_METRES[a.grasp]) < abs(
                OFFSET_METRES[action(best[key]).grasp]):
            best[key] = item
    out, seen = [], set()
    for item in items:
        chosen = best.get(alike(item), item)
        if id(chosen) not in seen:
            seen.add(id(chosen))
            out.append(chosen)
    return out
