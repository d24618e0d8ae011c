"""Times the arm's joint paths within the UR10's limits (Drake's TOPPRA path parametrisation).

A motion is a sequence of phases, each a joint path through IK waypoints that starts and
ends at rest, or a dwell while the fingers open or close. Each path is parametrised
time-optimally under the joint velocity and acceleration limits and, while the gripper
holds a box or comes close to one, a limit on the TCP's acceleration. The phases are
sampled into one cubic Hermite trajectory for the station to track.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.trajectories import PiecewisePolynomial

# UR10 datasheet: 120 deg/s at the base and shoulder, 180 deg/s at the elbow and wrists.
JOINT_VELOCITY = np.array([2.09, 2.09, np.pi, np.pi, np.pi, np.pi])
# The datasheet gives no acceleration limit; the fixed-duration trajectories this replaced
# peaked at 7-23 rad/s^2 per joint (medians over random actions; 34 at wrist 1 at most):
# 20 asks no more of the arm than they did.
JOINT_ACCELERATION = np.full(6, 20.0)
# Near the boxes and holding one, the TCP's acceleration (each world axis): a box stacked
# on the load rides along up to mu * g = 5.9 m/s^2 (mu 0.6), the PD's lag behind a harder
# stop brings the fingers 1 cm low at the grasp, and on 120 random actions a box lands
# 0.27 cm from its aim (median; p90 0.6) where 6 m/s^2 while carrying gives 0.30 (0.9).
TCP_ACCELERATION = 4.0  # m/s^2
FINGER_VELOCITY = 1.0  # m/s, finger joints (they stay put along a path)
SAMPLE_PERIOD = 0.02  # s between samples of the tracked trajectory
# 10 grid points: 2-3 ms per path; over 30 random actions the motions last 0.3 % longer
# than with 40 points, which take 4x the time.
GRID = CalcGridPointsOptions(max_err=1e-2, max_iter=20, max_seg_length=0.2, min_points=10)


@dc.dataclass
class Phase:
    """A joint path through `waypoints` (plant positions: arm and fingers), from rest to rest,
    or with one waypoint held for `dwell` seconds while the fingers move to `finger`."""

    waypoints: list[np.ndarray]
    tcp_acceleration: float | None = None  # m/s^2 at the TCP (TCP_ACCELERATION), if limited
    dwell: float = 0.0
    finger: float | None = None


class PathTimer:
    """Times phases on `plant` (the IK plant: six arm joints and two fingers) whose TCP
    frame is `tcp`."""

    def __init__(self, plant, tcp):
        self.plant, self.tcp = plant, tcp
        fingers = plant.num_positions() - 6
        self.velocity = np.concatenate([JOINT_VELOCITY, [FINGER_VELOCITY] * fingers])
        self.acceleration = np.concatenate([JOINT_ACCELERATION, [10.0] * fingers])

    def samples(self, phase: Phase) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times from 0, positions [n, d], velocities [n, d]) along the timed phase."""
        if phase.finger is not None:
            return self._dwell(phase)
        path = self._path(phase.waypoints)
        if path is None:  # the waypoints coincide: nothing to move
            return _still(phase.waypoints[0])
        s_of_t = self._parametrise(path, phase)
        n = max(2, int(np.ceil(s_of_t.end_time() / SAMPLE_PERIOD)) + 1)
        times = np.linspace(0.0, s_of_t.end_time(), n)
        s = np.array([s_of_t.value(t)[0, 0] for t in times])
        s_dot = np.array([s_of_t.EvalDerivative(t, 1)[0, 0] for t in times])
        s = np.clip(s, path.start_time(), path.end_time())
        q = np.array([path.value(si)[:, 0] for si in s])
        v = np.array([path.EvalDerivative(si, 1)[:, 0] * sd for si, sd in zip(s, s_dot, strict=True)])
        v[0] = v[-1] = 0.0
        return times, q, v

    def _dwell(self, phase: Phase):
        if phase.dwell <= 0.0:
            return _still(phase.waypoints[0])
        q0 = phase.waypoints[0]
        q1 = q0.copy()
        q1[6:] = phase.finger
        times = np.array([0.0, phase.dwell])
        return times, np.array([q0, q1]), np.zeros((2, len(q0)))

    @staticmethod
    def _path(waypoints: list[np.ndarray]) -> PiecewisePolynomial | None:
        """The joint path through the waypoints, parametrised by joint-space arc length."""
        points = [waypoints[0]]
        for w in waypoints[1:]:
            if np.linalg.norm(w - points[-1]) > 1e-6:
                points.append(w)
        if len(points) < 2:
            return None
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        Q = np.column_stack(points)
        if len(points) == 2:
            return PiecewisePolynomial.FirstOrderHold(s, Q)
        return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(s, Q)

    def _parametrise(self, path: PiecewisePolynomial, phase: Phase) -> PiecewisePolynomial:
        toppra = Toppra(path, self.plant, Toppra.CalcGridPoints(path, GRID))
        toppra.AddJointVelocityLimit(-self.velocity, self.velocity)
        toppra.AddJointAccelerationLimit(-self.acceleration, self.acceleration)
        if phase.tcp_acceleration is not None:
            limit = np.concatenate([[1e3] * 3, [phase.tcp_acceleration] * 3])
            toppra.AddFrameAccelerationLimit(self.tcp, -limit, limit)
        s_of_t = toppra.SolvePathParameterization()
        if s_of_t is None:
            raise RuntimeError("TOPPRA found no parametrisation of the joint path")
        return s_of_t

    def trajectory(self, phases: list[Phase]) -> tuple[PiecewisePolynomial, list[float]]:
        """One trajectory through every phase, and the time at which each phase ends."""
        times, qs, vs, ends = [0.0], [phases[0].waypoints[0]], [np.zeros_like(
            phases[0].waypoints[0])], []
        for phase in phases:
            t, q, v = self.samples(phase)
            if len(t) > 1:
                times.extend(times[-1] + t[1:])
                qs.extend(q[1:])
                vs.extend(v[1:])
            ends.append(times[-1])
        if len(times) == 1:  # nothing moves at all
            times.append(1e-3)
            qs.append(qs[0])
            vs.append(vs[0])
        trajectory = PiecewisePolynomial.CubicHermite(
            np.array(times), np.column_stack(qs), np.column_stack(vs))
        return trajectory, ends


def _still(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A phase that takes no time: the one sample q, at rest."""
    return np.zeros(1), q[None, :], np.zeros((1, len(q)))
