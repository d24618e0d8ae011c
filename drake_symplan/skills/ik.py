"""Inverse kinematics for top-down gripper poses on the UR10 (Drake InverseKinematics + SNOPT).

The UR's +-2pi joint range lets a solver return wrapped solutions that swing the arm
through the table, so the program bounds every joint to one elbow-up branch and adds a
quadratic cost towards a nominal posture.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.solvers import Solve

from drake_symplan.world.station_models import FINGER_OPEN, AddUr10, add_package_paths

# One elbow-up branch that reaches the whole workspace with the gripper pointing down.
Q_LOWER = np.array([-np.pi, -np.pi, 0.0, -2.5 * np.pi / 2, -np.pi, -np.pi])
Q_UPPER = np.array([np.pi, 0.0, np.pi, np.pi / 4, 0.0, np.pi])
NOMINAL_Q = np.array([0.0, -1.2, 1.8, -2.2, -1.5708, 0.0])

POSITION_TOL = 1e-3  # m
ANGLE_TOL = 0.02  # rad


def top_down_rotation(yaw: float) -> RotationMatrix:
    """Gripper z pointing down, fingers closing along the world x axis rotated by `yaw`."""
    return RotationMatrix.MakeZRotation(yaw) @ RotationMatrix.MakeXRotation(np.pi)


class ArmIK:
    """Solves for arm joint angles that put the gripper TCP at a pose."""

    def __init__(self):
        self.plant = MultibodyPlant(0.0)
        parser = Parser(self.plant)
        add_package_paths(parser)
        self.arm = AddUr10(self.plant, parser)
        self.plant.Finalize()
        self.context = self.plant.CreateDefaultContext()
        self.tcp = self.plant.GetFrameByName("tcp")

    def solve(
        self, position: np.ndarray, yaw: float, seed: np.ndarray | None = None
    ) -> np.ndarray | None:
        """Arm joint angles (6,) with the TCP at `position`, top-down at `yaw`; None if none."""
        ik = InverseKinematics(self.plant, self.context, with_joint_limits=False)
        q = ik.q()
        prog = ik.get_mutable_prog()
        lower = np.concatenate([Q_LOWER, [FINGER_OPEN, FINGER_OPEN]])
        upper = np.concatenate([Q_UPPER, [FINGER_OPEN, FINGER_OPEN]])
        prog.AddBoundingBoxConstraint(lower, upper, q)
        p = np.asarray(position, float)
        ik.AddPositionConstraint(
            self.tcp, np.zeros(3), self.plant.world_frame(), p - POSITION_TOL, p + POSITION_TOL)
        ik.AddOrientationConstraint(
            self.plant.world_frame(), top_down_rotation(yaw), self.tcp, RotationMatrix(),
            ANGLE_TOL)
        nominal = np.concatenate([NOMINAL_Q, [FINGER_OPEN, FINGER_OPEN]])
        prog.AddQuadraticErrorCost(np.diag([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0, 0]), nominal, q)
        start = NOMINAL_Q if seed is None else seed
        prog.SetInitialGuess(q, np.concatenate([start, [FINGER_OPEN, FINGER_OPEN]]))
        result = Solve(prog)
        if not result.is_success():
            return None
        return result.GetSolution(q)[:6]

    def tcp_pose(self, q_arm: np.ndarray) -> RigidTransform:
        self.plant.SetPositions(self.context, np.concatenate([q_arm, [FINGER_OPEN] * 2]))
        return self.tcp.CalcPoseInWorld(self.context)
