"""How Abstraction.plan plans a goal on the symbols: a goal of relations stage by stage, its
lowest pairs first, each stage from the state the plan before it predicts; else, or where
the stages do not reach it, at once.

A named pair holds where its bits read the example's pattern or a kept one of its kind
(relation_goal.pair_choices). A stage is planned to any of them in one search, a pair read
by a kept pattern costing half a sure move more than one read as the example reads it
(planning/grounding.py's OTHER_READING_COST): of plans of as many sure moves, the
example's reading is planned. A move is dearer by the boxes it carries (abstraction's
CARRY_COST, LiftedOperator.carried): a block laid across two supports names the second
but carries nothing, and priced as a carry it lost to a block set beside one support
and then the other (a kept pattern of "bears", and not what the arm can do).
"""

from __future__ import annotations

from dataclasses import replace

from drake_symplan.abstraction.relation_goal import pair_of, stage_keys
from drake_symplan.planning.budget import Budget
from drake_symplan.symbolic.structs import Goal, Task, goal_of


def stages(goal, atoms: frozenset) -> list[frozenset]:
    """A goal of relations' atoms in growing stages, by Reading.pairs' values (layer,
    relation, place in a row): those of the first relation's pairs whose lower box stands
    in the lowest layer of the example (a row's first pair alone, then its next), then
    the next relation's in that layer with them, and so on up: structures planned from
    the bottom up, as a person builds them, one at a time, with no move that carries a
    built part."""
    if any(len(a) != 3 for a in atoms):  # a model without relations: one stage
        return [atoms]
    choices = goal_of(atoms).choices
    return [Goal((a for a in atoms if goal.pairs[pair_of(goal.pairs, a)] <= stage),
                 [(key, alts) for key, alts in choices if goal.pairs[key] <= stage])
            for stage in stage_keys(goal)]


def plan_goal(abstraction, task: Task, start, goal, budget: Budget, planner: str,
              focus: bool, penalties):
    """`task` planned stage by stage where it is a goal of relations (`plan_stages`),
    else, or where the stages find no plan to the goal, at once; where that finds none
    either, the plan of the first stages (level "staged")."""
    options = (planner, budget, focus, penalties)
    staged = None
    if goal.pairs is not None:
        staged = plan_stages(abstraction, task, start, goal, *options)
        if staged is not None and not staged.subgoal:
            return staged
    found = abstraction.plan_focused(task, start, goal, *options)
    return staged if staged is not None and not found.solved else found


def plan_stages(abstraction, task: Task, start, goal, planner: str, budget: Budget,
                focus: bool, penalties):
    """`task` planned stage by stage (`stages`), each from the state the plan before it
    predicts; where a stage finds no plan, the plan of the stages before it that moves
    something (level "staged": the agent runs it and plans on from what it sees, where
    what no operator predicts may hold: two towers' tops a bridge apart); None where
    there is none or the stages do not reach the goal."""
    parts = stages(goal, task.goal)
    if len(parts) < 2:
        return None
    state, steps = task.init, []
    for atoms in parts:
        found = abstraction.plan_focused(replace(task, init=state, goal=atoms), start, goal,
                                         planner, budget, focus, penalties)
        if not found.solved:
            return replace(found, status="solved", steps=steps, level="staged") \
                if steps else None
        for step in found.steps:
            state = step.apply(state)
        steps += found.steps
    if not goal_of(task.goal) <= state:
        return None
    return replace(found, steps=steps, message="")
