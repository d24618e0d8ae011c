"""A plan's time budget: CPU seconds with a wall-clock cap, counted from when it is made.

The CPU is this process's and its finished children's (the symbolic planner runs in child
processes), so a problem gets the same answer on a busy host as on a quiet one; the
wall-clock cap (WALL_FACTOR times the CPU seconds unless told) bounds a host so busy that
the CPU seconds come slowly. One budget per plan flows down to the planner's call: a part
of it is a `share`, what is left of it is `cpu_left` / `wall_left` (planners.py takes
those as `cpu_seconds` and its wall-clock seconds).
"""

from __future__ import annotations

import time

from drake_symplan.planning.planners import WALL_FACTOR
from drake_symplan.planning.processes import cpu_used


class Budget:
    """CPU seconds with a wall-clock cap (module docstring), counted from construction."""

    def __init__(self, cpu_seconds: float, wall_seconds: float):
        self.cpu, self.wall = cpu_seconds, wall_seconds
        self.cpu0, self.wall0 = cpu_used(), time.perf_counter()

    @classmethod
    def of_cpu(cls, cpu_seconds: float) -> Budget:
        """`cpu_seconds` with the usual wall-clock cap, WALL_FACTOR times that."""
        return cls(cpu_seconds, WALL_FACTOR * cpu_seconds)

    def cpu_left(self) -> float:
        return self.cpu - (cpu_used() - self.cpu0)

    def wall_left(self) -> float:
        return self.wall - (time.perf_counter() - self.wall0)

    def left(self) -> float:
        """CPU seconds left (the wall-clock cap counted as CPU when it is nearer)."""
        return min(self.cpu_left(), self.wall_left())

    def spent(self) -> bool:
        return self.left() <= 0

    def share(self, fraction: float) -> Budget:
        """A budget of `fraction` of what is left, from now."""
        left = max(self.left(), 0.0)
        return Budget(fraction * left, fraction * left * self.wall / max(self.cpu, 1e-9))
