"""What the station diagram is made of: StationConfig, the robot (UR10 + gripper, or the
hand), the table and the box pool, with their constants; world/station.py builds on it."""

from __future__ import annotations

import dataclasses as dc
from importlib import resources
from pathlib import Path

import numpy as np
from pydrake.geometry import ProximityProperties, RoleAssign
from pydrake.multibody.parsing import Parser
from pydrake.multibody.tree import PdControllerGains

from drake_symplan.boxes import OBJECT_TYPES
from drake_symplan.world.cameras import CameraConfig
from drake_symplan.world.hand import AddHand
from drake_symplan.world.scene_model import POOL

MODEL_FILES = {
    "cube": "package://drake_symplan_models/objects/cube.sdf",
    "long": "package://drake_symplan_models/objects/long_block.sdf",
}
ARM_JOINTS = [
    "shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
    "wrist_1_joint", "wrist_2_joint", "wrist_3_joint",
]
FINGER_JOINTS = ["left_finger_joint", "right_finger_joint"]
FINGER_OPEN = 0.05  # finger joint position (m): 8.5 cm between the finger pads
FINGER_CLOSED = 0.0  # commanded when grasping; contact stops the fingers earlier

ROBOTS = ("ur10", "hand")  # StationConfig.robot
# 10 ms, Hunt-Crossley contact (robot/backends.py): half the steps of 5 ms, the same
# outcomes on 117 of 120 random arm pick/places and 180 of 180 with the hand, placements
# 0.2-0.3 cm from their aim (median; 0.1-0.17 at 5 ms), hand-arm parity kept
# (docs/speed.md).
TIME_STEP = 1e-2  # s
# The boxes' hydroelastic modulus (Pa). At 1e7 a box resting on a box rocks in a
# discrete-time limit cycle at 10 ms and walks: a tower of two cubes drifts 1.8 cm in 4 s
# and one of four falls; at 1e6 every stack rests and single actions end as before
# (docs/world.md).
BOX_MODULUS = 1e6

# Home: TCP at (0.35, 0, 0.30) pointing down, behind the workspace (x >= 0.45): the
# cameras see every object unoccluded, and every pick starts close by.
HOME_Q = np.array([-0.4757, -2.1928, 2.4549, -1.8312, -1.5838, -2.0314])


@dc.dataclass
class StationConfig:
    """Everything that shapes the diagram; loadable with yaml_load_typed."""

    time_step: float = TIME_STEP
    contact_model: str = "hydroelastic_with_fallback"
    discrete_contact_approximation: str = "similar"
    box_modulus: float = BOX_MODULUS  # Pa, replaces the box models' own value
    pool_cubes: int = POOL["cube"]
    pool_longs: int = POOL["long"]
    arm_kp: list[float] = dc.field(default_factory=lambda: [4000, 4000, 2000, 500, 500, 300])
    arm_kd: list[float] = dc.field(default_factory=lambda: [400, 400, 200, 30, 30, 15])
    finger_kp: float = 1000.0
    finger_kd: float = 20.0
    cameras: list[CameraConfig] = dc.field(default_factory=list)  # see default_cameras()
    # "ur10": the arm and gripper in full physics; "hand": the collision-free hand of
    # world/hand.py (no arm), the fast back-end for data collection.
    robot: str = "ur10"
    # The depth sensor's errors (world/depth_sensor.CAMERA_NOISE) and the seed of its
    # per-camera calibration error and of its frames' noise when no rng is given.
    camera_noise: str = "none"
    camera_seed: int = 0


def models_dir() -> Path:
    """The installed models (package drake_symplan_models: the repo's top-level models/)."""
    return Path(str(resources.files("drake_symplan_models")))


def add_package_paths(parser: Parser) -> None:
    parser.package_map().AddPackageXml(str(models_dir() / "package.xml"))


def AddUr10(plant, parser: Parser):
    """Adds the UR10 + gripper welded at the world origin; returns its model instance."""
    (arm,) = parser.AddModels(url="package://drake_symplan_models/ur10/ur10.urdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link", arm))
    return arm


def _set_modulus(plant, scene_graph, body, modulus: float) -> None:
    """Sets the hydroelastic modulus of `body`'s collision geometries."""
    inspector = scene_graph.model_inspector()
    for geometry in plant.GetCollisionGeometriesForBody(body):
        properties = ProximityProperties(inspector.GetProximityProperties(geometry))
        properties.UpdateProperty("hydroelastic", "hydroelastic_modulus", modulus)
        scene_graph.AssignRole(plant.get_source_id(), geometry, properties, RoleAssign.kReplace)


def add_models(plant, scene_graph, cfg: StationConfig) -> tuple:
    """Adds the robot, the table and the box pool to `plant`: (the arm's model instance or
    None, the hand or None, the pool: object type -> its bodies)."""
    parser = Parser(plant)
    add_package_paths(parser)
    arm = hand = None
    if cfg.robot == "ur10":
        arm = AddUr10(plant, parser)
        # Gravity is compensated exactly by disabling it on the arm (PD alone would sag).
        plant.set_gravity_enabled(arm, False)
    (table,) = parser.AddModels(url="package://drake_symplan_models/table/table.sdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("__model__", table))
    pool: dict[str, list] = {t: [] for t in OBJECT_TYPES}
    sizes = {"cube": cfg.pool_cubes, "long": cfg.pool_longs}
    for kind in OBJECT_TYPES:
        for i in range(sizes[kind]):
            parser.SetAutoRenaming(True)
            (inst,) = parser.AddModels(url=MODEL_FILES[kind])
            plant.RenameModelInstance(inst, f"{kind}_{i}")
            body = plant.GetBodyByName("body", inst)
            _set_modulus(plant, scene_graph, body, cfg.box_modulus)
            pool[kind].append(body)
    if arm is not None:
        for name, kp, kd in zip(ARM_JOINTS, cfg.arm_kp, cfg.arm_kd, strict=True):
            plant.GetJointActuatorByName(name + "_motor").set_controller_gains(
                PdControllerGains(p=kp, d=kd))
        for name in FINGER_JOINTS:
            plant.GetJointActuatorByName(
                name.replace("_joint", "_motor")).set_controller_gains(
                PdControllerGains(p=cfg.finger_kp, d=cfg.finger_kd))
    else:
        hand = AddHand(plant, [b for bodies in pool.values() for b in bodies])
    return arm, hand, pool
