"""What a solve returns (SolveResult, its statuses and failure causes) and the clock that
splits its wall time into phases (PhaseClock)."""

from __future__ import annotations

import dataclasses as dc
import time
from contextlib import contextmanager

from drake_symplan.symbolic.structs import PlanStep

STATUSES = ("success", "failure", "no_plan", "timeout", "infeasible", "error")
FAILURE_CAUSES = ("no_plan", "timeout", "execution", "perception", "infeasible", "error")
PHASES = ("perceive", "symbols", "plan", "execute", "total")


@dc.dataclass
class SolveResult:
    """What `solve` returns; `to_json` is the documented JSON. `plan` is the first plan,
    `executed` every step executed (repositionings and replans included)."""

    status: str
    plan: list[PlanStep] = dc.field(default_factory=list)
    executed: list[PlanStep] = dc.field(default_factory=list)
    replans: int = 0
    objects: dict[str, dict] = dc.field(default_factory=dict)
    seconds: dict[str, float] = dc.field(default_factory=dict)
    failure_cause: str | None = None
    message: str = ""
    # On a failure: do the goal's atoms hold in the last perceived scene? True with objects
    # off their goal positions means the symbols did not capture the goal; False means the
    # plan did not reach it (an operator's prediction or the execution went wrong).
    symbolic_goal_reached: bool | None = None
    # The first plan's candidates (bilevel and continuous planning): the plans looked at,
    # the rejected ones with why (abstraction/bilevel.py: Candidate).
    candidates: list = dc.field(default_factory=list)
    # Which level found the first plan: "symbolic", "bilevel", "receding" (a long skeleton's
    # first steps, to its subgoal), "continuous", "nearest" (no
    # plan reaches the goal in prediction: the steps predicted nearest it) or "oracle".
    level: str = ""
    # Steps after which a box perceived resting on the carried one no longer rests on it
    # (skills/carry.riders on the perceived scenes before and after): riders dropped.
    dropped_riders: int = 0
    # Plans made again where a plan ended at its subgoal (receding planning), apart from
    # the replans on a departure
    subgoals: int = 0
    # Steps the arm refused that were planned around (apart from the replans)
    refusals: int = 0
    # Search nodes the solve's plans expanded, all of them (planning/nodes.py: Fast
    # Downward's states, the continuous level's scenes)
    nodes: int = 0
    # A goal of relations: those not held in the last perceived scene (the verdict), and
    # on the simulator's truth (evaluation only; no decision reads it)
    unmet: list[str] | None = None
    unmet_true: list[str] | None = None

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"unknown status {self.status!r}; expected one of {STATUSES}")

    @property
    def success(self) -> bool:
        return self.status == "success"

    def to_json(self) -> dict:
        out = {"status": self.status, "plan": [str(s) for s in self.plan],
               "executed": [str(s) for s in self.executed], "replans": self.replans,
               "objects": self.objects, "level": self.level,
               "seconds": {k: round(v, 4) for k, v in self.seconds.items()}}
        if self.candidates:
            out["candidates"] = [c.to_json() for c in self.candidates]
        if self.dropped_riders:
            out["dropped_riders"] = self.dropped_riders
        if self.subgoals:
            out["subgoals"] = self.subgoals
        if self.refusals:
            out["refusals"] = self.refusals
        out["nodes"] = self.nodes
        if self.unmet is not None:
            out["relations"] = {"unmet": self.unmet, "unmet_true": self.unmet_true}
        if not self.success:
            out["failure_cause"] = self.failure_cause
            out["message"] = self.message
            out["symbolic_goal_reached"] = self.symbolic_goal_reached
        return out


class PhaseClock:
    """Wall time per phase; perception inside other phases is moved to "perceive"."""

    def __init__(self, robot):
        """`robot`: a robot.backends.Backend (its perception_seconds)."""
        self.robot = robot
        self.seconds = dict.fromkeys(PHASES, 0.0)

    @contextmanager
    def __call__(self, phase: str):
        start, seen = time.perf_counter(), self.robot.perception_seconds
        try:
            yield
        finally:
            perceived = self.robot.perception_seconds - seen
            self.seconds[phase] += time.perf_counter() - start - perceived
            self.seconds["perceive"] += perceived
