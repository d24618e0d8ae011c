"""The continuous level of bilevel planning: a symbolic skeleton's offsets chosen, and
moves added, by prediction (`Refiner.refine`), and the weighted best-first search over
every pick/place move (`Refiner.search`). No simulator: every check is a prediction.

Both roll the learned continuous model (continuous.py) forward from the perceived boxes
and accept a plan when every box is predicted within the tolerance less MARGIN of its goal
position. The search's heuristic is the summed predicted distance to the goal and the
moves the goal's order asks for (goal_order.py); those moves are predicted first, the rest
wait in the frontier DEFER dearer. bilevel.py decides when each runs and in what budget.
"""

from __future__ import annotations

import heapq
import itertools
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drake_symplan.abstraction.anchoring import AnchoredGoal
from drake_symplan.abstraction.continuous import MOVED, Boxes, goal_errors, rollout
from drake_symplan.abstraction.goal_order import GoalOrder
from drake_symplan.abstraction.offsets import PredictedScorer, central, ranked
from drake_symplan.abstraction.refusals import Refusals, allows
from drake_symplan.abstraction.set_down import set_down_tips
from drake_symplan.abstraction.stability import unstable
from drake_symplan.actions import OFFSETS, Action, grasp_on_box
from drake_symplan.boxes import GOAL_TOLERANCE, goal_reached
from drake_symplan.planning.budget import Budget
from drake_symplan.planning.nodes import EXPANDED
from drake_symplan.relations import unmet
from drake_symplan.symbolic.structs import PlanningOperators, PlanStep, Reposition, Step

MARGIN = 0.01  # m: accepted plans put every box this far inside the tolerance
# m of summed distance to the goal the search's heuristic counts as one move: the goal's
# order counts the moves, the distance ranks scenes as many moves away (at 0.15 m, how far
# one action moves a box, the distance outweighed the count and the search found 20 of 30
# eight-box plans in 6 CPU s; at 1 m, 25)
STEP_SCALE = 1.0
MOVE_LEFT = 1.0  # the search's heuristic per move the goal's order asks for (goal_order.py)
DEFER = 3.0  # the search's f added to the moves the goal's order does not ask for next
MISSED = 3.0  # the search's cost added to a move each time the arm missed it in this solve
NEARER = 0.05  # m: a partial plan runs only if predicted to bring the boxes this much nearer
SLACK = 0.01  # m: a box the subgoal leaves off its goal may be predicted this much farther


@dataclass
class Refined:
    """A plan of typed steps with the scene predicted after each; `subgoal`: the first
    steps of a longer skeleton, refined to its subgoal (Refiner.refine's horizon)."""

    steps: list[PlanStep]
    predicted: list[Boxes]
    subgoal: bool = False

    def then(self, step: PlanStep, after: Boxes) -> Refined:
        """This plan with `step` after it, predicted to leave `after`."""
        return Refined(self.steps + [step], self.predicted + [after])


def _asked_first(boxes: Boxes, order: GoalOrder, goal: dict[str, np.ndarray], limit: float,
                 missed: Counter, in_the_way: set[str] = frozenset()
                 ) -> tuple[set[str], Callable[[Reposition], bool]]:
    """The moves the goal's order asks for next (GoalOrder.next_moves: FD's preferred
    operators, in kind; and any move of a box `in_the_way` of a refused grasp), none in
    `missed`: (the sources they move, whether a move is one of them)."""
    asked = order.next_moves(boxes.where(), goal_errors(boxes, goal), limit,
                             {n for n in boxes.names if boxes.riding(n)})
    asked.update({n: None for n in in_the_way})

    def first(option: Reposition) -> bool:
        a = option.action
        targets = asked.get(a.source, set())
        return a not in missed and (a.source in asked and targets is None or a.target in targets)

    return set(asked), first


def reaches_goal(boxes: Boxes, goal: dict[str, np.ndarray], limit: float) -> bool:
    """Is every box predicted within `limit` of its goal, its spread counted against it
    (boxes.goal_reached)?"""
    return goal_reached(goal_errors(boxes, goal), limit)


def moved(before: Boxes, after: Boxes) -> set[str]:
    """The boxes predicted more than MOVED from where they were."""
    then = before.where()
    return {n for n, p in after.where().items() if np.linalg.norm(p - then[n]) > MOVED}


def moves(names, sources, half_length, kind: str = "reposition", riding=None,
          covered=frozenset()) -> list[Reposition]:
    """Every pick/place of a box in `sources` onto another of `names`, at a grasp point on
    the box (actions.grasp_on_box; `half_length(name)`: the box's half length along the
    offsets' axis, as the caller measures it), in the order of `names` and OFFSETS.
    `riding(name)`: the boxes on a box; with it a box is placed only on a box with nothing
    on it, and never on what it carries. The arm releases a box at the height of the
    target's own top, so a box placed on one under a stack is driven into the stack (a
    tower knocked over, the box flung 40 cm); the model, which saw few such actions,
    predicts the box on the stack's top. `covered`: boxes with another resting on them in
    part (a block's end over a cube: Boxes.covered), barred as targets too."""
    out = []
    on = {n: riding(n) for n in names} if riding is not None else {}
    covered = set(covered) | {n for n, above in on.items() if above}
    for src in names:
        if src not in sources:
            continue
        length = half_length(src)
        barred = covered | on.get(src, set())
        for tgt, grasp, release in itertools.product(names, OFFSETS, OFFSETS):
            if tgt != src and tgt not in barred and grasp_on_box(grasp, length):
                out.append(Reposition(Action(src, grasp, tgt, release), kind))
    return out


class Refiner:
    """The continuous level: refines skeletons and searches (module docstring).
    `operators`: the learned operators (a list, or symbolic/structs.py's
    PlanningOperators); `continuous` has `predict(boxes, actions) -> [Boxes]`
    (abstraction/continuous.py)."""

    def __init__(self, operators, continuous, tolerance: float = GOAL_TOLERANCE,
                 margin: float = MARGIN, extra_moves: int = 2, max_depth: int = 12,
                 weight: float = 1.5, defer: float | None = DEFER):
        # the planning operators whose offset variants a skeleton's steps choose among
        self.operators = operators if isinstance(operators, PlanningOperators) \
            else PlanningOperators(operators)
        self.continuous = continuous
        self.limit = tolerance - margin
        self.extra_moves, self.max_depth, self.weight = extra_moves, max_depth, weight
        self.defer = defer
        # the moves the arm was seen to miss in this solve, with how often: no longer
        # asked for, and a move's cost in the search is 1 + MISSED per miss
        self.missed: Counter = Counter()
        # what the arm refused in the scene as it stands (abstraction/refusals.py): no
        # step of the plans from it takes them (Refusals.barred)
        self.refusals = Refusals()
        self.predictions = 0
        # a goal of relations (relations.Relation): reached where the predicted boxes hold
        # them, wherever they stand (`reached`)
        self.relations: tuple = ()

    def reached(self, boxes: Boxes, goal: dict[str, np.ndarray]) -> bool:
        """Is the goal reached in the predicted `boxes`: of a goal of relations, its
        relations held wherever they stand (the example's positions within the limit
        are not enough: a row's boxes 4 cm across are near their places and no row);
        else every goal box within the limit of its goal position (reaches_goal)."""
        if self.relations:
            return not unmet(self.relations, boxes.object_states())
        return reaches_goal(boxes, goal, self.limit)

    def clears_way(self, start: Boxes, plan: Refined) -> bool:
        """Does `plan` move a box in the way of a refused step (Refusals.in_the_way)?"""
        return bool(plan.steps) and bool(self.refusals.in_the_way(start)
                                         - self.refusals.in_the_way(plan.predicted[-1]))

    @staticmethod
    def topples(before: Boxes, after: Boxes) -> bool:
        """Is a box the step moved predicted to rest where it topples, or to load one under
        it off its support (stability.unstable)? No plan goes through such a scene: the
        model predicts where such a box was released, not where it falls."""
        return unstable(after, moved(before, after))

    def unsafe(self, before: Boxes, after: Boxes, action: Action) -> bool:
        """Does the step topple a box, where the model predicts it (topples) or where the
        action sets its source down (set_down_tips), or release it where the arm or the
        agent refuses (Refusals.release_refused: driven into a box, out of view)?"""
        return self.topples(before, after) or set_down_tips(before, action) \
            or self.refusals.release_refused(before, action)

    def _allowed(self, boxes: Boxes, options: list[Reposition]) -> list[Reposition]:
        """The `options` no refusal bars in `boxes`, the arm's rules asked of their
        sources' grasps only (Refusals.barred), of those that move a source alike the one
        held nearest its centre (offsets.central)."""
        barred = self.refusals.barred(boxes, {m.action.source for m in options})
        return central([m for m in options if allows(m.action, barred)], boxes.riding)

    def _predict(self, boxes: Boxes, steps: list[PlanStep]) -> list[Boxes]:
        self.predictions += len(steps)
        return self.continuous.predict(boxes, [s.action for s in steps])

    def rollout(self, boxes: Boxes, steps: list[PlanStep]) -> Boxes:
        """The scene predicted after `steps`, one after the other, from `boxes`."""
        return rollout(self._predict, boxes, steps)[-1] if steps else boxes

    def refine(self, skeleton: list[Step], start: Boxes, believed, goal_atoms,
               goal: dict[str, np.ndarray], budget: Budget, horizon: int | None = None
               ) -> Refined | None:
        """The skeleton's offsets chosen and extra moves added so that the predicted end
        reaches `goal` (positions by name), or None. A skeleton longer than `horizon`:
        its first `horizon` steps' offsets, chosen so that they reach its subgoal."""
        before = goal_errors(start, goal)

        def extend(i: int, boxes: Boxes, state, done: Refined) -> Refined | None:
            if i == len(skeleton):
                return self.finish(boxes, done, goal, budget)
            if i == horizon:
                placed = {s.action.source for s in done.steps}
                later = moved(boxes, self.rollout(boxes, skeleton[i:]))
                return done if self.subgoal_reached(boxes, goal, before, placed, later) \
                    else None
            scorer = PredictedScorer(self._predict, boxes, goal, self.relations)
            # every offset variant of the step moves its source (one box's grasp rules)
            barred = self.refusals.barred(boxes, {skeleton[i].action.source})
            covered = boxes.covered()
            options = [o for o in ranked(self.operators, skeleton[i], skeleton[i + 1:],
                                         state, goal_atoms, scorer)
                       if allows(o.step.action, barred) and o.step.action.target not in covered]
            EXPANDED.add(1)
            for option in central(options, boxes.riding, lambda o: o.step.action):
                after, step = option.predicted, option.step
                if self.unsafe(boxes, after, step.action):
                    continue
                found = extend(i + 1, after, step.apply(state),
                               Refined(done.steps + [step], done.predicted + [after]))
                if found is not None or budget.spent():
                    return found
            return None

        return extend(0, start, frozenset(believed), Refined([], []))

    def subgoal_reached(self, boxes: Boxes, goal: dict[str, np.ndarray],
                        before: dict[str, float], placed: set[str], later: set[str]) -> bool:
        """Does the predicted scene `boxes` reach a skeleton's subgoal? Of the boxes the
        rest of the skeleton does not move (`later`: predicted to move, riders too), those `placed` by the
        steps so far and those at their goal `before` them (errors by name) are predicted
        within the limit of their goal, and the others no farther from it than before
        (SLACK)."""
        for name, error in goal_errors(boxes, goal).items():
            if name in later:
                continue
            if name in placed or before[name] <= self.limit:
                if error > self.limit:
                    return False
            elif error > before[name] + SLACK:
                return False
        return True

    def finish(self, boxes: Boxes, done: Refined, goal, budget: Budget,
               depth: int = 0) -> Refined | None:
        """`done` if its end reaches the goal, else with up to `extra_moves` moves of the
        boxes that are off their goal (the best three predicted first at each depth)."""
        if self.reached(boxes, goal):
            return done
        if depth >= self.extra_moves or budget.spent():
            return None
        off = {n for n, e in goal_errors(boxes, goal).items() if e > self.limit}
        options = self._allowed(boxes, moves(boxes.names, off, boxes.half_length,
                                             "reposition", boxes.riding, boxes.covered()))
        scored = sorted(((after, option) for after, option in
                         zip(self._predict(boxes, options), options, strict=True)
                         if not self.unsafe(boxes, after, option.action)),
                        key=lambda pair: max(goal_errors(pair[0], goal).values()))
        for after, option in scored[:3]:
            found = self.finish(after, Refined(done.steps + [option],
                                               done.predicted + [after]),
                                goal, budget, depth + 1)
            if found is not None or budget.spent():
                return found
        return None

    def moves_left(self, boxes: Boxes, goal: dict[str, np.ndarray],
                   order: GoalOrder | None = None) -> int:
        """The moves `boxes` is at least from `goal` by the goal's order
        (goal_order.GoalOrder, made here unless given)."""
        order = order or GoalOrder(goal, boxes.kinds())
        return order.moves_left(boxes.where(), goal_errors(boxes, goal), self.limit)

    def _split(self, boxes: Boxes, order: GoalOrder, goal: dict[str, np.ndarray],
               in_the_way) -> tuple[list[Reposition], Callable[[], list[Reposition]] | None]:
        """The moves from `boxes` that the search predicts now, and those it defers
        (`defer`; None: none), made when asked for: most deferred nodes never leave the
        frontier, and making every move of a sixteen-box scene (2,300) took a sixth of the
        search. The first are the ones the goal's order asks for first."""
        covered = boxes.covered()

        def options(sources) -> list[Reposition]:
            return moves(boxes.names, sources, boxes.half_length, "move", boxes.riding, covered)

        if self.defer is None:
            return self._allowed(boxes, options(set(boxes.names))), None
        sources, asked = _asked_first(boxes, order, goal, self.limit, self.missed, in_the_way)
        first = [m for m in options(sources) if asked(m)]
        allowed = self._allowed(boxes, first)
        # a box the order asks to move that the arm cannot grasp where it stands (a
        # block's span over it, a tower beside it): the boxes crowding it are in the way
        stuck = {m.action.source for m in first} - {m.action.source for m in allowed}
        if stuck:
            sources, asked = _asked_first(boxes, order, goal, self.limit, self.missed,
                                          set(in_the_way) | self.refusals.crowding(boxes, stuck))
            allowed = self._allowed(boxes, [m for m in options(sources) if asked(m)])

        def later() -> list[Reposition]:
            return [m for m in options(set(boxes.names)) if not asked(m)]

        return (allowed, later) if allowed else (self._allowed(boxes, later()), None)

    def search(self, start: Boxes, goal: dict[str, np.ndarray], budget: Budget,
               max_depth: int | None = None) -> tuple[Refined | None, Refined]:
        """Weighted best-first search over pick/place moves in predicted space: f = g
        + weight * h, g the steps (a move the arm missed in this solve dearer: `missed`),
        h = (summed distance to the goal) / STEP_SCALE + MOVE_LEFT per move the goal's
        order asks for. A node's moves the order asks for next (a box onto its
        supports in place, what is in the way off: GoalOrder.next_moves) are predicted
        first; the rest wait in the frontier `defer` dearer (None: all at once), so the
        ~500 moves of an 8-box scene cost a prediction only where the asked ones lead
        nowhere. (the plan that reaches the goal or None, the plan predicted to end
        nearest it, by h; where that is not nearer than the start (_nearer), the one
        nearest it of those that move a box in the way of a refused grasp, if any).
        `max_depth`: plans at most this long (default the refiner's)."""
        depth = self.max_depth if max_depth is None else max_depth

        order = GoalOrder(goal, start.kinds())
        anchored = AnchoredGoal(self.relations, goal) if self.relations else None

        def guided(boxes) -> tuple[dict[str, np.ndarray], GoalOrder]:
            """The goal positions and order a scene is ranked by (anchoring.py)."""
            if anchored is None:
                return goal, order
            here = anchored.at(boxes.where())
            return (goal, order) if here is anchored.goal else (here, order.at(here))

        def h(boxes):
            here, by = guided(boxes)
            errors = goal_errors(boxes, here)
            return sum(errors.values()) / STEP_SCALE + MOVE_LEFT * by.moves_left(
                boxes.where(), errors, self.limit)

        tie = itertools.count()
        # a node: (f, tie, g, h, boxes, plan, deferred moves, the scene before its last
        # step where that step is still to be checked for safety, else None)
        frontier = [(self.weight * h(start), next(tie), 0.0, h(start), start, Refined([], []),
                     None, None)]
        nearest = (h(start), Refined([], []))
        clearing = None  # the node nearest the goal among those that clear a refused grasp
        blocking = self.refusals.in_the_way(start)
        seen = set()
        while frontier and not budget.spent():
            f, _, g, distance, boxes, done, deferred, before = heapq.heappop(frontier)
            if before is not None and self.unsafe(before, boxes, done.steps[-1].action):
                continue
            if deferred is None:
                if self.reached(boxes, goal):
                    return done, done
                nearest = min(nearest, (distance, done), key=lambda pair: pair[0])
                in_the_way = self.refusals.in_the_way(boxes)
                if blocking and done.steps and blocking - in_the_way:
                    clearing = min(clearing or (distance, done), (distance, done),
                                   key=lambda pair: pair[0])
                key = tuple(np.round(boxes.positions, 2).ravel())
                if key in seen or len(done.steps) >= depth:
                    continue
                seen.add(key)
                here, by = guided(boxes)
                options, later = self._split(boxes, by, here, in_the_way)
                if later:
                    heapq.heappush(frontier, (f + self.defer, next(tie), g, distance, boxes,
                                              done, later, None))
            else:
                deferred = deferred()
                if not deferred:
                    continue
                options = self._allowed(boxes, deferred)
            # a step's safety (`unsafe`) is checked when its node comes off the frontier:
            # most nodes never do, and the check costs more than the prediction
            EXPANDED.add(1)
            for after, option in zip(self._predict(boxes, options), options, strict=True):
                cost, distance = g + 1 + MISSED * self.missed[option.action], h(after)
                heapq.heappush(frontier, (cost + self.weight * distance, next(tie), cost,
                                          distance, after, done.then(option, after), None,
                                          boxes))
        if clearing is not None and not nearer(nearest[1], start, goal):
            return None, clearing[1]
        return None, nearest[1]


def nearer(plan: Refined, start: Boxes, goal: dict[str, np.ndarray]) -> bool:
    """Is `plan` predicted to end at least NEARER (summed over the boxes) closer to the
    goal than `start` is?"""
    if not plan.steps:
        return False
    before = sum(goal_errors(start, goal).values())
    return sum(goal_errors(plan.predicted[-1], goal).values()) <= before - NEARER
