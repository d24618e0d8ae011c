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


def test_the_hand_knocks_a_tall_tower_where_the_arms_wrist_would(hand):
    hand.reset(suite_scene("tall_p9"))  # three cubes stacked 9 cm along the base block
    before = hand.perceive()
    top = [0.70, -0.15 + 0.09, 0.175]  # the top cube's centre
    assert _perceived_near(before, top)[0] < 0.01
    runs = hand.twin.actions
    result = hand.execute(Action(_perceived_near(before, [0.70, -0.15, 0.025])[1], "center",
                                 _perceived_near(before, [0.70, 0.18, 0.025])[1], "center"),
                          before)
    assert result.status == "ok" and hand.twin.actions == runs + 1
    assert result.lift is not before  # the lifted scene was perceived from the twin's
    # the block left, the tower did not stay on it: nothing stands 17.5 cm high any more
    assert max(o.position[2] for o in result.after.objects) < 0.15
