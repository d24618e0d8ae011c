"""The one geometry (relations.py): rests-on, riders, top, and each goal relation on scenes
built to hold it and to miss it by a little."""

from __future__ import annotations

import numpy as np
import pytest

from drake_symplan.datasets import ObjectState
from drake_symplan.relations import (
    Relation,
    SpecError,
    holding,
    parse,
    rests_on,
    riders,
    top,
    unmet,
)


def box(name, kind, x, y, z, yaw=0.0, tilt=0.0):
    return ObjectState(name, kind, np.array([x, y, z], float), yaw, tilt)


def scene(*boxes):
    return {b.name: b for b in boxes}


TOWER = scene(box("a", "cube", 0.7, 0.0, 0.125), box("b", "cube", 0.7, 0.0, 0.075),
              box("c", "cube", 0.7, 0.0, 0.025))


def test_top_rests_on_and_riders():
    assert top(TOWER["c"]) == pytest.approx(0.05)
    assert top(box("t", "long", 0.7, 0, 0.025, tilt=np.pi / 2)) == pytest.approx(0.15)
    assert rests_on(TOWER["b"], TOWER["c"]) and not rests_on(TOWER["c"], TOWER["b"])
    assert not rests_on(TOWER["a"], TOWER["c"])  # a rests on b, not on c
    assert riders("c", TOWER) == ["b", "a"] and riders("a", TOWER) == []
    # 1.4 cm above its support still rests (REST_TOL 1.5 cm); 2 cm does not
    assert rests_on(box("u", "cube", 0.7, 0, 0.089), TOWER["c"])
    assert not rests_on(box("u", "cube", 0.7, 0, 0.095), TOWER["c"])
    # its centre 3.4 cm off a cube's centre: over the footprint grown by 1 cm; 3.6 cm: not
    assert rests_on(box("u", "cube", 0.7, 0.034, 0.075), TOWER["c"])
    assert not rests_on(box("u", "cube", 0.7, 0.036, 0.075), TOWER["c"])


def test_on_and_tower_hold_wherever_they_stand_and_miss_by_a_little():
    tower = parse(["tower a b c"])
    assert unmet(tower, TOWER) == []
    moved = {n: box(n, o.type, 0.5, -0.3, o.position[2]) for n, o in TOWER.items()}
    assert unmet(tower, moved) == []  # anywhere on the table
    lifted = {**TOWER, "a": box("a", "cube", 0.7, 0.0, 0.145)}
    assert unmet(tower, lifted) == ["'tower a b c': a is not on b"]
    tipped = {**TOWER, "a": box("a", "cube", 0.7, 0.0, 0.125, tilt=0.3)}
    assert unmet(parse(["on a b"]), tipped) == ["'on a b': a is not on b"]
    assert unmet(parse(["on a x"]), TOWER) == ["'on a x': x not seen"]


def test_holding_names_the_boxes_of_the_pairs_that_hold_already():
    lone = box("d", "cube", 0.5, 0.3, 0.025)  # named, in no pair that holds
    assert holding(parse(["tower a b c", "tower d a"]), {**TOWER, "d": lone}) == {"a", "b", "c"}
    # a tower of three with its top lifted off: only the lower pair holds
    lifted = {**TOWER, "a": box("a", "cube", 0.7, 0.0, 0.145)}
    assert holding(parse(["tower a b c"]), lifted) == {"b", "c"}
    assert holding(parse(["on d c", "tower a x"]), {**TOWER, "d": lone}) == set()


def test_a_bridge_bears_on_both_supports():
    supports = scene(box("a", "cube", 0.7, 0.0, 0.025), box("b", "cube", 0.7, 0.15, 0.025))
    bridge = parse(["bridge L a b"])
    assert unmet(bridge, {**supports, "L": box("L", "long", 0.7, 0.075, 0.075)}) == []
    # slid 9 cm along y: its end overlaps a by 0.5 cm, under BEAR_OVERLAP (1 cm)
    slid = {**supports, "L": box("L", "long", 0.7, 0.165, 0.075)}
    assert unmet(bridge, slid) == ["'bridge L a b': L does not bear on a"]
    fallen = {**supports, "L": box("L", "long", 0.7, 0.075, 0.025)}
    assert unmet(bridge, fallen) == ["'bridge L a b': L does not bear on a"]
    # across world x, over both: the supports stand along x instead
    across = scene(box("a", "cube", 0.6, 0.0, 0.025), box("b", "cube", 0.75, 0.0, 0.025),
                   box("L", "long", 0.675, 0.0, 0.075, yaw=np.pi / 2))
    assert unmet(bridge, across) == []


def test_a_row_stands_side_by_side_along_y_on_the_table():
    row = parse(["row a b c"])
    spaced = scene(*(box(n, "cube", 0.7, 0.075 * i, 0.025) for i, n in enumerate("abc")))
    assert unmet(row, spaced) == []
    touching = scene(*(box(n, "cube", 0.5, -0.2 + 0.05 * i, 0.025) for i, n in enumerate("abc")))
    assert unmet(row, touching) == []
    wide = {**spaced, "c": box("c", "cube", 0.7, 0.18, 0.025)}  # a 5.5 cm gap
    assert unmet(row, wide) == ["'row a b c': c is not beside b along +y (gap 5.5 cm, "
                                "0.0 cm across)"]
    askew = {**spaced, "c": box("c", "cube", 0.725, 0.15, 0.025)}
    assert "2.5 cm across" in unmet(row, askew)[0]
    backwards = parse(["row c b a"])
    assert len(unmet(backwards, spaced)) == 1
    stacked = {**spaced, "c": box("c", "cube", 0.7, 0.075, 0.075)}
    assert unmet(row, stacked) == ["'row a b c': b and c do not both stand on the table"]


def test_specs_parse_into_relations_and_bad_ones_say_why():
    assert parse(["tower o3 o1 o0", " on  a b "]) == [
        Relation("tower", ("o3", "o1", "o0")), Relation("on", ("a", "b"))]
    assert Relation("bridge", ("L", "a", "b")).pairs() == (("L", "a"), ("L", "b"))
    for spec, why in (("", "an empty spec"), ("fly a b", "unknown word 'fly'"),
                      ("bridge a b", "bridge takes 3 objects, got 2"),
                      ("tower a b a", "a named twice")):
        with pytest.raises(SpecError, match=why):
            parse([spec])


def test_pair_kinds_each_on_a_pair_built_to_hold_it_and_one_that_misses():
    from drake_symplan.relations import pair_unmet

    a, b = box("a", "cube", 0.7, 0.0, 0.075), box("b", "cube", 0.7, 0.0, 0.025)
    assert pair_unmet("on", a, b) is None and pair_unmet("bears", a, b) is None
    assert pair_unmet("on", b, a) == "b is not on a"
    first, second = box("f", "cube", 0.6, 0.0, 0.025), box("s", "cube", 0.6, 0.09, 0.025)
    assert pair_unmet("beside", first, second) is None  # a 4 cm gap along +y
    assert pair_unmet("beside", second, first) is not None  # -y: the wrong way
    assert pair_unmet("beside", first, box("s", "cube", 0.6, 0.11, 0.025)) is not None
    with pytest.raises(ValueError, match="unknown pair kind"):
        pair_unmet("under", a, b)


# Scenes with known answers for every user of rests-on: (boxes, the pairs (upper, lower)
# that rest on each other, the pairs where the upper is held up by the lower in part).
KNOWN = {
    "a cube on a cube": ([box("a", "cube", 0.7, 0, 0.025), box("b", "cube", 0.7, 0, 0.075)],
                         {("b", "a")}, {("b", "a")}),
    "a cube 2 cm off a cube": ([box("a", "cube", 0.7, 0, 0.025),
                                box("b", "cube", 0.72, 0, 0.075)], {("b", "a")}, {("b", "a")}),
    "a cube 3 cm off a cube (its centre within FOOTPRINT_TOL)": (
        [box("a", "cube", 0.7, 0, 0.025), box("b", "cube", 0.73, 0, 0.075)],
        {("b", "a")}, {("b", "a")}),
    "a block across two cubes": ([box("a", "cube", 0.7, -0.1, 0.025),
                                  box("b", "cube", 0.7, 0.1, 0.025),
                                  box("l", "long", 0.7, 0, 0.075)],
                                 set(), {("l", "a"), ("l", "b")}),
    "two cubes side by side, touching": ([box("a", "cube", 0.7, 0, 0.025),
                                          box("b", "cube", 0.75, 0, 0.025)], set(), set()),
    "a cube 1 cm above a cube": ([box("a", "cube", 0.7, 0, 0.025),
                                  box("b", "cube", 0.7, 0, 0.085)], {("b", "a")}, {("b", "a")}),
    "a cube 1.8 cm above a cube (beyond REST_TOL)": (
        [box("a", "cube", 0.7, 0, 0.025), box("b", "cube", 0.7, 0, 0.093)], set(), set()),
    "a tower of three": (list(TOWER.values()), {("a", "b"), ("b", "c")},
                         {("a", "b"), ("b", "c")}),
    "a block on two towers over a lone cube": (
        [box("p", "cube", 0.7, -0.1, 0.025), box("q", "cube", 0.7, -0.1, 0.075),
         box("r", "cube", 0.7, 0.1, 0.025), box("s", "cube", 0.7, 0.1, 0.075),
         box("l", "long", 0.7, 0, 0.125), box("m", "cube", 0.7, 0, 0.025)],
        {("q", "p"), ("s", "r")}, {("q", "p"), ("s", "r"), ("l", "q"), ("l", "s")}),
}


def as_boxes(objects):
    """The scene as the continuous model sees it (feature rows, continuous.Boxes)."""
    from drake_symplan.abstraction.continuous import Boxes
    from drake_symplan.features import object_features

    rows = np.stack([object_features(o.type, o.position, np.array(
        [[np.cos(o.yaw), -np.sin(o.yaw), 0], [np.sin(o.yaw), np.cos(o.yaw), 0], [0, 0, 1]]))
        for o in objects])
    return Boxes(tuple(o.name for o in objects), rows, frozenset()).moved(rows[:, :3])


def closure(name, pairs):
    """What rests on `name`, and on those, and so on, from the (upper, lower) `pairs`."""
    found, frontier = set(), [name]
    while frontier:
        below = frontier.pop()
        new = {u for u, low in pairs if low == below} - found
        found |= new
        frontier += new
    return found


@pytest.mark.parametrize("title", KNOWN)
def test_every_user_of_rests_on_agrees_with_the_one_definition(title):
    from drake_symplan.abstraction.goal_order import GoalOrder
    from drake_symplan.abstraction.stability import supports_of

    objects, resting, held = KNOWN[title]
    states, boxes = scene(*objects), as_boxes(objects)
    assert {(u, low) for u in states for low in states
            if u != low and rests_on(states[u], states[low])} == resting
    for name in states:
        assert set(riders(name, states)) == closure(name, resting)
        assert boxes.riding(name) == closure(name, resting)  # the continuous model's
    assert {(u, boxes.names[j]) for i, u in enumerate(boxes.names)
            for j, *_ in supports_of(boxes, i)} == held  # stability's: held up in part
    # the goal's order (positions, no yaw): a centre within the lower box's longest half
    # extent, so not the cube 3 cm off
    order = GoalOrder({n: o.position for n, o in states.items()}, boxes.kinds())
    assert {(u, low) for u, below in order.under.items() for low in below} == {
        (u, low) for u, low in resting if "3 cm off" not in title}

