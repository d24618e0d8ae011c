"""How Abstraction.plan plans a goal on the symbols: a goal of relations stage by stage, its
lowest pairs first, each stage from the state the plan before it predicts; else, or where
the stages do not reach it, at once.

A named pair holds where its bits read the example's pattern or a kept one of its kind
(relation_goal.pair_choices). A stage is planned to any of them, a pair read by a kept
pattern costing half a sure move more than one read as the example reads it
(planning/grounding.py's OTHER_READING_COST); where its plan still ends with a pair read
by a pattern, the stage is planned again to the example's reading alone, and that plan
runs where it is no longer. The operators' effects are unreliable: one whose effect reads
a kept pattern may set a cube 7.5 cm off a block's centre, or lay a bridge's block by a
place beside (cheaper than the spanning operator, and not what the arm can do), where the
example's reading takes as many moves. (Planning the whole goal twice, to the example's
reading first in half the budget and then to the patterns, took 6 of a plan's 10 CPU
seconds at twelve boxes and left the skeletons of bilevel planning no time.)
"""

from __future__ import annotations

from dataclasses import replace

from drake_symplan.abstraction.relation_goal import pair_of, stage_keys
from drake_symplan.planning.budget import Budget
from drake_symplan.symbolic.structs import Goal, Task, flat, goal_of, reaches

# A stage's plan to the example's reading (plan_stage): at most this share of what is
# left of the plan's budget, and this many times the CPU time its first search took, at
# least EXAMPLE_FLOOR CPU seconds
EXAMPLE_SHARE = 0.5
EXAMPLE_TIMES = 2.0
EXAMPLE_FLOOR = 0.25


def stages(goal, atoms: frozenset) -> list[frozenset]:
    """A goal of relations' atoms in growing stages, by Reading.pairs' values (layer,
    relation): those of the first relation's pairs whose lower box stands in the lowest
    layer of the example, then the next relation's in that layer with them, and so on
    up: structures planned from the bottom up, as a person builds them, one at a time,
    with no move that carries a built part."""
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
    found = plan_stage(abstraction, task, start, goal, *options)
    return staged if staged is not None and not found.solved else found


def plan_stage(abstraction, task: Task, start, goal, planner: str, budget: Budget,
               focus: bool, penalties):
    """`task` planned to any reading of its pairs; where that plan ends with a pair read
    by a kept pattern, also to the example's reading alone: that plan where it is no
    longer (module docstring), searched for at most EXAMPLE_TIMES the first search's CPU
    time (EXAMPLE_FLOOR at least; EXAMPLE_SHARE of what is left at most): of as many
    moves, it took as long; of more, four times as long, to no use."""
    cpu = budget.cpu_left()
    found = abstraction.plan_focused(task, start, goal, planner, budget, focus, penalties)
    if not (found.solved and found.steps and goal_of(task.goal).choices):
        return found
    example = Goal(flat(task.goal))
    if reaches(found.steps, task.init, example):
        return found
    cap = min(EXAMPLE_SHARE * budget.cpu_left(),
              max(EXAMPLE_FLOOR, EXAMPLE_TIMES * (cpu - budget.cpu_left())))
    own = abstraction.plan_focused(replace(task, goal=example), start, goal, planner,
                                   Budget.of_cpu(cap), focus, penalties)
    return own if own.solved and len(own.steps) <= len(found.steps) else found


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
        found = plan_stage(abstraction, replace(task, init=state, goal=atoms), start, goal,
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
