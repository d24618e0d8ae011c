"""The robot: one interface to act on the table and see it, two simulators of the action.

The agent executes plans with it and data collection explores with it.

- `arm`: the UR10 executes the IK-planned pick/place in full physics (skills/pick_place).
- `hand`: the collision-free simulated hand (world/hand.py, skills/hand_place.py) holds the
  grasped box with a weld constraint while carrying, then physics settles the scene; the
  grasp and release geometry is the arm's, and where the arm's wrist or fingers would
  touch what the hand does not, the arm itself runs the action (skills/arm_twin.py).

Both see the world only through the same perception: `reset` puts a scene on the table,
`perceive` returns a `PerceivedScene`, and `execute(action, before)` plans from the
perceived `before` (the beliefs) and returns the scenes perceived at the end of the lift
and after the action. Simulator state is used by the simulators themselves only (the
hand's grasp rule, settling) and by `ground_truth_states` / `ground_truth_poses`, which
are for bookkeeping (a problem's goal file, the evaluation's simulator check) and tests.

Drake is imported at the top: this layer is the simulator's.
"""

from __future__ import annotations

import dataclasses as dc
import time

import numpy as np
from scipy.spatial import QhullError

from drake_symplan.actions import Action
from drake_symplan.perception.perceive import Perceiver
from drake_symplan.skills.arm_twin import ArmTwin
from drake_symplan.skills.geometry import InfeasibleAction
from drake_symplan.skills.hand_place import hand_pick_place
from drake_symplan.skills.pick_place import PickPlaceMotions, run_motion
from drake_symplan.world.cameras import DepthNoise, default_cameras
from drake_symplan.world.scenes import Scene
from drake_symplan.world.station import Station, StationConfig
from drake_symplan.world.visualization import recording

# SAP's linear contact model with the boxes' 0.05 s relaxation time launches a box that
# drops a few cm onto the table (both robots); Hunt-Crossley ("similar", still the SAP
# solver, so weld constraints work) lands it. Random releases drop boxes all the time.
CONTACT_APPROXIMATION = "similar"
RESET_SETTLE = 0.1  # s of physics after putting a sampled scene on the table


class PerceptionFailure(Exception):
    """Perception raised on a scene (a numerical failure): the episode cannot go on.

    Not a RuntimeError, so the back-ends' simulation-failure handlers let it through."""


@dc.dataclass
class Execution:
    """What one action did, as perceived. status: "ok" | "infeasible" | "sim_failure"."""

    status: str
    lift: object = None  # PerceivedScene at the end of the lift
    after: object = None  # PerceivedScene after the action
    message: str = ""
    obstacles: tuple[str, ...] = ()  # infeasible: the boxes in the arm's way, where known
    at: str = ""  # infeasible: "grasp" or "release", the side the arm refused at


class Backend:
    """A station with cameras, a perceiver and a way to execute the action; `meshcat`
    shows the station live (and lets `recording` write it); `camera_noise` and
    `camera_seed`: the cameras' sensor model; `time_step` and `box_modulus`, where given,
    the physics' (StationConfig)."""

    name = ""
    robot = ""
    perception_seconds = 0.0  # wall time spent in perceive, for the benchmarks

    def __init__(self, noise: DepthNoise | None = None, rng: np.random.Generator | None = None,
                 time_step: float | None = None, meshcat=None, camera_noise: str = "none",
                 camera_seed: int = 0, box_modulus: float | None = None):
        config = StationConfig(cameras=default_cameras(), robot=self.robot,
                               discrete_contact_approximation=CONTACT_APPROXIMATION,
                               camera_noise=camera_noise, camera_seed=camera_seed)
        if time_step is not None:
            config.time_step = time_step
        if box_modulus is not None:
            config.box_modulus = box_modulus
        self.station = Station(config, meshcat=meshcat)
        self.perceiver = Perceiver()
        self.noise = noise if noise is not None and noise.active else None
        self.rng = rng or np.random.default_rng(0)

    @property
    def noisy(self) -> bool:
        """Whether perceiving the same scene twice can see it differently (depth noise or
        the cameras' sensor model)."""
        return self.noise is not None or self.station.sensor.active

    def seconds(self) -> dict[str, float]:
        """Wall time spent so far in physics (simulating) and in perception (rendering
        included): where collection time goes, for `data stats` and the benchmark."""
        return {"physics": self.station.physics_seconds, "perception": self.perception_seconds}

    def reset(self, scene: Scene) -> None:
        self.station.reset(scene)
        self.station.settle(RESET_SETTLE)

    def mirror(self, types: dict[str, str], poses: dict) -> None:
        """Puts objects at simulated poses (another station's state, from
        `ground_truth_poses`), robot home, and lets them settle as `reset` does."""
        self.station.mirror(types, poses)
        self.station.settle(RESET_SETTLE)

    def perceive(self, prior=None, views=None):
        """The scene as perceived now; `prior`: the scene perceived before the action;
        `views` (perception.perceive.DepthViews: frames on disk): perceived instead of
        what the station's cameras see."""
        start = time.perf_counter()
        try:
            if views is not None:
                return self.perceiver.perceive_views(views, self.noise, self.rng, prior)
            return self.perceiver.perceive(self.station, noise=self.noise, rng=self.rng,
                                           prior=prior)
        except (ValueError, ArithmeticError, QhullError) as e:
            raise PerceptionFailure(f"perception failed: {type(e).__name__}: {e}") from e
        finally:
            self.perception_seconds += time.perf_counter() - start

    def execute(self, action: Action, before, lift: bool = True) -> Execution:
        """Runs `action` planned from the perceived `before`; `lift=False` skips perceiving
        the scene at the end of the lift (Execution.lift is None then)."""
        raise NotImplementedError

    def ground_truth_states(self) -> dict:
        """Simulator truth (tests and bookkeeping only; never a learning input)."""
        return self.station.object_states()

    def ground_truth_poses(self) -> tuple[dict, dict[str, str]]:
        """(pose by object, type by object) as simulated: what a problem's goal file
        records (a world description, never a belief)."""
        return self.station.object_poses(), dict(self.station.types)

    def recording(self, path):
        """A context that records the station's Meshcat to the HTML file `path` (None:
        nothing; also nothing without a Meshcat)."""
        return recording(self.station, path)


class HandBackend(Backend):
    """The fast back-end: weld-constraint hand; carries are kinematic or rigid (hand_place),
    and what the arm's wrist or fingers would touch otherwise, the arm's (`twin`)."""

    name = "hand"
    robot = "hand"

    def __init__(self, *args, allow_kinematic: bool = True, arm_twin: bool = True, **kwargs):
        super().__init__(*args, **kwargs)
        self.allow_kinematic = allow_kinematic
        self.twin = ArmTwin() if arm_twin else None

    def seconds(self) -> dict[str, float]:
        out = super().seconds()
        out["physics"] += self.twin.physics_seconds if self.twin else 0.0
        return out

    def execute(self, action: Action, before, lift: bool = True) -> Execution:
        at_lift = (lambda: self._perceive_if_moved(before)) if lift else (lambda: None)
        try:
            motion, lifted = hand_pick_place(self.station, action, before.object_states(),
                                             at_lift=at_lift,
                                             allow_kinematic=self.allow_kinematic,
                                             twin=self.twin)
        except InfeasibleAction as e:
            return Execution("infeasible", message=str(e), obstacles=e.obstacles, at=e.at)
        except RuntimeError as e:
            # The state is unusable; the episode ends and the next reset starts afresh.
            self.station.release()
            return Execution("sim_failure", message=f"simulation failed: {e}")
        if motion.held is None and not motion.by_arm and not self.noisy:
            # Nothing was caught, so nothing was simulated: the scene is exactly the one
            # perceived before, and perceiving it again would return the same objects.
            return Execution("ok", before if lift else None, before)
        if lift and lifted is None:
            lifted = before
        return Execution("ok", lifted, self.perceive(before))

    def _perceive_if_moved(self, before):
        moved = self.station.held is not None or bool(self.twin and self.twin.running)
        return self.perceive(before) if moved or self.noisy else None


class ArmBackend(Backend):
    """The UR10 with the IK primitives in full physics."""

    name = "arm"
    robot = "ur10"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.planner = PickPlaceMotions()

    def execute(self, action: Action, before, lift: bool = True) -> Execution:
        try:
            motion = self.planner.plan(action, before.object_states(),
                                       self.station.robot_positions(), lift_hold=lift)
        except InfeasibleAction as e:
            return Execution("infeasible", message=str(e), obstacles=e.obstacles, at=e.at)
        at_lift = (lambda: self.perceive(before)) if lift else (lambda: None)
        try:
            lifted = run_motion(self.station, motion, at_lift)
        except RuntimeError as e:
            # The state is unusable; the episode ends and the next reset starts afresh.
            return Execution("sim_failure", message=f"simulation failed: {e}")
        return Execution("ok", lifted, self.perceive(before))


BACKENDS: dict[str, type[Backend]] = {"hand": HandBackend, "arm": ArmBackend}


def make_backend(name: str, **kwargs) -> Backend:
    if name not in BACKENDS:
        raise ValueError(f"unknown back-end {name!r}; expected one of {tuple(BACKENDS)}")
    return BACKENDS[name](**kwargs)
