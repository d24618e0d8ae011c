"""How the agent solves: one `SolveConfig`, from the command line through `eval planning`
and `reproduce` to the solve loop. No Drake here, so the CLI can check it first."""

from __future__ import annotations

import dataclasses as dc

from drake_symplan.planning.planners import DEFAULT_TIMEOUT, PLANNERS

# How a plan is had (agent/planning_modes.py), and "oracle": the problem's recorded actions
# replayed open loop, the evaluation's ceiling row.
PLANNING = ("bilevel", "symbolic", "continuous")
PLANNING_MODES = (*PLANNING, "oracle")


@dc.dataclass(frozen=True)
class SolveConfig:
    """planner: a planning.planners.PLANNERS back-end; timeout: its seconds per call
    (bilevel and continuous planning: the CPU seconds of the search); monitor: perceive
    after each step and replan on a mismatch (False: open loop, as the paper);
    max_replans: replans per solve; refine: with symbolic planning, choose each step's
    offsets among interchangeable operators and put boxes down at their goal spot
    (agent/refine.py); planning: PLANNING_MODES (agent/planning_modes.py); alternatives:
    bilevel planning's skeletons beyond the first two when none refines
    (abstraction/bilevel.py: skeletons)."""

    planner: str = "fd"
    timeout: float = DEFAULT_TIMEOUT
    monitor: bool = True
    # 4: on 162 reproducible arm problems 4 more solves than 2 and none fewer (docs/planning.md)
    max_replans: int = 4
    refine: bool = True
    planning: str = "bilevel"
    alternatives: int = 0

    def __post_init__(self):
        if self.planner not in PLANNERS:
            raise ValueError(f"unknown planner {self.planner!r}; one of {sorted(PLANNERS)}")
        if not self.timeout > 0:
            raise ValueError(f"the planner timeout must be positive, got {self.timeout:g}")
        if self.max_replans < 0:
            raise ValueError(f"max_replans must be 0 or more, got {self.max_replans}")
        if self.alternatives < 0:
            raise ValueError(f"alternatives must be 0 or more, got {self.alternatives}")
        if self.planning not in PLANNING_MODES:
            raise ValueError(f"unknown planning {self.planning!r}; one of {PLANNING_MODES}")

    def to_dict(self) -> dict:
        return dc.asdict(self)

    def replace(self, **changes) -> SolveConfig:
        return dc.replace(self, **changes)

    def flags(self) -> list[str]:
        """The `symplan solve` / `eval planning` flags (cli/options.py) that give this
        config, less the monitoring (eval planning runs both modes): for child processes."""
        flags = ["--planner", self.planner, "--timeout", f"{self.timeout:g}",
                 "--max-replans", str(self.max_replans), "--planning", self.planning]
        return (flags + ([] if self.refine else ["--no-refine"])
                + (["--alternatives", str(self.alternatives)] if self.alternatives else []))


DEFAULT_SOLVE = SolveConfig()
