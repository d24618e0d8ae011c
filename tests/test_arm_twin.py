"""The hand's arm twin (skills/arm_twin.py): a station mirrored from another's poses, and a
hand back-end action that the arm's wrist would strike run, and perceived, as the arm's."""

import numpy as np
import pytest

from drake_symplan.actions import Action
from drake_symplan.evaluation.carry import suite_scene


@pytest.fixture(scope="module")
def hand():
    from drake_symplan.robot.backends import make_backend

    return make_backend("hand")


def test_a_mirrored_station_holds_the_poses_it_was_given(hand):
    from drake_symplan.world.station import Station

    hand.reset(suite_scene("tall_p9", 20.0))
    poses, types = hand.ground_truth_poses()
    arm = Station()
    arm.mirror(types, poses)
    assert arm.types == types
    for name, X in arm.object_poses().items():
        assert np.allclose(X.GetAsMatrix4(), poses[name].GetAsMatrix4(), atol=1e-12), name


def _perceived_near(scene, xyz):
    """The perceived object nearest the point `xyz` and its distance."""
    return min((float(np.linalg.norm(o.position - np.asarray(xyz))), o.name)
               for o in scene.objects)


def test_the_hand_refuses_what_the_arms_wrist_would_knock_as_the_arm_does(hand):
    hand.reset(suite_scene("tall_p9"))  # three cubes stacked 9 cm along the base block
    before = hand.perceive()
    top = [0.70, -0.15 + 0.09, 0.175]  # the top cube's centre
    assert _perceived_near(before, top)[0] < 0.01
    runs = hand.twin.actions
    result = hand.execute(Action(_perceived_near(before, [0.70, -0.15, 0.025])[1], "center",
                                 _perceived_near(before, [0.70, 0.18, 0.025])[1], "center"),
                          before)
    # the twin planned it and its wrist would sweep the tower's top: refused, not run
    # (before the arm checked its links, it ran and the tower fell)
    assert result.status == "infeasible", result.message
    assert "wrist" in result.message and hand.twin.actions == runs
    assert _perceived_near(hand.perceive(), top)[0] < 0.01  # the tower stands


def test_a_block_released_beside_a_tower_knocks_it_on_the_hand_as_the_palm_does(hand):
    # A block (held across its short side: it cannot be turned as a cube is) released on
    # a block 9.6 cm along x from a tower of four: the arm's palm comes down on the
    # tower's top; the hand, which has no palm, ran it on the twin.
    from drake_symplan.world.scenes import ObjectSpec, Scene

    tower = [ObjectSpec(f"t{i}", "cube", [0.618, -0.235, 0.025 + 0.05 * i], 0.0)
             for i in range(4)]
    hand.reset(Scene(tower + [ObjectSpec("b", "long", [0.714, -0.235, 0.025], 0.0),
                              ObjectSpec("l", "long", [0.85, 0.2, 0.025], 0.0)]))
    before = hand.perceive()
    top = [0.618, -0.235, 0.175]
    assert _perceived_near(before, top)[0] < 0.01
    runs = hand.twin.actions
    result = hand.execute(Action(_perceived_near(before, [0.85, 0.2, 0.025])[1], "center",
                                 _perceived_near(before, [0.714, -0.235, 0.025])[1], "center"),
                          before)
    assert result.status == "ok" and hand.twin.actions == runs + 1
    assert _perceived_near(result.after, top)[0] > 0.03  # the tower's top is gone from there
