"""The UR10 URDF against the published DH parameters, and the object models' geometry."""

import numpy as np
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from drake_symplan.world.station_models import AddUr10, add_package_paths

D = [0.1273, 0, 0, 0.163941, 0.1157, 0.0922]
A = [0, -0.612, -0.5723, 0, 0, 0]
ALPHA = [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]


def dh_forward(q):
    T = np.eye(4)
    for i in range(6):
        ct, st = np.cos(q[i]), np.sin(q[i])
        ca, sa = np.cos(ALPHA[i]), np.sin(ALPHA[i])
        T = T @ np.array([[ct, -st * ca, st * sa, A[i] * ct],
                          [st, ct * ca, -ct * sa, A[i] * st],
                          [0, sa, ca, D[i]],
                          [0, 0, 0, 1]])
    return T


def test_tool0_matches_dh_over_random_configurations():
    plant = MultibodyPlant(0.0)
    parser = Parser(plant)
    add_package_paths(parser)
    AddUr10(plant, parser)
    plant.Finalize()
    ctx = plant.CreateDefaultContext()
    tool0 = plant.GetFrameByName("tool0")
    # ur_description's base_link is the DH base frame turned by pi about z.
    base = np.diag([-1.0, -1.0, 1.0, 1.0])
    rng = np.random.default_rng(0)
    for _ in range(50):
        q = rng.uniform(-np.pi, np.pi, 6)
        plant.SetPositions(ctx, np.concatenate([q, [0.0, 0.0]]))
        X = tool0.CalcPoseInWorld(ctx).GetAsMatrix4()
        T = base @ dh_forward(q)
        assert np.linalg.norm(X[:3, 3] - T[:3, 3]) < 1e-3
        assert np.allclose(X[:3, :3], T[:3, :3], atol=1e-6)


def test_arm_has_joint_limits_efforts_and_masses():
    plant = MultibodyPlant(0.0)
    parser = Parser(plant)
    add_package_paths(parser)
    arm = AddUr10(plant, parser)
    plant.Finalize()
    efforts = [plant.get_joint_actuator(i).effort_limit()
               for i in plant.GetJointActuatorIndices(arm)]
    assert efforts == [330, 330, 150, 56, 56, 56, 40, 40]
    mass = sum(plant.GetBodyByName(n).default_mass() for n in
               ["shoulder_link", "upper_arm_link", "forearm_link",
                "wrist_1_link", "wrist_2_link", "wrist_3_link"])
    assert abs(mass - (7.1 + 12.7 + 4.27 + 2.0 + 2.0 + 0.365)) < 1e-9
