"""The verdict of one solve on the scene perceived last: every box within GOAL_TOLERANCE of
its perceived goal position, or a goal of relations held wherever it stands; the
simulator's view reported beside it, for evaluation only (no decision reads it)."""

from __future__ import annotations

from drake_symplan.agent import beliefs
from drake_symplan.agent.result import SolveResult
from drake_symplan.boxes import GOAL_TOLERANCE, goal_reached
from drake_symplan.relations import unmet

# the result's statuses a solve's ending cause keeps; any other is a "failure"
STATUSES = ("no_plan", "timeout", "infeasible", "error")


def verdict(result: SolveResult, true_states: dict, goal_scene, final, relations,
            abstraction, goal_atoms, cause: str, message: str) -> SolveResult:
    """`result` completed with the check on `final` (the perceived scene after the last
    step) against the perceived `goal_scene` or `relations`, `true_states` (the
    simulator's) reported beside; else its status for `cause` ("execution": the plan ran
    out; a planner's or the arm's, with `message`). `goal_atoms` (None: never planned)
    says whether the symbols reached the goal where the check fails."""
    result.objects = beliefs.goal_report(beliefs.positions(goal_scene),
                                         beliefs.positions(final),
                                         {n: s.position for n, s in true_states.items()})
    errors = {n: o["error_cm"] for n, o in result.objects.items()}
    if relations:
        result.unmet = unmet(relations, final.object_states())
        result.unmet_true = unmet(relations, true_states)
        reached = not result.unmet
    else:  # error_cm is rounded to 0.01 cm: the check reads what the result reports
        reached = goal_reached({n: None if e is None else e / 100 for n, e in errors.items()})
    if reached and cause != "perception":
        result.status = "success"
        return result
    if goal_atoms is not None and set(goal_scene.names) <= set(final.names):
        result.symbolic_goal_reached = abstraction.goal_holds(abstraction.read_scene(final),
                                                              goal_atoms)
    if cause == "execution" and relations:
        message = message or f"not held: {'; '.join(result.unmet)}"
    elif cause == "execution":
        far = {n: e for n, e in errors.items() if e is not None and e > GOAL_TOLERANCE * 100}
        message = message or f"objects farther than {GOAL_TOLERANCE * 100:g} cm from " \
                             f"their goal: {far}"
    result.status = cause if cause in STATUSES else "failure"
    result.failure_cause, result.message = cause, message
    return result
