"""The search nodes the planners expand in this process, tallied for the solves that read
them (agent/solve.py: a solve's `nodes`): Fast Downward's expanded states, read from its
output, and the continuous level's expanded scenes (abstraction/refiner.py: a search's
node whose moves are predicted, a skeleton's step whose offsets are). pyperplan runs in
a child process and is not counted."""

from __future__ import annotations

import re
import statistics

_FD_EXPANDED = re.compile(r"Expanded (\d+) state|(\d+) expanded")


class Tally:
    """A count that only grows; a reader takes the difference across what it measures."""

    def __init__(self):
        self.total = 0

    def add(self, n: int) -> None:
        self.total += n


EXPANDED = Tally()


def fd_expanded(output: str | None) -> int:
    """The states a Fast Downward search expanded, by its output: its closing count, else
    its last progress line's (a search stopped at its limits prints no closing count)."""
    return max((int(a or b) for a, b in _FD_EXPANDED.findall(output or "")), default=0)


def median_nodes(records: list[dict]) -> float | None:
    """The median of per-solve records' "nodes", or None where one has no count (records
    made before solves counted them)."""
    if not records or any("nodes" not in r for r in records):
        return None
    return float(statistics.median(r["nodes"] for r in records))
