"""How the agent completes a plan on symbols as it runs (agent/solve.py's loop): each step's
offsets chosen by the geometric scorer (abstraction/offsets.py), the order of steps the
symbols leave free, a tower's base moved to where its step has room, and a box the arm
names in its way set aside (agent/reposition.py). The symbols say which box is on which,
never where on the table; these choices are made from the perceived boxes and the
skill's own geometry, with no simulator.
"""

from __future__ import annotations

import dataclasses as dc

from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.offsets import GeometricScorer, choose
from drake_symplan.abstraction.set_down import set_down_meets, set_down_tips
from drake_symplan.agent import beliefs
from drake_symplan.agent.reposition import (
    REPOSITIONS_PER_OBJECT,
    clearing_step,
    room_step,
    unblocking,
)
from drake_symplan.boxes import GOAL_TOLERANCE, goal_distances, neighbour_pairs
from drake_symplan.relations import holding
from drake_symplan.skills.geometry import grasp_refused, release_refused
from drake_symplan.symbolic.structs import PlanStep, Reposition, Step


@dc.dataclass
class Planned:
    """A step to run, with the scene the plan predicted after it (None: a plan on
    symbols, a repositioning)."""

    step: PlanStep
    predicted: Boxes | None = None


class Completion:
    """The part of a solve's loop (solve._Run) that completes a plan on symbols: it reads
    the loop's scene, plan, goal and counters."""

    def _unblock(self) -> None:
        """Where the next step would set its source down against a box it does not name
        (set_down.set_down_meets), the later step that moves that box runs first if the
        plan still reaches the goal (reposition.unblocking), else, where the goal leaves
        the step's target free to stand elsewhere (`_movable_base`), the target is first
        moved to where the step has room (reposition.room_step); once per step. (Setting
        such a box aside instead put it beside a tower the arm then could not grasp it
        by.)"""
        step = self.todo[0].step
        if not isinstance(step, Step) or str(step) in self.unblocked:
            return
        self.unblocked.add(str(step))
        chosen = self._offsets(step)
        met = set_down_meets(Boxes.of(self.scene), chosen.action) - set(step.args)
        later = unblocking(step, self.rest[1:], self.believed, self.goal_atoms, met)
        if later is not None:
            self.todo.insert(0, self.todo.pop(later + 1))
        elif met and self._movable_base(step) and self._repositions_left():
            room = room_step(chosen, self.scene)
            if room is not None:
                self.todo.insert(0, Planned(room))
                self.repositions += 1

    def _movable_base(self, step: Step) -> bool:
        """May `step`'s target move before it, where the goal is one of relations? Where
        the goal pairs it with no box but the step's source (a tower's base, not a row's
        cube nor a bridge's support, whose place the other boxes of the pair fix)."""
        pairs = self.goal.reading.pairs if self.goal and self.goal.reading else None
        src, tgt = step.action.source, step.action.target
        return bool(self.relations) and pairs is not None and all(
            src in pair for pair in pairs if tgt in pair)

    def _repositions_left(self) -> bool:
        """Has the solve made fewer repositionings than REPOSITIONS_PER_OBJECT a box?"""
        return self.repositions < REPOSITIONS_PER_OBJECT * len(self.scene.names)

    def _completes(self) -> bool:
        """Does the agent complete the plan as it runs (offsets, repositionings)? For plans
        on symbols only: plans checked in continuous space chose offsets and moves by
        search, the oracle replays."""
        return self.config.refine and self.planner.symbolic_plan

    def _offsets(self, step: PlanStep) -> PlanStep:
        """`step` with the offsets the geometric scorer chooses, completing a plan on
        symbols (abstraction/offsets.py), else as planned: the best that does not set its
        source down to topple (set_down.set_down_tips) nor asks what the arm's own rules
        refuse on the perceived boxes (a palm that would strike a box, a grasp under a
        stack, a source driven into a box or set down out of the cameras' view:
        skills/geometry.py, as the refiner's search asks them), where one does not, held
        nearest its centre (offsets.central)."""
        if not (self._completes() and isinstance(step, Step)):
            return step
        with self.clock("symbols"):
            related = neighbour_pairs(self.goal_scene, self.abs.bundle.relevance_radius)
            scorer = GeometricScorer(beliefs.positions(self.scene),
                                     beliefs.positions(self.goal_scene), related)
            boxes, objects = Boxes.of(self.scene), self.scene.object_states()
            return choose(self.abs.bundle.planning, step, self.rest, self.believed,
                          self.goal_atoms, scorer,
                          lambda a: a in self.refused or set_down_tips(boxes, a)
                          or grasp_refused(a, objects) or release_refused(a, objects),
                          boxes.riding)

    def _clearing(self, step: PlanStep, obstacles) -> Reposition | None:
        """Completing a plan on symbols, with repositionings left: a step that sets aside
        a box the arm named in its way (reposition.clearing_step), one the goal leaves
        free: in no pair of its relations that holds already (where a structure stands
        is its own; a box of one not begun may stand anywhere), of a whole-scene goal not
        at its goal position already."""
        if not (self._completes() and obstacles and self._repositions_left()):
            return None
        now, goal = beliefs.positions(self.scene), beliefs.positions(self.goal_scene)
        at_goal = goal_distances(now, {n: p for n, p in goal.items() if n in now})
        keep = holding(self.relations, self.scene.object_states()) if self.relations else {
            n for n, d in at_goal.items() if d <= GOAL_TOLERANCE}
        clear = clearing_step(obstacles, step, self.scene, keep)
        self.repositions += clear is not None
        return clear
