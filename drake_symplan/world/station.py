"""The station diagram: UR10 + gripper, table, a pool of boxes, PD control, optional Meshcat.

One diagram serves many episodes: `Station.reset(scene)` assigns pool bodies to the
scene's objects, parks (and locks) the unused ones under the table, and puts the arm home.
"""

from __future__ import annotations

import dataclasses as dc
import time
import zlib
from importlib import resources
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    Meshcat,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    ProximityProperties,
    Role,
    RoleAssign,
)
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import PdControllerGains
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_symplan.boxes import HALF_EXTENTS, OBJECT_TYPES, tilt_of
from drake_symplan.boxes import contact_graph as box_contact_graph
from drake_symplan.datasets import ObjectState
from drake_symplan.world.cameras import (
    AddDepthCameras,
    CameraConfig,
    DepthNoise,
    back_project,
    read_depth_frames,
    read_point_clouds,
    robot_shapes,
)
from drake_symplan.world.depth_sensor import calibration_error, camera_noise, reflectance_by_label
from drake_symplan.world.hand import AddHand
from drake_symplan.world.scenes import Scene, validate_scene

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
    pool_cubes: int = 16
    pool_longs: int = 8
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


def _scene_digest(scene: Scene) -> int:
    """A stable number of a scene's objects (names, types, poses to 0.1 mm)."""
    text = ";".join(f"{o.name},{o.type},{np.round(o.position, 4).tolist()},{o.yaw:.4f}"
                    for o in scene.objects)
    return zlib.crc32(text.encode())


def _parked_pose(index: int) -> RigidTransform:
    # Far below the table and apart from each other: out of every camera's view.
    return RigidTransform([-3.0 + 0.4 * index, 3.0, -3.0])


class Station:
    """The built diagram plus handles and per-episode reset."""

    def __init__(self, config: StationConfig | None = None, meshcat: Meshcat | None = None):
        self.config = config or StationConfig()
        cfg = self.config
        if cfg.robot not in ROBOTS:
            raise ValueError(f"unknown robot {cfg.robot!r}; expected one of {ROBOTS}")
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(
            time_step=cfg.time_step, contact_model=cfg.contact_model,
            discrete_contact_approximation=cfg.discrete_contact_approximation), builder)
        self._add_models(plant, scene_graph)
        plant.Finalize()
        self._add_command_source(builder, plant)
        self.meshcat = meshcat
        self.visualizer = None
        if meshcat is not None:
            self.visualizer = MeshcatVisualizer.AddToBuilder(
                builder, scene_graph, meshcat,
                MeshcatVisualizerParams(role=Role.kIllustration, prefix="station"))
        self.plant, self.scene_graph = plant, scene_graph
        self.cameras = AddDepthCameras(builder, scene_graph, cfg.cameras)
        self.sensor = camera_noise(cfg.camera_noise)
        self._add_sensor_errors()
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.physics_seconds = 0.0  # wall time spent in advance_to, for the benchmarks
        self.context = self.simulator.get_mutable_context()
        self.plant_context = plant.GetMyMutableContextFromRoot(self.context)
        self.assigned: dict[str, object] = {}  # scene name -> body
        self.types: dict[str, str] = {}
        self._name_of: dict = {}  # body index -> scene name
        self._following = None  # (the trajectory `follow` commands, its shift)
        # Each pool body's model instance holds exactly its floating joint.
        self._floating_joints = {
            b.index(): plant.get_joint(plant.GetJointIndices(b.model_instance())[0])
            for bodies in self.pool.values() for b in bodies
        }

    def _add_models(self, plant, scene_graph) -> None:
        """Adds the robot (self.arm or self.hand), the table and the box pool (self.pool)."""
        cfg = self.config
        parser = Parser(plant)
        add_package_paths(parser)
        self.arm = self.hand = None
        if cfg.robot == "ur10":
            self.arm = AddUr10(plant, parser)
            # Gravity is compensated exactly by disabling it on the arm (PD alone would sag).
            plant.set_gravity_enabled(self.arm, False)
        (table,) = parser.AddModels(url="package://drake_symplan_models/table/table.sdf")
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("__model__", table))
        self.pool: dict[str, list] = {t: [] for t in OBJECT_TYPES}
        sizes = {"cube": cfg.pool_cubes, "long": cfg.pool_longs}
        for kind in OBJECT_TYPES:
            for i in range(sizes[kind]):
                parser.SetAutoRenaming(True)
                (inst,) = parser.AddModels(url=MODEL_FILES[kind])
                plant.RenameModelInstance(inst, f"{kind}_{i}")
                body = plant.GetBodyByName("body", inst)
                _set_modulus(plant, scene_graph, body, cfg.box_modulus)
                self.pool[kind].append(body)
        if self.arm is not None:
            for name, kp, kd in zip(ARM_JOINTS, cfg.arm_kp, cfg.arm_kd, strict=True):
                plant.GetJointActuatorByName(name + "_motor").set_controller_gains(
                    PdControllerGains(p=kp, d=kd))
            for name in FINGER_JOINTS:
                plant.GetJointActuatorByName(
                    name.replace("_joint", "_motor")).set_controller_gains(
                    PdControllerGains(p=cfg.finger_kp, d=cfg.finger_kd))
        else:
            self.hand = AddHand(plant, [b for bodies in self.pool.values() for b in bodies])

    def _add_sensor_errors(self) -> None:
        """The cameras' calibration errors (fixed for the station's life), the surfaces'
        reflectance and the sensor's own noise source, all from `camera_seed`."""
        seed = self.config.camera_seed
        self.sensor_rng = np.random.default_rng([seed, 1])
        self.reflectance = None
        if not self.sensor.active:
            return
        if self.sensor.calib_translation > 0 or self.sensor.calib_rotation_deg > 0:
            rng = np.random.default_rng([seed, 0])
            for cam in self.cameras:
                cam.miscalibrate(calibration_error(self.sensor, rng))
        if self.sensor.dark_holes > 0:
            self.reflectance = reflectance_by_label(self.scene_graph)

    def _add_command_source(self, builder, plant) -> None:
        """Adds the source of the robot's commanded trajectory (`hold` and `follow` set it)."""
        if self.arm is not None:
            self.command_source = builder.AddSystem(
                TrajectorySource(self.hold_trajectory(HOME_Q), 1))
            builder.Connect(self.command_source.get_output_port(),
                            plant.get_desired_state_input_port(self.arm))
        else:
            self.command_source = self.hand.add_command_source(builder)

    def hold_trajectory(self, q: np.ndarray, finger: float = FINGER_OPEN) -> PiecewisePolynomial:
        """A constant command: robot positions `q` (the arm's with `finger`, or the hand's)."""
        if self.arm is not None:
            q = np.concatenate([q, [finger, finger]])
        q = np.asarray(q, float)
        return PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.column_stack([q, q]))

    # --- episodes -----------------------------------------------------------------

    def reset(self, scene: Scene, q_arm: np.ndarray = HOME_Q) -> None:
        """Puts the scene's objects on the table, parks the rest, robot home, time 0."""
        validate_scene(scene)
        # The frames' noise restarts from the scene itself: a problem's start is seen with
        # the same noise whichever solves ran before it, in whichever worker.
        self.sensor_rng = np.random.default_rng([self.config.camera_seed, 1,
                                                 _scene_digest(scene)])
        self._put({o.name: o.type for o in scene.objects},
                  {o.name: RigidTransform(RollPitchYaw(o.orientation),
                                          np.asarray(o.position, float))
                   for o in scene.objects}, q_arm)

    def mirror(self, types: dict[str, str], poses: dict[str, RigidTransform],
               velocities: dict[str, SpatialVelocity] | None = None,
               q_arm: np.ndarray = HOME_Q) -> None:
        """Like `reset`, with the objects at the poses (and velocities) of another station's
        (as simulated, so not validated as a scene file is): the arm twin's start
        (skills/arm_twin.py)."""
        self._put(types, poses, q_arm, velocities or {})

    def _put(self, types: dict[str, str], poses: dict[str, RigidTransform],
             q_arm: np.ndarray, velocities: dict | None = None) -> None:
        counts = {t: sum(v == t for v in types.values()) for t in OBJECT_TYPES}
        for t in OBJECT_TYPES:
            if counts[t] > len(self.pool[t]):
                raise ValueError(
                    f"scene has {counts[t]} objects of type {t!r}; the station's pool has "
                    f"{len(self.pool[t])} (StationConfig.pool_{t}s)")
        self.context.SetTime(0.0)
        self._following = None
        plant, ctx = self.plant, self.plant_context
        self.assigned, self.types = {}, {}
        used = {t: 0 for t in OBJECT_TYPES}
        for name, kind in types.items():
            body = self.pool[kind][used[kind]]
            used[kind] += 1
            self.assigned[name], self.types[name] = body, kind
        self._name_of = {b.index(): n for n, b in self.assigned.items()}
        park = 0
        for t in OBJECT_TYPES:
            for i, body in enumerate(self.pool[t]):
                fj = self._floating_joints[body.index()]
                fj.Unlock(ctx)
                if i >= used[t]:
                    plant.SetFreeBodyPose(ctx, body, _parked_pose(park))
                    plant.SetFreeBodySpatialVelocity(ctx, body, SpatialVelocity.Zero())
                    fj.Lock(ctx)
                    park += 1
        for name, X in poses.items():
            self.set_object_pose(name, X)
        for name, V in (velocities or {}).items():
            plant.SetFreeBodySpatialVelocity(ctx, self.assigned[name], V)
        if self.arm is not None:
            q = np.concatenate([q_arm, [FINGER_OPEN, FINGER_OPEN]])
            plant.SetPositions(ctx, self.arm, q)
            plant.SetVelocities(ctx, self.arm, np.zeros(8))
            self.hold(q_arm)
        else:
            self.hand.reset(ctx)
        self.simulator.Initialize()
        self._show_only_assigned()  # after Initialize: it re-creates the geometry

    def _show_only_assigned(self) -> None:
        if self.meshcat is None:
            return
        in_use = {b.index() for b in self.assigned.values()}
        for bodies in self.pool.values():
            for b in bodies:
                path = f"/drake/station/{self.plant.GetModelInstanceName(b.model_instance())}"
                self.meshcat.SetProperty(path, "visible", b.index() in in_use)

    # --- commanding the robot -----------------------------------------------------

    def time(self) -> float:
        return self.context.get_time()

    def hold(self, q: np.ndarray, finger: float = FINGER_OPEN) -> None:
        """Commands the robot to hold positions `q` (arm: 6 joints, hand: its 6) from now on."""
        self.command_source.UpdateTrajectory(self.hold_trajectory(q, finger))
        self._following = None

    def follow(self, trajectory: PiecewisePolynomial, t_from: float, t_to: float) -> None:
        """Tracks `trajectory` (in its own time) from t_from, which is now, to t_to.

        The one way every skill moves the robot: consecutive calls with the same
        trajectory continue it (follow(tr, 0, t1); perceive; follow(tr, t1, t2))."""
        t0 = self.context.get_time() - t_from
        last = self._following
        if last is None or last[0] is not trajectory or last[1] != t0:  # not commanded yet
            shifted = trajectory.Clone()
            shifted.shiftRight(t0)
            self.command_source.UpdateTrajectory(shifted)
            self._following = (trajectory, t0)
        self.advance_to(t0 + t_to)

    def settle(self, seconds: float = 0.5) -> None:
        """Lets physics run with the current command held (objects come to rest)."""
        self.advance_to(self.context.get_time() + seconds)

    def advance_to(self, t: float) -> None:
        """Simulates up to time t; the wall time it takes adds to `physics_seconds`."""
        start = time.perf_counter()
        try:
            self.simulator.AdvanceTo(t)
        finally:
            self.physics_seconds += time.perf_counter() - start

    def snapshot(self):
        """The full simulation state now, for `restore`."""
        return self.context.Clone()

    def restore(self, snapshot) -> None:
        """Back to a `snapshot`, the robot holding where it was then."""
        self.context.SetTimeStateAndParametersFrom(snapshot)
        self.hold(self.robot_positions())
        self.simulator.Initialize()

    def robot_positions(self) -> np.ndarray:
        """The arm's six joint positions, or the hand's [x, y, z, yaw, pitch, roll]."""
        if self.arm is not None:
            return self.plant.GetPositions(self.plant_context, self.arm)[:6].copy()
        return self.hand.positions(self.plant_context)

    # --- the hand (robot "hand" only) ---------------------------------------------

    @property
    def held(self) -> str | None:
        """The scene name of the object the hand holds, or None."""
        body = self.hand.held if self.hand is not None else None
        return None if body is None else self._name_of[body.index()]

    def grasp(self, name: str) -> None:
        """Puts the hand at the object's pose and welds them (the grasp never moves it)."""
        self.hand.grasp(self.plant_context, self.assigned[name])

    def release(self) -> None:
        self.hand.release(self.plant_context)

    def set_robot_positions(self, q: np.ndarray) -> None:
        """Kinematically puts the hand at q, at rest (the held object is moved separately)."""
        self.hand.set_positions(self.plant_context, q)

    def set_object_pose(self, name: str, X: RigidTransform) -> None:
        """Kinematically puts an object at pose X, at rest."""
        body = self.assigned[name]
        self.plant.SetFreeBodyPose(self.plant_context, body, X)
        self.plant.SetFreeBodySpatialVelocity(self.plant_context, body, SpatialVelocity.Zero())

    # --- ground truth (tests and perception measurement only) ----------------------

    def object_poses(self) -> dict[str, RigidTransform]:
        return {n: self.plant.EvalBodyPoseInWorld(self.plant_context, b)
                for n, b in self.assigned.items()}

    def object_velocities(self) -> dict[str, SpatialVelocity]:
        return {n: self.plant.EvalBodySpatialVelocityInWorld(self.plant_context, b)
                for n, b in self.assigned.items()}

    def object_states(self) -> dict[str, ObjectState]:
        out = {}
        for n, X in self.object_poses().items():
            R = X.rotation()
            yaw = float(RollPitchYaw(R).yaw_angle())
            out[n] = ObjectState(n, self.types[n], X.translation().copy(), yaw, tilt_of(R.matrix()))
        return out

    def contact_graph(self, tolerance: float = 0.003) -> set[tuple[str, str]]:
        """Pairs of scene objects whose surfaces are within `tolerance` (sorted names)."""
        query = self._query()
        body_of = {}
        for name, body in self.assigned.items():
            for gid in self.plant.GetCollisionGeometriesForBody(body):
                body_of[gid] = name
        pairs = set()
        try:
            closest = query.ComputeSignedDistancePairwiseClosestPoints(tolerance)
        except RuntimeError:
            # FCL's GJK gives up on some boxes touching face to face exactly (it reports
            # the origin outside the polytope by 1e-14); the boxes' own geometry answers.
            return box_contact_graph(
                {n: (X.translation(), X.rotation().matrix(),
                     np.array(HALF_EXTENTS[self.types[n]]))
                 for n, X in self.object_poses().items()}, tolerance)
        for d in closest:
            a, b = body_of.get(d.id_A), body_of.get(d.id_B)
            if a and b and a != b:
                pairs.add(tuple(sorted((a, b))))
        return pairs

    # --- sensing (what perception may read) -----------------------------------------

    def point_clouds(self, noise: DepthNoise | None = None, rng=None,
                     z_min: float | None = None) -> list[np.ndarray]:
        """World-frame depth points [M, 3] from each camera at the current state, as the
        sensor gives them (one frame) and located where perception believes the cameras
        are; `noise` perturbs them further."""
        if not self.sensor.active:
            self._check_cameras()
            return read_point_clouds(self.cameras, self.context, noise, rng, z_min)
        clouds = [back_project(cam, frames[0], z_min) for cam, frames in
                  zip(self.cameras, self.depth_frames(1, rng), strict=True)]
        if noise is not None and noise.active:
            rng = rng or self.sensor_rng
            clouds = [noise.apply(c, cam.X_WB.translation(), rng)
                      for cam, c in zip(self.cameras, clouds, strict=True)]
            clouds = clouds if z_min is None else [c[c[:, 2] > z_min] for c in clouds]
        return clouds

    def depth_frames(self, frames: int = 1, rng=None) -> list[np.ndarray]:
        """Each camera's `frames` depth images [F, H, W] (NaN: no return) of the current
        state, from the sensor (StationConfig.camera_noise); `rng`: the noise's source
        (default the station's own)."""
        self._check_cameras()
        return read_depth_frames(self.cameras, self.context, self.sensor,
                                 rng or self.sensor_rng, frames, self.reflectance)

    def _check_cameras(self) -> None:
        if not self.cameras:
            raise ValueError("the station has no cameras (StationConfig.cameras is empty)")

    def clearance(self, names: list[str], cap: float = 0.01) -> float:
        """Distance (m) from the named objects to the nearest geometry not theirs, at most cap
        (ground truth: the hand's simulation of a release uses it)."""
        query = self._query()
        mine = {g for n in names for g in self.plant.GetCollisionGeometriesForBody(self.assigned[n])}
        best = cap
        for d in query.ComputeSignedDistancePairwiseClosestPoints(cap):
            if (d.id_A in mine) != (d.id_B in mine):
                best = min(best, d.distance)
        return best

    def robot_collision_shapes(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """The robot's collision shapes at its current joint state (proprioception):
        world/cameras.robot_shapes."""
        if self.arm is None:
            return []
        return robot_shapes(self.plant, self._query(), self.arm)

    def _query(self):
        return self.scene_graph.get_query_output_port().Eval(
            self.scene_graph.GetMyContextFromRoot(self.context))
