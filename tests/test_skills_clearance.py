"""The arm's wrist and forearm against the believed boxes: the motion is refused where a
link would strike one on the way down (skills/arm_clearance.py)."""

import numpy as np
import pytest

from drake_symplan.actions import Action
from drake_symplan.datasets import ObjectState
from drake_symplan.skills.arm_clearance import cylinder_points
from drake_symplan.skills.geometry import InfeasibleAction


def test_cylinder_points_lie_on_the_cylinder_and_reach_its_ends():
    points = cylinder_points((0.0, 0.0, 0.1), (0.0, 0.0, 1.0), 0.06, 0.045)
    across = np.linalg.norm(points[:2], axis=0)
    assert across.max() == pytest.approx(0.045)
    assert points[2].min() == pytest.approx(0.04) and points[2].max() == pytest.approx(0.16)
    side = np.isclose(across, 0.045)
    inside_ends = ~side
    assert np.all(np.isclose(points[2, inside_ends], 0.04) | np.isclose(points[2, inside_ends], 0.16))


TOWER = [(0.7109, 0.0379, 0.025, 0.0), (0.7111, 0.0374, 0.0749, -0.0839),
         (0.7114, 0.0357, 0.1249, -0.1318), (0.7118, 0.0336, 0.1748, -0.2458)]


def _tower_beside_a_block(levels: int) -> dict[str, ObjectState]:
    """A traced eight-box scene: a tower of cubes 9 cm from the near end of a long block."""
    tower = {f"t{i}": ObjectState(f"t{i}", "cube", np.array([x, y, z]), yaw)
             for i, (x, y, z, yaw) in enumerate(TOWER[:levels])}
    return {**tower, "b": ObjectState("b", "long", np.array([0.776, 0.253, 0.025])),
            "c": ObjectState("c", "cube", np.array([0.835, -0.36, 0.025]))}


def test_the_wrist_that_would_sweep_a_tower_of_four_refuses_the_grasp(planner):
    # In physics this grasp knocked the top three cubes off (the wrist_1 link comes down
    # 16 cm beside the tool, level with the tower's top).
    with pytest.raises(InfeasibleAction, match="wrist_1 would strike t3 on the way down to b"
                       ) as refused:
        planner.plan(Action("b", "left", "c", "center"), _tower_beside_a_block(4))
    assert refused.value.obstacles == ("t3",)  # what the planner is told is in the way
    assert refused.value.at == "grasp"  # on the source's side
    # the block's other end, and the same end beside a tower of two, are clear
    planner.plan(Action("b", "right", "c", "center"), _tower_beside_a_block(4))
    planner.plan(Action("b", "left", "c", "center"), _tower_beside_a_block(2))


def _bridge_over_a_cube() -> dict[str, ObjectState]:
    """A traced eight-box scene: a long block on two cubes, its near end over a third
    cube (c1) it does not touch."""
    def cube(name, y, z=0.025):
        return ObjectState(name, "cube", np.array([0.816, y, z]))
    return {"c1": cube("c1", 0.036), "c4": cube("c4", 0.111), "c5": cube("c5", 0.182),
            "b": ObjectState("b", "long", np.array([0.814, 0.111, 0.075])),
            "far": ObjectState("far", "cube", np.array([0.77, -0.263, 0.025]))}


def test_a_grasp_under_a_block_that_bridges_over_the_source_is_refused(planner):
    # In physics the palm came down on the block's end (a tower of three fell).
    with pytest.raises(InfeasibleAction, match="palm would strike b coming down to c1"
                       ) as refused:
        planner.plan(Action("c1", "center", "far", "center"), _bridge_over_a_cube())
    assert (refused.value.obstacles, refused.value.at) == (("b",), "grasp")
    planner.plan(Action("b", "center", "far", "center"), _bridge_over_a_cube())


def test_a_block_set_down_into_a_taller_tower_beside_its_target_is_refused(planner):
    # A long block (25 cm along y) centred on a cube 7 cm from a tower of three: in
    # physics it was lowered into the tower, which fell.
    tower = {f"t{i}": ObjectState(f"t{i}", "cube", np.array([0.83, 0.127, 0.025 + 0.05 * i]))
             for i in range(3)}
    scene = {**tower, "c": ObjectState("c", "cube", np.array([0.829, 0.197, 0.025])),
             "b": ObjectState("b", "long", np.array([0.938, 0.044, 0.025])),
             "d": ObjectState("d", "cube", np.array([0.6, 0.07, 0.025]))}
    with pytest.raises(InfeasibleAction, match="b would be driven into t1, t2 set down on c"
                       ) as refused:
        planner.plan(Action("b", "center", "c", "center"), scene)
    assert (refused.value.obstacles, refused.value.at) == (("t1", "t2"), "release")
    planner.plan(Action("b", "center", "d", "center"), scene)  # clear of the tower
    planner.plan(Action("c", "center", "d", "center"), scene)  # a cube fits beside it


def _cube_beside_a_tower(levels: int, dx: float, dy: float) -> dict[str, ObjectState]:
    """A cube at (0.7, 0) on the table, a tower of `levels` cubes (dx, dy) from it and a
    free target; the robot's base stands at the origin, on the -x side."""
    tower = {f"t{i}": ObjectState(f"t{i}", "cube", np.array([0.7 + dx, dy, 0.025 + 0.05 * i]))
             for i in range(levels)}
    return {"s": ObjectState("s", "cube", np.array([0.7, 0.0, 0.025])), **tower,
            "c": ObjectState("c", "cube", np.array([0.8, -0.35, 0.025]))}


def test_the_planners_rule_names_the_boxes_the_wrist_would_strike_as_the_arm_does(planner):
    from drake_symplan.skills.geometry import grasp_refused, grasp_struck

    grasp = Action("s", "center", "c", "center")
    # a tower of three touching the cube: wrist_3, about the tool axis, strikes its top at
    # every turn of the gripper
    with pytest.raises(InfeasibleAction, match="wrist_3 would strike t2"):
        planner.plan(grasp, _cube_beside_a_tower(3, 0.0, 0.052))
    assert grasp_struck(grasp, _cube_beside_a_tower(3, 0.0, 0.052)) == ["t2"]
    assert not grasp_refused(grasp, _cube_beside_a_tower(2, 0.0, 0.052))  # below the wrist
    # a tower of four 10 cm towards the base meets wrist_1, which stands out that way; the
    # same tower 10 cm away from the base is clear
    with pytest.raises(InfeasibleAction, match="wrist_1 would strike t3"):
        planner.plan(grasp, _cube_beside_a_tower(4, -0.1, 0.0))
    assert grasp_struck(grasp, _cube_beside_a_tower(4, -0.1, 0.0)) == ["t3"]
    planner.plan(grasp, _cube_beside_a_tower(4, 0.1, 0.0))
    assert grasp_struck(grasp, _cube_beside_a_tower(4, 0.1, 0.0)) == []
    # the traced block beside a tower of four: its near end refused, its far end clear
    assert grasp_struck(Action("b", "left", "c", "center"), _tower_beside_a_block(4)) == ["t3"]
    assert grasp_struck(Action("b", "right", "c", "center"), _tower_beside_a_block(4)) == []


def test_a_refusal_names_the_box_in_the_way_where_another_turn_is_out_of_reach(monkeypatch):
    # traced (twelve boxes): the gripper's quarter turn was out of reach, the turn half a
    # turn round struck a tower's top; told only "unreachable", the planner did not know
    # that moving the tower would let the arm grasp the cube
    from drake_symplan.skills.pick_place import PickPlaceMotions

    tries = iter([InfeasibleAction("unreachable pose: pre-grasp"),
                  InfeasibleAction("the arm's wrist_3 would strike t2", ("t2",))])

    def refuse(*args, **kwargs):
        raise next(tries, InfeasibleAction("the palm would strike t1", ("t1",)))

    motions = PickPlaceMotions.__new__(PickPlaceMotions)
    monkeypatch.setattr(motions, "_motion", refuse)
    with pytest.raises(InfeasibleAction, match="wrist_3 would strike t2") as refused:
        motions.plan(Action("s", "center", "c", "center"), _cube_beside_a_tower(3, 0.0, 0.07))
    assert refused.value.obstacles == ("t2",)
