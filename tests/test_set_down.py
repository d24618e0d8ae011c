"""Where a pick/place sets its source down (abstraction/set_down.py): whether it topples
there, which boxes it comes to touch."""

from __future__ import annotations

import numpy as np

from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.set_down import set_down_meets, set_down_tips
from drake_symplan.actions import Action
from drake_symplan.features import object_features


def upright(**where) -> Boxes:
    """Boxes at rest, upright, unrotated: name -> (type, xyz)."""
    features = np.stack([object_features(kind, np.array(p), np.eye(3))
                         for kind, p in where.values()])
    return Boxes(tuple(where), features, frozenset()).moved(features[:, :3])


def test_a_block_grasped_at_its_end_and_released_over_a_cube_would_topple():
    # traced (eight boxes): pick(o3:right) place(o6:center) brought the block's centre down
    # 7.5 cm off a cube atop a tower, and block and tower fell; the model predicted the
    # block resting on the cube. The action's own points say where it comes down (c
    # stands on d: a tower of two).
    features = np.stack([object_features("cube", np.array([0.89, 0.31, z]), np.eye(3))
                         for z in (0.025, 0.075)]
                        + [object_features("long", np.array([0.7, 0.0, 0.025]), np.eye(3))])
    scene = Boxes(("d", "c", "l"), features, frozenset()).moved(features[:, :3])
    assert set_down_tips(scene, Action("l", "right", "c", "center"))  # centre 7.5 cm off
    assert set_down_tips(scene, Action("l", "left", "c", "center"))
    assert not set_down_tips(scene, Action("l", "center", "c", "center"))  # centred
    assert not set_down_tips(scene, Action("l", "right", "c", "right"))  # offsets cancel
    assert not set_down_tips(scene, Action("c", "center", "l", "right"))  # on its end: held
    # on a cube on the table the block leans on the table (goals have blocks so)
    assert not set_down_tips(scene, Action("l", "right", "d", "center"))
    # traced (six boxes): a block picked up leaning (20 degrees) at its end and released
    # over a cube atop a tower fell just the same; the tilt it had is not the one it lands with
    leaning = scene.features.copy()
    leaning[2, 3] = np.cos(np.radians(20))
    scene = Boxes(scene.names, leaning, frozenset()).moved(leaning[:, :3])
    assert set_down_tips(scene, Action("l", "right", "c", "center"))
    assert not set_down_tips(scene, Action("l", "center", "c", "center"))


def test_a_block_carrying_a_block_is_judged_where_both_come_down():
    # traced (eight boxes): pick(o4:left) place(o5:right), a block with a block on it
    # released 15 cm off a cube atop a tower (its end on the cube's edge: half a block and
    # half a cube), and block, rider and tower fell. The rider comes down with the block
    # (left where it was, it can read as a second support), the edge holds the block's end.
    where = {"c0": ("cube", (0.65, -0.16, 0.025)), "c1": ("cube", (0.65, -0.16, 0.075)),
             "l": ("long", (0.65, 0.18, 0.025)), "r": ("long", (0.65, 0.18, 0.075))}
    features = np.stack([object_features(kind, np.array(p), np.eye(3))
                         for kind, p in where.values()])
    scene = Boxes(tuple(where), features, frozenset()).moved(features[:, :3])
    assert set_down_tips(scene, Action("l", "left", "c1", "right"))
    assert not set_down_tips(scene, Action("l", "center", "c1", "center"))



def test_a_block_centred_on_a_cube_meets_the_cube_standing_at_its_end():
    # traced (two towers of three, eight boxes): a block set centred on its cube reached
    # 12.5 cm along y and came to rest on a cube beside that one (the first tower's top,
    # still on the table): a contact the step, over the block and its cube, did not predict
    scene = upright(c=("cube", (0.714, 0.239, 0.025)), n=("cube", (0.763, 0.364, 0.025)),
                    l=("long", (0.49, 0.0, 0.025)), far=("cube", (0.5, -0.3, 0.025)))
    assert set_down_meets(scene, Action("l", "center", "c", "center")) == {"n"}
    # a cube set on the same cube reaches nothing but its target
    assert set_down_meets(scene, Action("far", "center", "c", "center")) == set()
    # the block set on the lone cube, nothing beside it
    assert set_down_meets(scene, Action("l", "center", "far", "center")) == set()
