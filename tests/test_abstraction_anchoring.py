"""A goal of relations' example positions anchored where its structures stand."""

from __future__ import annotations

import numpy as np
from bilevel_fixtures import STACK, Stacking, boxes

from drake_symplan.abstraction.anchoring import AnchoredGoal, structures
from drake_symplan.abstraction.refiner import Refiner
from drake_symplan.planning.budget import Budget
from drake_symplan.relations import parse

# the example: a tower of two (a on b) at x 0.7 and a row of two (c, d) at x 0.5
EXAMPLE = {"a": np.array([0.7, 0.0, 0.075]), "b": np.array([0.7, 0.0, 0.025]),
           "c": np.array([0.5, 0.1, 0.025]), "d": np.array([0.5, 0.155, 0.025])}
SPEC = parse(["tower a b", "row c d"])


def test_structures_are_the_connected_named_boxes_led_by_their_lowest():
    assert structures(SPEC, EXAMPLE) == [("b", "a"), ("c", "d")]
    # a bridge joins the towers of its supports into one structure
    spec = parse(["tower x y", "tower z w", "bridge l x z"])
    example = {"y": np.array([0.7, 0.0, 0.025]), "x": np.array([0.7, 0.0, 0.075]),
               "w": np.array([0.7, 0.15, 0.025]), "z": np.array([0.7, 0.15, 0.075]),
               "l": np.array([0.7, 0.075, 0.125])}
    assert structures(spec, example) == [("y", "w", "x", "z", "l")]


TALL = {"a": np.array([0.7, 0.0, 0.125]), "b": np.array([0.7, 0.0, 0.075]),
        "c": np.array([0.7, 0.0, 0.025])}


def test_a_structure_begun_elsewhere_is_the_goal_where_it_stands():
    anchored = AnchoredGoal(parse(["tower a b c"]), TALL)
    # b set on c 20 cm along -y of their example places: a's goal is on b there
    begun = {"a": np.array([0.5, 0.3, 0.025]), "b": np.array([0.7, -0.2, 0.075]),
             "c": np.array([0.7, -0.2, 0.025])}
    here = anchored.at(begun)
    np.testing.assert_allclose(here["a"], [0.7, -0.2, 0.125])
    np.testing.assert_allclose(here["c"], begun["c"])
    # c moved but nothing set on it as in the example, or a on b standing apart from c:
    # the example's places stay (the stack is carried onto c, not built under)
    moved = {**begun, "b": np.array([0.5, 0.2, 0.025])}
    apart = {"a": np.array([0.5, 0.2, 0.075]), "b": np.array([0.5, 0.2, 0.025]),
             "c": np.array([0.7, -0.2, 0.025])}
    for scene in (moved, apart):
        kept = anchored.at(scene)
        for name, place in TALL.items():
            np.testing.assert_allclose(kept[name], place)


def test_the_search_finishes_a_tower_where_it_has_begun():
    # b on c, 25 cm off their example places: one move (a onto b) holds the tower there
    scene = boxes(a=(0.5, -0.2, 0.025), b=(0.7, 0.25, 0.075), c=(0.7, 0.25, 0.025))
    refiner = Refiner(list(STACK.values()), Stacking())
    refiner.relations = tuple(parse(["tower a b c"]))
    found, _ = refiner.search(scene, TALL, Budget.of_cpu(10))
    assert [str(s.action) for s in found.steps] == ["pick(a:center) place(b:center)"]
    assert refiner.predictions == 3  # the order asks for a onto b at once
