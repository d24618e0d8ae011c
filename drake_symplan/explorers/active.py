"""Active exploration: each action chosen where the robot expects to learn most, with what
the previous round learned (explorers/rounds.py).

An ActiveExplorer holds a round's model bundle (the symbol model, its operators, an
ensemble of effect models as continuous.pt) and mixes three ways of choosing an action:

- random, a share `p_random` of the actions, so that nothing is starved;
- a babbled goal, a share `p_goal` (after GLIB, Chitnis et al. AAAI 2021): goals of one or
  two atoms over the learned symbols that do not hold now, on predicates the data has seen
  change, each valued by how unreliably the operators reach it in one step (1 - the best
  reliability; 1 when no operator reaches it). The most valuable is pursued: with the
  step that reaches it, or when none does, with an action on its objects that no
  operator covers in this state ("uncovered": where the domain has a gap), the ensemble's
  disagreement ranking them;
- disagreement, the rest: the action whose predicted effect the ensemble's members
  disagree on most (the largest distance of a member's predicted box position from their
  mean).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import torch

from drake_symplan.abstraction.abstraction import Abstraction
from drake_symplan.abstraction.continuous import Boxes, ContinuousModel
from drake_symplan.actions import OFFSETS, Action
from drake_symplan.data.exploration import random_action
from drake_symplan.symbolic.structs import Atom, LiftedOperator, Step


@dataclass(frozen=True)
class ActiveConfig:
    """The rounds and the mix. `warmup` random transitions come first; every `round_size`
    after them the explorer is learned again from all the data so far: `members` effect
    models (the first is the symbol model) trained from the previous round's weights
    (`epochs_for`), effect-first operators of `min_count`; `goals` babbled per goal choice."""

    warmup: int = 1000
    round_size: int = 1000
    p_random: float = 0.2
    p_goal: float = 0.4
    members: int = 3
    epochs: int = 30
    patience: int = 10
    min_count: int = 5
    goals: int = 16

    def __post_init__(self):
        if self.warmup < 1 or self.round_size < 1:
            raise ValueError("warmup and round_size must be positive")
        if not (0 <= self.p_random and 0 <= self.p_goal and self.p_random + self.p_goal <= 1):
            raise ValueError(f"p_random + p_goal must be within [0, 1], got "
                             f"{self.p_random} + {self.p_goal}")
        if self.members < 2:
            raise ValueError(f"disagreement needs at least 2 ensemble members, got "
                             f"{self.members}")
        if min(self.epochs, self.patience, self.min_count, self.goals) < 1:
            raise ValueError("epochs, patience, min_count and goals must be positive")

    def epochs_for(self, transitions: int) -> int:
        """Training epochs of a round that learns from `transitions`: `epochs` over the
        warm-up, then as many gradient steps as `epochs` over one round (the warm start
        holds the rest), at least 3."""
        return max(3, math.ceil(self.epochs * min(self.warmup, self.round_size)
                                / transitions)) if transitions > self.warmup else self.epochs

    def round_end(self, r: int) -> int:
        """The number of transitions collected when round r ends."""
        return self.warmup + r * self.round_size


def all_actions(names) -> list[Action]:
    """Every pick/place action over the objects `names` (source != target)."""
    return [Action(s, g, t, r) for s, t in itertools.permutations(names, 2)
            for g in OFFSETS for r in OFFSETS]


def ground_steps(operators: list[LiftedOperator], state: frozenset, objects) -> list[Step]:
    """Every operator bound to distinct objects whose preconditions hold in `state`."""
    steps = []
    for op in operators:
        for args in itertools.permutations(objects, op.n_params):
            step = Step(op, args)
            if step.applicable(state):
                steps.append(step)
    return steps


def babble_goals(rng: np.random.Generator, state: frozenset, objects,
                 predicates, count: int) -> list[frozenset]:
    """`count` goals of one or two atoms over `objects` on `predicates` ((name, arity)
    pairs) that do not hold in `state`; a goal never holds an atom and its negation."""
    atoms = sorted(Atom(name, *args) for name, arity in sorted(predicates)
                   for args in itertools.permutations(objects, arity)
                   if Atom(name, *args) not in state)
    if not atoms:
        return []
    goals = []
    for _ in range(count):
        size = min(len(atoms), 1 + int(rng.integers(2)))
        picked = [atoms[i] for i in rng.choice(len(atoms), size=size, replace=False)]
        if len({(a.predicate.removeprefix("not_"), a.args) for a in picked}) == len(picked):
            goals.append(frozenset(picked))
    return goals


def goal_values(goals: list[frozenset], steps: list[Step], state: frozenset) -> np.ndarray:
    """Per goal, 1 - the best reliability of a step that reaches it from `state` (1: none)."""
    after = [(s.apply(state), s.operator.reliability) for s in steps]
    return np.array([1.0 - max((rel for atoms, rel in after if goal <= atoms), default=0.0)
                     for goal in goals])


def pursue(goals: list[frozenset], steps: list[Step], state: frozenset
           ) -> tuple[frozenset, Step | None]:
    """The most valuable goal (the first of equals) and the most reliable step reaching it
    (None when no step does)."""
    goal = goals[int(np.argmax(goal_values(goals, steps, state)))]
    reaching = [s for s in steps if goal <= s.apply(state)]
    return goal, max(reaching, key=lambda s: s.operator.reliability, default=None)


class ActiveExplorer:
    """A round's explorer (module docstring): `explorer(rng, scene) -> (action, mode)`,
    the contract of data.exploration.random_choice."""

    def __init__(self, bundle, config: ActiveConfig, predicates):
        self.abstraction = Abstraction(bundle)
        self.operators = bundle.operators
        self.ensemble = ContinuousModel(bundle.continuous, snap=0.0,
                                        radius=bundle.relevance_radius)  # every disagreement
        self.config = config
        self.predicates = tuple(tuple(p) for p in predicates)

    def __call__(self, rng: np.random.Generator, scene) -> tuple[Action, str]:
        u = rng.random()
        if u < self.config.p_random:
            return random_action(rng, scene.names), "random"
        torch.set_num_threads(1)  # the same choices on any worker
        if u < self.config.p_random + self.config.p_goal:
            chosen = self._for_goal(rng, scene)
            if chosen is not None:
                return chosen
        candidates = all_actions(scene.names)
        return self._most_disputed(scene, candidates), "disagreement"

    def _most_disputed(self, scene, actions: list[Action]) -> Action:
        return actions[int(np.argmax(self.ensemble.disagreement(Boxes.of(scene), actions)))]

    def _for_goal(self, rng, scene) -> tuple[Action, str] | None:
        state = self.abstraction.believed(self.abstraction.read_scene(scene))
        goals = babble_goals(rng, state, scene.names, self.predicates, self.config.goals)
        if not goals:
            return None
        steps = ground_steps(self.operators, state, scene.names)
        goal, step = pursue(goals, steps, state)
        if step is not None:
            return step.action, "goal"
        involved = {n for atom in goal for n in atom.args}
        on_goal = [a for a in all_actions(scene.names)
                   if a.source in involved or a.target in involved]
        covered = {s.action for s in steps}
        return self._most_disputed(scene, [a for a in on_goal if a not in covered]
                                   or on_goal), "uncovered"
