"""How the agent solves: one `SolveConfig`, from the command line through `eval planning`
and `reproduce` to the solve loop. No Drake here, so the CLI can check it first."""

from __future__ import annotations

import dataclasses as dc

from drake_symplan.agent.planning_modes import PLANNING_MODES
from drake_symplan.planning.planners import DEFAULT_TIMEOUT, PLANNERS

GOAL_CHECKS = ("relations", "scene")


@dc.dataclass(frozen=True)
class SolveConfig:
    """planner: a planning.planners.PLANNERS back-end; cpu_seconds: each plan's budget
    (planning/budget.py: CPU seconds with a wall-clock cap; bilevel and continuous
    planning: the whole search's), the CLI's --timeout; monitor: perceive after each step
    and replan on a mismatch (False: open loop, as the paper); max_replans: replans per
    solve; refine (the CLI's --no-refine turns it off): complete a plan on symbols as it
    runs, each step's offsets chosen among its offset variants (abstraction/offsets.py's
    geometric scorer) and boxes put down at their goal spot (agent/reposition.py);
    planning: a key of agent.planning_modes.PLANNING_MODES; alternatives: bilevel
    planning's skeletons beyond the first two when none refines (abstraction/bilevel.py:
    skeletons); goal_check: how a problem made from a written goal (a spec) is judged,
    "relations" (the relations it names, wherever they stand) or "scene" (every box within
    5 cm of the built example, the paper's check); a goal scene alone is always "scene"."""

    planner: str = "fd"
    cpu_seconds: float = DEFAULT_TIMEOUT
    monitor: bool = True
    # 4: on 162 reproducible arm problems 4 more solves than 2 and none fewer
    max_replans: int = 4
    refine: bool = True
    planning: str = "bilevel"
    alternatives: int = 0
    goal_check: str = "relations"

    def __post_init__(self):
        if self.goal_check not in GOAL_CHECKS:
            raise ValueError(f"unknown goal check {self.goal_check!r}; one of {GOAL_CHECKS}")
        if self.planner not in PLANNERS:
            raise ValueError(f"unknown planner {self.planner!r}; one of {sorted(PLANNERS)}")
        if not self.cpu_seconds > 0:
            raise ValueError(f"the planner timeout must be positive, got {self.cpu_seconds:g}")
        if self.max_replans < 0:
            raise ValueError(f"max_replans must be 0 or more, got {self.max_replans}")
        if self.alternatives < 0:
            raise ValueError(f"alternatives must be 0 or more, got {self.alternatives}")
        if self.planning not in PLANNING_MODES:
            raise ValueError(f"unknown planning {self.planning!r}; one of "
                             f"{tuple(PLANNING_MODES)}")

    @property
    def timeout(self) -> float:
        """`cpu_seconds` by the CLI's name (--timeout), as tools/run_demo.py reads it."""
        return self.cpu_seconds

    def to_dict(self) -> dict:
        return dc.asdict(self)

    def replace(self, **changes) -> SolveConfig:
        return dc.replace(self, **changes)

    def flags(self) -> list[str]:
        """The `symplan solve` / `eval planning` flags (cli/options.py) that give this
        config, less the monitoring (eval planning runs both modes): for child processes."""
        flags = ["--planner", self.planner, "--timeout", f"{self.cpu_seconds:g}",
                 "--max-replans", str(self.max_replans), "--planning", self.planning]
        return (flags + ([] if self.refine else ["--no-refine"])
                + (["--alternatives", str(self.alternatives)] if self.alternatives else [])
                + (["--goal-check", self.goal_check] if self.goal_check != "relations" else []))


DEFAULT_SOLVE = SolveConfig()
