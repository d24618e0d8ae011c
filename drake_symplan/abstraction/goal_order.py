"""What a goal scene stands on what, and how many moves a scene is at least from it by that
order: the continuous search's heuristic and its first depth bound (abstraction/bilevel.py).

A box is in place when it stands at its goal position and everything the goal puts under
it is in place. Each box not in place moves at least once, and twice where it stands at its
goal on the wrong support (off, then back) or holds the goal place of a box that the goal
puts under it (a tower's top sitting where the box under it must go). A count, not a
bound: a pick carries what rides on the source, so one move may put a whole stack in place.
"""

from __future__ import annotations

import copy

import numpy as np

from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.relations import REST_TOL, meets_at

REACH = 0.2  # m: a box set down beside another lands at most this far from it


def _stands_on(top: np.ndarray, top_kind: str, below: np.ndarray, below_kind: str) -> bool:
    """Does a box of `top_kind` centred at `top` stand on one of `below_kind` at `below`
    (its bottom meets the top, relations.meets_at; its centre within the lower box's
    longest half extent: a goal of positions has no yaw)?"""
    reach = max(HALF_EXTENTS[below_kind][:2])
    return meets_at(top_kind, top[2], below_kind, below[2]) and \
        float(np.linalg.norm(top[:2] - below[:2])) <= reach


class GoalOrder:
    """The goal's supports: `under[n]`, the boxes box n stands on in the goal, and
    `beneath[n]`, those and everything under them."""

    def __init__(self, goal: dict[str, np.ndarray], kinds: dict[str, str]):
        self.goal = {n: np.asarray(p, float) for n, p in goal.items()}
        self.under = {n: [m for m in self.goal if m != n and _stands_on(
            self.goal[n], kinds[n], self.goal[m], kinds[m])] for n in self.goal}
        self.beneath = {n: self._beneath(n) for n in self.goal}
        # a box whose bottom is higher than REST_TOL stands on another box
        self.goal_floor = {n: HALF_EXTENTS[kinds[n]][2] + REST_TOL for n in self.goal}

    def at(self, goal: dict[str, np.ndarray]) -> GoalOrder:
        """The same order (who stands on whom) with its boxes' goal positions at `goal`
        (a goal of relations guided where its structures stand: anchoring.py)."""
        out = copy.copy(self)
        out.goal = goal
        return out

    def _beneath(self, name: str) -> set[str]:
        found, frontier = set(), list(self.under[name])
        while frontier:
            m = frontier.pop()
            if m not in found:
                found.add(m)
                frontier.extend(self.under[m])
        return found

    def in_place(self, errors: dict[str, float], limit: float) -> set[str]:
        """The boxes in place: within `limit` of their goal (`errors`), on boxes in place."""
        at = {n for n, e in errors.items() if e <= limit}
        in_place: dict[str, bool] = {}

        def placed(n: str) -> bool:
            if n not in in_place:
                in_place[n] = False  # a cycle of supports (a perceived goal's slip) is none
                in_place[n] = n in at and all(placed(m) for m in self.under[n])
            return in_place[n]

        return {n for n in self.goal if placed(n)}

    def moves_left(self, where: dict[str, np.ndarray], errors: dict[str, float],
                   limit: float) -> int:
        """The moves a scene (`where`, with each box's distance to its goal, `errors`) is
        from the goal by the order (module docstring); boxes within `limit` are at goal."""
        placed = self.in_place(errors, limit)
        count = 0
        for n in self.goal:
            if n in placed:
                continue
            count += 1
            if errors[n] <= limit or self._holds_place(n, where[n], self.beneath[n], limit):
                count += 1
        return count

    def _holds_place(self, name: str, at: np.ndarray, others, limit: float) -> bool:
        return any(float(np.linalg.norm(at - self.goal[m])) <= limit
                   for m in others if m != name)

    def next_moves(self, where: dict[str, np.ndarray], errors: dict[str, float],
                   limit: float, covered: set[str]) -> dict[str, set[str] | None]:
        """The moves the order asks for next, as {box: the boxes it may be placed on, None
        for any}: a box not in place with nothing on it (not in `covered`) goes onto its
        goal's supports once they are in place (a box whose goal is on the table, beside a
        box within REACH of its goal); one whose supports are not in place moves only
        if it is in the way (it stands on another box, or holds the goal place of a box
        not in place), anywhere."""
        placed = self.in_place(errors, limit)
        out: dict[str, set[str] | None] = {}
        for n in self.goal:
            if n in placed or n in covered:
                continue
            if all(m in placed for m in self.under[n]):
                out[n] = set(self.under[n]) or {
                    m for m in where if m != n and float(np.linalg.norm(
                        where[m][:2] - self.goal[n][:2])) <= REACH} or None
            elif where[n][2] > self.goal_floor[n] or self._holds_place(
                    n, where[n], set(self.goal) - placed, limit):
                out[n] = None
        return out
