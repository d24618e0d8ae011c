"""Stability (abstraction/stability.py): which boxes tip, overload or overhang their supports."""

from __future__ import annotations

import numpy as np
from bilevel_fixtures import STACK, Stacking

from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.refiner import Refiner
from drake_symplan.abstraction.stability import on_overhang, overloaded, tips, unstable
from drake_symplan.features import object_features
from drake_symplan.planning.budget import Budget


def test_a_load_near_its_one_supports_edge_falls_and_no_step_puts_it_there():
    # settled in full physics for 2 s from these positions: each `fell` scene toppled,
    # each `stood` one stood
    def scene(*where):  # (name, type, y, z) along one line
        features = np.stack([object_features(kind, np.array([0.7, y, z]), np.eye(3))
                             for _, kind, y, z in where])
        return Boxes(tuple(w[0] for w in where), features, frozenset()).moved(features[:, :3])

    c = ("c", "cube", 0.0, 0.025)
    fell = [scene(c, ("l", "long", 0.018, 0.075)),  # a block centred 1.8 cm off a cube
            scene(c, ("l", "long", 0.0, 0.075), ("t", "cube", -0.075, 0.125))]  # 1.5 cm
    stood = [scene(c, ("l", "long", 0.01, 0.075)),
             scene(c, ("l", "long", 0.0, 0.075), ("m", "long", 0.0, 0.125),
                   ("t", "cube", -0.075, 0.175)),  # 0.8 cm off
             scene(*[(f"c{k}", "cube", 0.003 * k, 0.025 + 0.05 * k) for k in range(5)])]
    for s in fell:
        assert unstable(s, ["t" if "t" in s.names else "l"]), s.names
        assert unstable(s, ["l"]) and overloaded(s, "l") and not overloaded(s, "c")
    for s in stood:
        assert not unstable(s, [s.names[-1]]), s.names
    # the first cube t on the end of the block on c: the step that puts it there is unsafe
    before = scene(c, ("l", "long", 0.0, 0.075), ("t", "cube", 0.2, 0.025))
    after = scene(c, ("l", "long", 0.0, 0.075), ("t", "cube", -0.075, 0.125))
    assert Refiner.topples(before, after)
    assert not Refiner.topples(before, scene(c, ("l", "long", 0.0, 0.075),
                                             ("t", "cube", 0.0, 0.125)))


def test_a_box_set_on_the_free_end_of_a_block_balanced_on_a_cube_topples_it():
    # traced (eight boxes): a cube let down on the end of a block balanced on a cube atop a
    # tower, a cube centred on the block, brought the tower down; its load is 1.25 cm off
    # the cube's centre, which stands where it is built without the blow
    def scene(*where):  # (name, type, y, z) along one line
        features = np.stack([object_features(kind, np.array([0.79, y, z]), np.eye(3))
                             for _, kind, y, z in where])
        return Boxes(tuple(w[0] for w in where), features, frozenset()).moved(features[:, :3])

    tower = [("c0", "cube", 0.14, 0.075), ("c1", "cube", 0.14, 0.125),
             ("l", "long", 0.14, 0.175), ("top", "cube", 0.14, 0.225),
             ("base", "long", 0.216, 0.025)]
    end = scene(*tower, ("s", "cube", 0.214, 0.225))
    assert on_overhang(end, "s") and unstable(end, ["s"])
    assert not overloaded(end, "l")  # not by statics alone
    centred = scene(*tower[:3], ("s", "cube", 0.14, 0.225), tower[4])
    assert not on_overhang(centred, "s") and not unstable(centred, ["s"])
    # across two cubes (a bridge) the block's end is held: no overhang
    bridge = scene(("a", "cube", 0.04, 0.025), ("b", "cube", 0.24, 0.025),
                   ("l", "long", 0.14, 0.075), ("s", "cube", 0.21, 0.125))
    assert not on_overhang(bridge, "s") and not unstable(bridge, ["s"])


def test_a_box_released_with_its_centre_beyond_its_one_support_topples_and_no_plan_goes_there():
    def scene(**where):  # name -> (type, position)
        features = np.stack([object_features(kind, np.array(p, float), np.eye(3))
                             for kind, p in where.values()])
        return Boxes(tuple(where), features, frozenset()).moved(features[:, :3])

    c = ("cube", (0.5, 0.0, 0.025))
    assert tips(scene(c=c, l=("long", (0.5, 0.075, 0.075))), "l")  # its end over c
    assert tips(scene(c=c, t=("cube", (0.5, 0.035, 0.075))), "t")  # 1 cm past c's edge
    assert not tips(scene(c=c, l=("long", (0.5, 0.02, 0.075))), "l")  # c under its centre
    assert not tips(scene(c=c, d=("cube", (0.5, 0.2, 0.025)), l=("long", (0.5, 0.1, 0.075))),
                    "l")  # a bridge: its centre between its two supports
    assert not tips(scene(c=c, l=("long", (0.5, 0.075, 0.025))), "l")  # on the table
    # a block leaning with one end on c (tilted 20 degrees): held by the table too
    leaning = object_features("long", np.array([0.5, 0.1, 0.05]),
                              np.array([[1, 0, 0], [0, 0.94, -0.342], [0, 0.342, 0.94]]))
    both = np.stack([object_features("cube", np.array(c[1]), np.eye(3)), leaning])
    assert not tips(Boxes(("c", "l"), both, frozenset()).moved(both[:, :3]), "l")
    # the hand-written model puts l's centre 7.5 cm off c's (a release at c's right): the
    # search reaches that scene without the rules (the prediction's and the action's own
    # points') and not with them
    start = scene(c=c, l=("long", (0.7, 0.2, 0.025)))
    goal = {"c": np.array(c[1]), "l": np.array([0.5, 0.075, 0.075])}
    refiner = Refiner(list(STACK.values()), Stacking())
    found, _ = refiner.search(start, goal, Budget.of_cpu(10))
    assert found is None
    refiner.unsafe = lambda before, after, action: False
    found, _ = refiner.search(start, goal, Budget.of_cpu(10))
    assert [(s.action.source, s.action.target) for s in found.steps] == [("l", "c")]
