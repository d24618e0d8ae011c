"""The station diagram: UR10 + gripper, table, a pool of boxes, PD control, optional Meshcat.

One diagram serves many episodes: `Station.reset(scene)` assigns pool bodies to the
scene's objects, parks (and locks) the unused ones under the table, and puts the arm home.
What the diagram is made of (StationConfig, the robot, table and pool) is station_models.py.
"""

from __future__ import annotations

import time
import zlib

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_symplan.boxes import HALF_EXTENTS, OBJECT_TYPES, tilt_of
from drake_symplan.boxes import contact_graph as box_contact_graph
from drake_symplan.datasets import ObjectState
from drake_symplan.world.cameras import (
    AddDepthCameras,
    DepthNoise,
    back_project,
    read_depth_frames,
    read_point_clouds,
    robot_shapes,
)
from drake_symplan.world.depth_sensor import calibration_error, camera_noise, reflectance_by_label
from drake_symplan.world.scenes import Scene, validate_scene

# BOX_MODULUS, FINGER_CLOSED, TIME_STEP and models_dir are made in station_models.py and
# imported from here (skills, data/collect.py, tests): re-exported, `as` themselves.
from drake_symplan.world.station_models import BOX_MODULUS as BOX_MODULUS
from drake_symplan.world.station_models import FINGER_CLOSED as FINGER_CLOSED
from drake_symplan.world.station_models import (
    FINGER_OPEN,
    HOME_Q,
    ROBOTS,
    StationConfig,
    add_models,
)
from drake_symplan.world.station_models import TIME_STEP as TIME_STEP
from drake_symplan.world.station_models import models_dir as models_dir


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
        # The robot (self.arm or self.hand), the table and the box pool (self.pool).
        self.arm, self.hand, self.pool = add_models(plant, scene_graph, cfg)
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
