"""The goal's order (abstraction/goal_order.py): what stands on what in a goal, and how many
moves a scene is from it, on small towers with known answers."""

from __future__ import annotations

import numpy as np

from drake_symplan.abstraction.goal_order import GoalOrder
from drake_symplan.boxes import goal_distances

KINDS = {"a": "cube", "b": "cube", "c": "long", "x": "cube"}
# goal: a on b on the long block c; x on the table
GOAL = {"c": [0.70, 0.00, 0.025], "b": [0.70, 0.05, 0.075], "a": [0.70, 0.05, 0.125],
        "x": [0.55, -0.20, 0.025]}


def moves_left(where: dict) -> int:
    order = GoalOrder({n: np.array(p) for n, p in GOAL.items()}, KINDS)
    where = {n: np.array(p, float) for n, p in where.items()}
    return order.moves_left(where, goal_distances(where, order.goal), 0.02)


def test_the_goal_names_what_stands_on_what():
    order = GoalOrder({n: np.array(p) for n, p in GOAL.items()}, KINDS)
    assert order.under == {"c": [], "b": ["c"], "a": ["b"], "x": []}
    assert order.beneath["a"] == {"b", "c"}


def test_each_box_out_of_place_moves_once_and_twice_where_it_holds_a_lower_place():
    assert moves_left(GOAL) == 0
    assert moves_left({**GOAL, "a": [0.55, 0.20, 0.025]}) == 1  # a on the table
    # x sits where b goes, b on the table, a beside: x off, b on, a on
    assert moves_left({**GOAL, "x": [0.70, 0.05, 0.075], "b": [0.55, 0.20, 0.025],
                       "a": [0.85, 0.20, 0.025]}) == 3
    # a sits where a goes but on x, which holds b's place: a off, x off, b on, a back
    assert moves_left({**GOAL, "x": [0.70, 0.05, 0.075], "b": [0.55, 0.20, 0.025]}) == 4


def next_moves(where: dict, covered=()) -> dict:
    order = GoalOrder({n: np.array(p) for n, p in GOAL.items()}, KINDS)
    where = {n: np.array(p, float) for n, p in where.items()}
    return order.next_moves(where, goal_distances(where, order.goal), 0.02, set(covered))


def test_the_order_asks_for_a_box_onto_its_support_in_place_and_for_what_is_in_the_way():
    assert next_moves(GOAL) == {}
    # x sits on c where b goes, b and a on the table: b onto c (in place), x anywhere
    # (its goal on the table, no box near it); a waits for b
    assert next_moves({**GOAL, "x": [0.70, 0.05, 0.075], "b": [0.55, 0.20, 0.025],
                       "a": [0.85, 0.20, 0.025]}) == {"b": {"c"}, "x": None}
    # a on b, b on the table off its goal: b carries a, so a goes first, anywhere
    assert next_moves({**GOAL, "b": [0.55, 0.20, 0.025], "a": [0.55, 0.20, 0.075]},
                      covered={"b"}) == {"a": None}
    # x off its goal on the table, c beside its goal: x goes beside c
    assert next_moves({**GOAL, "x": [0.40, 0.20, 0.025], "c": [0.55, -0.15, 0.025],
                       "b": [0.40, 0.0, 0.025], "a": [0.30, 0.0, 0.025]})["x"] == {"c"}
