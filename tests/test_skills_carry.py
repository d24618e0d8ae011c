"""The careful carry (skills/carry.py): what the beliefs say rides on the source, where the
fingers close then, and the known physical answers on the carry suite (evaluation/carry.py)."""

import numpy as np
import pytest

from drake_symplan.actions import Action
from drake_symplan.datasets import ObjectState
from drake_symplan.evaluation.carry import Runner, suite_scene
from drake_symplan.relations import riders
from drake_symplan.skills.carry import careful_points
from drake_symplan.skills.geometry import action_geometry
from drake_symplan.world.scenes import ObjectSpec, Scene


def beliefs(scene):
    return {o.name: ObjectState(o.name, o.type, np.array(o.position), o.yaw)
            for o in scene.objects}


def test_riders_are_what_rests_on_the_source_and_on_them():
    objects = beliefs(Scene([
        ObjectSpec("base", "long", [0.7, 0.0, 0.025]),
        ObjectSpec("a", "cube", [0.7, -0.07, 0.075]),
        ObjectSpec("b", "cube", [0.7, -0.07, 0.125]),
        ObjectSpec("beside", "cube", [0.7, 0.2, 0.025]),
    ]))
    assert sorted(riders("base", objects)) == ["a", "b"]
    assert riders("beside", objects) == []
    assert riders("a", objects) == ["b"]


def test_careful_grasp_is_clear_of_the_riders_and_lands_the_base_where_the_action_says():
    objects = beliefs(suite_scene("two_cubes"))
    action = Action("base", "left", "target", "center")
    g = action_geometry(action, objects)
    grasp, release, careful = careful_points(action, objects, g.grasp, g.release, 0.0)
    assert careful
    base = objects["base"].position
    assert grasp[:2] == pytest.approx(base[:2], abs=1e-6)  # between the cubes, balanced
    # the base's centre is released where the nominal grasp would have put it
    assert (release - grasp)[:2] == pytest.approx((g.release - g.grasp)[:2], abs=1e-6)


def test_a_stack_is_not_released_with_its_centre_past_the_targets_end():
    # grasp left, release right: the base's centre would land 15 cm along a target whose
    # end is at 12.5 cm; the careful carry releases it with the centre of mass (the base's
    # and the rider's, both at its centre) 1.5 cm inside the end, 4 cm nearer
    for yaw in (0.0, 8.22):
        objects = beliefs(suite_scene("rider_0", yaw))
        action = Action("base", "left", "target", "right")
        g = action_geometry(action, objects)
        grasp, release, careful = careful_points(action, objects, g.grasp, g.release, 0.0)
        target = objects["target"]
        landing = release[:2] + objects["base"].position[:2] - grasp[:2]
        c, s = np.cos(-target.yaw), np.sin(-target.yaw)
        d = landing - target.position[:2]
        across, along = c * d[0] - s * d[1], s * d[0] + c * d[1]  # in the target's frame
        assert careful and along == pytest.approx(0.125 - 0.015, abs=1e-6), yaw
        # turned, the 15 cm along world y are 2.1 cm across the 5 cm block: 1 cm at most
        assert abs(across) == pytest.approx(0.0 if yaw == 0 else 0.025 - 0.015, abs=1e-6)
    # centred on the block, the same action lands where it says
    objects = beliefs(suite_scene("rider_0"))
    centred = Action("base", "center", "target", "right")
    g = action_geometry(centred, objects)
    grasp, release, _ = careful_points(centred, objects, g.grasp, g.release, 0.0)
    assert (release - grasp)[:2] == pytest.approx((g.release - g.grasp)[:2], abs=1e-6)


def test_a_load_near_the_edge_of_the_cube_it_lands_on_is_set_down_inside_the_margin():
    # a cube (0.1 kg) at 7.5 cm along a block (0.4 kg): the load's centre of mass is 1.5 cm
    # from the block's centre; released centred on a cube it would lie 1 cm inside the
    # cube's edge, nearer than the 1.5 cm margin: the block lands 5 mm back
    objects = beliefs(Scene([
        ObjectSpec("cube", "cube", [0.7, 0.0, 0.025]),
        ObjectSpec("block", "long", [0.6, 0.2, 0.025]),
        ObjectSpec("rider", "cube", [0.6, 0.275, 0.075]),
    ]))
    action = Action("block", "center", "cube", "center")
    g = action_geometry(action, objects)
    grasp, release, careful = careful_points(action, objects, g.grasp, g.release, 0.0)
    landing = release[:2] + objects["block"].position[:2] - grasp[:2]
    assert careful and landing == pytest.approx([0.7, -0.005], abs=1e-6)


def test_a_grasp_beside_a_loaded_block_stays_above_the_riders():
    objects = beliefs(suite_scene("rider_0", 90.0))
    action = Action("base", "left", "target", "center")  # offsets along world y: a miss
    g = action_geometry(action, objects)
    grasp, _, _ = careful_points(action, objects, g.grasp, g.release, 0.0)
    assert grasp[2] > 0.10 + 0.015  # the pads above the cube's top


@pytest.fixture(scope="module")
def runner():
    return Runner()


def test_two_cubes_on_a_block_ride_along_on_the_arm(runner):
    scene = suite_scene("two_cubes")
    for grasp in ("left", "right"):
        out = runner.run("arm", scene, "two_cubes", Action("base", grasp, "target", "center"))
        assert out["status"] == "ok" and out["moved"] and out["kept"], grasp


def _kept_base(runner, backend, action):
    """Runs `action` on the `rider_0` scene; the base's position, its rider kept."""
    out = runner.run(backend, suite_scene("rider_0"), "rider_0", action)
    assert out["status"] == "ok" and out["moved"] and out["kept"], backend
    station = runner.arm if backend == "arm" else runner.hand
    return station.object_poses()["base"].translation()


def test_a_block_placed_on_its_own_rider_shifts_the_stack_on_both_back_ends(runner):
    # pick(base) place(r0, left): the stack moves 7.5 cm to -y and is lowered to the
    # table, on the arm (careful carry) and on the hand (which follows its points)
    for backend in ("hand", "arm"):
        base = _kept_base(runner, backend, Action("base", "center", "r0", "left"))
        assert base == pytest.approx([0.70, -0.225, 0.025], abs=0.006), backend


def test_a_stack_released_past_the_targets_end_is_set_down_on_it_on_both_back_ends(runner):
    # grasp left, release right would leave the base's centre 2.5 cm past the target's end
    # (it tipped, and the rider's fate was chance); the careful carry sets it down 4 cm
    # nearer, its centre 11 cm along the target, and the rider stays
    for backend in ("hand", "arm"):
        base = _kept_base(runner, backend, Action("base", "left", "target", "right"))
        assert base == pytest.approx([0.70, 0.18 + 0.11, 0.075], abs=0.006), backend


def test_a_rider_hanging_more_than_half_off_the_end_falls_on_both_back_ends(runner):
    scene = suite_scene("hanging")  # the cube's centre 6 mm beyond the block's end
    for backend in ("hand", "arm"):
        out = runner.run(backend, scene, "hanging", Action("base", "center", "target", "center"))
        assert out["status"] == "ok" and out["moved"], backend
        assert not out["kept"], backend


def test_a_tower_on_a_cube_is_pinched_as_before_but_not_dropped_beside_the_target():
    objects = beliefs(suite_scene("tower", 90.0))
    on_target = Action("base", "center", "target", "center")
    g = action_geometry(on_target, objects)
    grasp, release, careful = careful_points(on_target, objects, g.grasp, g.release, 0.0)
    assert not careful and grasp == pytest.approx(g.grasp) and release == pytest.approx(g.release)
    beside = Action("base", "center", "target", "right")  # across the turned target: the table
    g = action_geometry(beside, objects)
    _, release, _ = careful_points(beside, objects, g.grasp, g.release, 0.0)
    assert release[2] == pytest.approx(0.025 + 0.004)


def _poses(spec):
    from pydrake.math import RigidTransform
    return {n: RigidTransform(np.array(p, float)) for n, p in spec.items()}


def test_the_wrist_strikes_what_rises_past_the_palm_near_the_tool_axis():
    from drake_symplan.boxes import HALF_EXTENTS
    from drake_symplan.world.hand import wrist_strikes

    half = {n: np.array(HALF_EXTENTS["cube"]) for n in ("a", "b", "c", "far")}
    tcp = np.array([0.7, 0.0, 0.025])  # the fingers on the bottom cube of a tower
    tower3 = _poses({"a": [0.7, 0.0, 0.025], "b": [0.7, 0.0, 0.075], "c": [0.7, 0.0, 0.125],
                     "far": [0.7, 0.3, 0.025]})
    assert wrist_strikes(tower3, half, tcp) == ["c"]  # its top reaches 12.5 cm above the TCP
    tower2 = {n: X for n, X in tower3.items() if n != "c"}
    assert wrist_strikes(tower2, half, tcp) == []  # the rider stops 7.5 cm above: the palm's
    beside = _poses({"c": [0.7, 0.11, 0.175]})  # 8.5 cm from the axis, top 17.5 cm above
    assert wrist_strikes(beside, half, tcp) == ["c"]  # in wrist_2's reach
    assert wrist_strikes(beside, half, tcp + np.array([0.0, 0.0, 0.05])) == []  # under it


def test_the_open_fingers_strike_a_neighbour_across_the_finger_axis_only():
    from drake_symplan.boxes import HALF_EXTENTS
    from drake_symplan.world.hand import finger_strikes

    half = {n: np.array(HALF_EXTENTS["cube"]) for n in ("src", "x", "y")}
    # the source at the TCP; one cube 6 cm away across the finger axis (world x at yaw 0),
    # under a pad (4.25-5.75 cm out); one 6 cm away along y, beside the pads
    poses = _poses({"src": [0.7, 0.0, 0.025], "x": [0.76, 0.0, 0.025], "y": [0.7, 0.06, 0.025]})
    tcp = np.array([0.7, 0.0, 0.025])
    assert finger_strikes(poses, half, tcp, 0.0, skip="src") == ["x"]
    assert finger_strikes(poses, half, tcp, np.pi / 2, skip="src") == ["y"]  # turned
    assert finger_strikes(poses, half, tcp + np.array([0.0, 0.0, 0.07]), 0.0, "src") == []


def test_a_tall_tower_at_the_far_end_of_a_block_is_refused_on_both_back_ends(runner):
    """The arm's wrist would sweep the top of a three-cube tower 9 cm along the block: the
    arm refuses the grasp (skills/arm_clearance.py) and so does the hand, through its twin.
    Before the arm checked its links, the tower fell on both."""
    scene = suite_scene("tall_p9")
    action = Action("base", "center", "target", "center")
    for backend in ("hand", "arm"):
        out = runner.run(backend, scene, "tall_p9", action)
        assert out["status"] == "infeasible" and not out["moved"], (backend, out)


def test_a_block_across_the_reach_at_a_folded_yaw_is_picked_with_the_wrist_half_turned(runner):
    # The scene yawed 89 deg: the base lies along world x and the careful grasp is 5.5 cm
    # beyond its centre (x = 0.92 m), which the joint box reaches with the gripper turned
    # -91 deg but not +89 deg (grasp_yaw's fold). A long block perceived at 89 instead of
    # 90 deg was an unreachable pre-grasp; the same grasp with the wrist turned by pi is not.
    scene = suite_scene("rider_0", 89.0)
    action = Action("base", "center", "target", "center")
    assert runner.planner.plan(action, scene.object_states()) is not None
    out = runner.run("arm", scene, "rider_0", action)
    assert out["status"] == "ok" and out["moved"] and out["kept"]
