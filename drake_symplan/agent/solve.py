"""Solving one goal in full physics: perceive, read symbols, plan, execute, monitor, check.

`solve(start_scene, goal_scene, bundle)` builds one station (cameras and the robot of the
chosen back-end, data/backends.py) and runs `Agent.solve` on it; `Agent` keeps the station
for many solves (the evaluation).

1. The goal scene is put on the table and perceived; the file only names the boxes
   (agent/beliefs.py). The start scene likewise, then the robot stays in it.
2. The bundle reads both scenes' symbols and writes the problem: the start's certain atoms,
   the goal's unary atoms and relation atoms only between objects perceived in contact in
   the goal scene. The planner (Fast Downward or pyperplan) plans.
3. Each step is executed by the back-end on the perceived objects (the arm: IK-planned
   pick/place in full physics); the scene perceived after it keeps the names through
   perception's association. Before it runs, its offsets may be swapped for an
   interchangeable operator's that land the source nearer its goal, and a box that the
   symbols leave off its goal position on the table may be put down beside another first
   (agent/refine.py; both with `refine`).
4. Monitoring: after each step the bundle compares the perceived symbols with what the
   step's operator predicted; on a mismatch the agent replans from the perceived state
   (if that replan fails, the current plan runs on).
   When the plan has run out, the goal's atoms must hold in the perceived symbols, or it
   replans too. At most `max_replans` replans; after that the current plan runs on.
   Without monitoring the first plan runs open-loop, as in the paper.
5. The check: every object within GOAL_TOLERANCE (5 cm) of its perceived goal position,
   on the scene perceived after the last step. The simulator's positions are reported
   beside it (`final_true`), for evaluation only: no decision reads them.
"""

from __future__ import annotations

import dataclasses as dc
import time
from contextlib import contextmanager

from drake_symplan.agent import beliefs
from drake_symplan.agent.refine import (
    REPOSITIONS_PER_OBJECT,
    advance,
    reaches,
    refine_step,
    reposition_action,
    reposition_step,
)

GOAL_TOLERANCE = 0.05  # m
STATUSES = ("success", "failure", "no_plan", "timeout", "infeasible", "error")
FAILURE_CAUSES = ("no_plan", "timeout", "execution", "perception", "infeasible", "error")
PHASES = ("perceive", "symbols", "plan", "execute", "total")
RESET_SETTLE = 0.1  # s of physics after putting a scene on the table (as data/backends.py)
# Planner statuses -> the agent's status (= failure cause) when the plan cannot be had.
_PLANNER_STATUS = {"unsolvable": "no_plan", "timeout": "timeout", "error": "error"}


@dc.dataclass
class SolveResult:
    """What `solve` returns; `to_json` is the documented JSON. `plan` is the first plan,
    `executed` every step executed (replans included)."""

    status: str
    plan: list[str] = dc.field(default_factory=list)
    executed: list[str] = dc.field(default_factory=list)
    replans: int = 0
    objects: dict[str, dict] = dc.field(default_factory=dict)
    seconds: dict[str, float] = dc.field(default_factory=dict)
    failure_cause: str | None = None
    message: str = ""
    # On a failure: do the goal's atoms hold in the last perceived scene? True with objects
    # off their goal positions means the symbols did not capture the goal; False means the
    # plan did not reach it (an operator's prediction or the execution went wrong).
    symbolic_goal_reached: bool | None = None

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"unknown status {self.status!r}; expected one of {STATUSES}")

    @property
    def success(self) -> bool:
        return self.status == "success"

    def to_json(self) -> dict:
        out = {"status": self.status, "plan": list(self.plan), "executed": list(self.executed),
               "replans": self.replans, "objects": self.objects,
               "seconds": {k: round(v, 4) for k, v in self.seconds.items()}}
        if not self.success:
            out["failure_cause"] = self.failure_cause
            out["message"] = self.message
            out["symbolic_goal_reached"] = self.symbolic_goal_reached
        return out


class _Clock:
    """Wall time per phase; perception inside other phases is moved to "perceive"."""

    def __init__(self, backend):
        self.backend = backend
        self.seconds = dict.fromkeys(PHASES, 0.0)

    @contextmanager
    def __call__(self, phase: str):
        start, seen = time.perf_counter(), self.backend.perception_seconds
        try:
            yield
        finally:
            perceived = self.backend.perception_seconds - seen
            self.seconds[phase] += time.perf_counter() - start - perceived
            self.seconds["perceive"] += perceived


class Agent:
    """One station with cameras and a robot that solves goals. `backend`: "arm" (the UR10
    in full physics), "hand" (the fast hand), or a data.backends.Backend to use as it is."""

    def __init__(self, backend="arm", meshcat=None):
        from drake_symplan.data.backends import make_backend

        self.backend = make_backend(backend) if isinstance(backend, str) else backend
        if meshcat is not None:
            # Backends build their station without a viewer: rebuild it with one.
            from drake_symplan.world.station import Station

            self.backend.station = Station(self.backend.station.config, meshcat=meshcat)

    @property
    def station(self):
        return self.backend.station

    def show(self, scene) -> None:
        """Puts `scene` on the table (tilted objects at their full `rpy`), robot home, and
        lets physics settle it."""
        self.station.reset(scene)
        self.station.settle(RESET_SETTLE)

    def look(self, scene, clock: _Clock | None = None) -> beliefs.Named:
        """Shows `scene` and perceives it, the boxes named after the file's objects; the
        perception (not the showing) counts on `clock` as "perceive"."""
        self.show(scene)
        if clock is None:
            return self.see(scene)
        with clock("perceive"):
            return self.see(scene)

    def see(self, scene) -> beliefs.Named:
        """Perceives the table as it is now, the boxes named after `scene`'s objects."""
        return beliefs.name_by_file(self.backend.perceive(), scene)

    def solve(self, start_scene, goal_scene, bundle, planner: str = "fd", timeout: float = 10.0,
              monitor: bool = True, max_replans: int = 2, record=None,
              refine: bool = True) -> SolveResult:
        """Solves `goal_scene` from `start_scene` (world.scenes.Scene) with `bundle`; with
        `refine`, each step's offsets are chosen among its equivalents (agent/refine.py)."""
        from drake_symplan.data.backends import PerceptionFailure
        from drake_symplan.world.visualization import recording

        beliefs.check_scene_pair(start_scene, goal_scene)
        clock = _Clock(self.backend)
        t0 = time.perf_counter()
        run = _Run(self, bundle, clock, planner, timeout, monitor, max_replans, refine)
        try:
            goal = self.look(goal_scene, clock)
            with recording(self.station, record):  # from the start scene on
                start = self.look(start_scene, clock)
                result = run.go(start, goal)
        except PerceptionFailure as e:  # perception raised: the loop cannot go on
            result = run.result
            result.status, result.failure_cause, result.message = "failure", "perception", str(e)
        result.seconds = dict(clock.seconds, total=time.perf_counter() - t0)
        return result


class _Run:
    """The loop of one solve; `go` returns the SolveResult without its seconds."""

    def __init__(self, agent: Agent, bundle, clock: _Clock, planner: str, timeout: float,
                 monitor: bool, max_replans: int, refine: bool = True):
        self.agent, self.bundle, self.clock = agent, bundle, clock
        self.planner, self.timeout = planner, timeout
        self.monitor, self.max_replans, self.refine = monitor, max_replans, refine
        self.result = SolveResult("failure")
        self.goal, self.goal_reading, self.goal_atoms = None, None, set()
        self.repositions = 0

    def go(self, start: beliefs.Named, goal: beliefs.Named) -> SolveResult:
        self.goal = goal
        if goal.lost or start.lost:
            lost = [f"{n} (goal)" for n in goal.lost] + [f"{n} (start)" for n in start.lost]
            return self._end(start.scene, "perception", f"perception lost {', '.join(lost)}")
        now = start.scene
        with self.clock("symbols"):
            self.goal_reading = self._read(goal.scene)
            reading = self._read(now)
            believed = self._believe(reading)
            self.goal_atoms = self.bundle.goal_atoms(self.goal_reading,
                                                     self.goal.scene.contacts)
        steps, stop = self._plan(reading)
        if stop:
            return self._end(now, *stop)
        self.result.plan = list(steps)
        while True:
            while True:
                if self.refine and self.repositions < REPOSITIONS_PER_OBJECT * len(now.names):
                    extra = reposition_step(steps, now, self.goal.scene, GOAL_TOLERANCE)
                    if extra is not None:
                        steps.insert(0, extra)
                        self.repositions += 1
                if not steps:
                    break
                step = steps.pop(0)
                moving = reposition_action(step)
                if self.refine and moving is None:
                    with self.clock("symbols"):
                        step = refine_step(self.bundle, step, steps, believed,
                                           self.goal_atoms,
                                           beliefs.positions(now),
                                           beliefs.positions(self.goal.scene),
                                           self.goal.scene.contacts)
                with self.clock("execute"):
                    action = moving or self.bundle.action_of(step)
                    execution = self.agent.backend.execute(action, now)
                self.result.executed.append(step)
                if execution.status == "infeasible":
                    return self._end(now, "infeasible", f"{step}: {execution.message}")
                if execution.status != "ok":
                    return self._end(now, "error", f"{step}: {execution.message}")
                seen = self._follow(now, execution.after, action)
                if seen.lost:
                    return self._end(seen.scene, "perception",
                                     f"after {step} perception lost {', '.join(seen.lost)}")
                before, now = reading, seen.scene
                if not self.monitor:  # open loop: the state is what the operator predicted
                    if self.refine and moving is None:
                        believed = advance(self.bundle, step, believed)
                    continue
                with self.clock("symbols"):
                    reading = self._read(now)
                    believed = self._believe(reading)
                    # A repositioning predicts no symbolic change: the rest must still apply.
                    wrong = not reaches(self.bundle, steps, believed, self.goal_atoms) \
                        if moving else self.bundle.mismatches(reading, step, before)
                if wrong and self.result.replans < self.max_replans:
                    replanned, stop = self._replan(reading)
                    if not stop:
                        steps = replanned
                    elif not steps:
                        return self._end(now, *stop)
                    # else the planner found nothing from here (timeout, no plan): the
                    # current plan runs on, as it would open loop.
            # The plan has run out. The monitor checks that the goal's atoms are seen too:
            # a step can pass its own check and still disturb another object.
            if not self.monitor or self.result.replans >= self.max_replans:
                break
            with self.clock("symbols"):
                reached = self._goal_holds(reading)
            if reached:
                break
            steps, stop = self._replan(reading)
            if stop:
                return self._end(now, *stop)
            if not steps:
                break
        return self._end(now, "execution", "")

    def _replan(self, reading) -> tuple[list[str], tuple[str, str] | None]:
        self.result.replans += 1
        return self._plan(reading)

    def _goal_holds(self, reading) -> bool:
        """Do the goal's atoms hold in `reading` (the planner's own criterion)?"""
        return self.goal_atoms <= self.bundle.atoms(reading)[0]

    def _believe(self, reading) -> set:
        """The state the planner starts from (uncertain bits read as the problem reads
        them), for choosing offsets; not needed without `refine`."""
        return self.bundle.atoms(reading, guess=True)[0] if self.refine else set()

    def _read(self, scene):
        return self.bundle.read(scene.names, scene.features(), scene.contacts)

    def _plan(self, reading) -> tuple[list[str], tuple[str, str] | None]:
        """(steps, None), or ([], (cause, message)) when the planner found no plan."""
        with self.clock("plan"):
            found = self.bundle.plan(reading, self.goal_reading, self.planner, self.timeout,
                                     self.goal.scene.contacts)
        if found.solved:
            return list(found.plan), None
        return [], (_PLANNER_STATUS.get(found.status, "error"),
                    f"planner {self.planner}: {found.status}: {found.message}".strip())

    def _follow(self, before, after, action) -> beliefs.Named:
        """`after` named by association; an object lost with the prior is looked for once
        more from scratch (no prior) before it counts as lost."""
        seen = beliefs.follow(before, after, action)
        if seen.lost:
            again = beliefs.follow(before, self.agent.backend.perceive(), action)
            if len(again.lost) < len(seen.lost):
                seen = again
        return seen

    def _end(self, final, cause: str, message: str) -> SolveResult:
        """The check on the last perceived scene `final`: success if every goal object is
        within GOAL_TOLERANCE, else the status for `cause`."""
        result = self.result
        truth = {n: s.position for n, s in self.agent.station.object_states().items()}
        result.objects = beliefs.goal_errors(beliefs.positions(self.goal.scene),
                                             beliefs.positions(final), truth)
        errors = [o["error_cm"] for o in result.objects.values()]
        if errors and all(e is not None and e <= GOAL_TOLERANCE * 100 for e in errors) \
                and cause != "perception":
            result.status = "success"
            return result
        if self.goal_reading is not None and set(self.goal.scene.names) <= set(final.names):
            result.symbolic_goal_reached = self._goal_holds(self._read(final))
        if cause == "execution":
            far = {n: o["error_cm"] for n, o in result.objects.items()
                   if o["error_cm"] is not None and o["error_cm"] > GOAL_TOLERANCE * 100}
            message = message or f"objects farther than {GOAL_TOLERANCE * 100:g} cm from " \
                                 f"their goal: {far}"
        result.status = cause if cause in ("no_plan", "timeout", "infeasible", "error") \
            else "failure"
        result.failure_cause, result.message = cause, message
        return result


def solve(start_scene, goal_scene, bundle, planner: str = "fd", timeout: float = 10.0,
          monitor: bool = True, max_replans: int = 2, meshcat=None, record=None,
          backend: str = "arm", refine: bool = True) -> SolveResult:
    """Solves one goal on a new station; `record`: write a Meshcat HTML recording there
    (a `meshcat` is started for it if none is given). seconds["setup"] is the station build."""
    t0 = time.perf_counter()
    if record is not None and meshcat is None:
        from drake_symplan.world.visualization import StartMeshcat

        meshcat = StartMeshcat()
    agent = Agent(backend, meshcat=meshcat)
    setup = time.perf_counter() - t0
    result = agent.solve(start_scene, goal_scene, bundle, planner, timeout, monitor,
                         max_replans, record, refine)
    result.seconds["setup"] = setup
    return result
