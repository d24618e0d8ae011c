"""The arm's paths are timed within its limits: known answers for a one-joint move, the carry
limit on the TCP and the finger dwell."""

import numpy as np
import pytest

from drake_symplan.skills.timing import (
    JOINT_ACCELERATION,
    JOINT_VELOCITY,
    TCP_ACCELERATION,
    Phase,
)
from drake_symplan.world.station import FINGER_CLOSED, FINGER_OPEN, HOME_Q


def q8(q_arm, finger=FINGER_OPEN):
    return np.concatenate([q_arm, [finger, finger]])


def test_one_joint_move_takes_the_trapezoid_time_and_stays_in_the_limits(planner):
    delta = 1.0
    end = HOME_Q.copy()
    end[0] += delta
    t, q, v = planner.timer.samples(Phase([q8(HOME_Q), q8(end)]))
    # Time-optimal: accelerate to the base's speed limit, cruise, decelerate.
    vmax, amax = JOINT_VELOCITY[0], JOINT_ACCELERATION[0]
    optimal = delta / vmax + vmax / amax
    assert optimal <= t[-1] <= 1.1 * optimal  # 20 grid points: within 10 % of optimal
    assert np.allclose(q[0], q8(HOME_Q)) and np.allclose(q[-1], q8(end))
    assert np.all(v[0] == 0.0) and np.all(v[-1] == 0.0)
    assert np.max(np.abs(v[:, 0])) <= vmax * 1.01
    assert np.allclose(q[:, 1:], q8(HOME_Q)[1:])  # the other joints stay put


def test_a_limited_path_keeps_the_tcp_acceleration_under_the_limit(planner):
    lift = planner.ik.solve(np.array([0.6, 0.25, 0.2]), 0.0, HOME_Q)
    above = planner.ik.solve(np.array([0.75, -0.15, 0.2]), 0.0, lift)
    free = planner.timer.samples(Phase([q8(lift, FINGER_CLOSED), q8(above, FINGER_CLOSED)]))
    loaded = planner.timer.samples(
        Phase([q8(lift, FINGER_CLOSED), q8(above, FINGER_CLOSED)], tcp_acceleration=TCP_ACCELERATION))
    t, q, _ = loaded
    tcp = np.array([planner.ik.tcp_pose(qi[:6]).translation() for qi in q])
    dt = t[1] - t[0]
    acceleration = np.abs(np.diff(tcp, 2, axis=0)) / dt**2
    assert acceleration.max() <= TCP_ACCELERATION * 1.25  # sampled finite differences
    assert loaded[0][-1] > free[0][-1]  # the limit slows the carry down


def test_a_dwell_moves_only_the_fingers_for_its_duration(planner):
    t, q, v = planner.timer.samples(
        Phase([q8(HOME_Q)], dwell=0.15, finger=FINGER_CLOSED))
    assert t[-1] == pytest.approx(0.15)
    assert np.allclose(q[-1], q8(HOME_Q, FINGER_CLOSED)) and np.allclose(v, 0.0)


def test_a_motion_ends_home_at_rest_and_marks_the_lift(planner):
    from drake_symplan.actions import Action
    from drake_symplan.datasets import ObjectState

    objects = {"a": ObjectState("a", "cube", np.array([0.6, 0.2, 0.025])),
               "b": ObjectState("b", "cube", np.array([0.7, -0.1, 0.025]))}
    motion = planner.plan(Action("a", "center", "b", "center"), objects)
    assert 0.0 < motion.t_lift < motion.t_end
    assert np.allclose(motion.trajectory.value(motion.t_end)[:6, 0], HOME_Q, atol=1e-6)
    assert np.allclose(motion.trajectory.EvalDerivative(motion.t_end, 1), 0.0, atol=1e-9)
    lifted = planner.ik.tcp_pose(motion.trajectory.value(motion.t_lift)[:6, 0]).translation()
    assert lifted[2] == pytest.approx(0.2, abs=2e-3)  # MIN_CARRY_HEIGHT over low boxes
