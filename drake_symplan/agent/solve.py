"""Solving one goal in full physics: perceive, read symbols, plan, execute, monitor, check.

`solve(start_scene, goal_scene, abstraction, config)` builds one robot (cameras and the arm or
the hand, robot/backends.py) and runs `Agent.solve` on it; `Agent` keeps the robot for many
solves (the evaluation). How it solves is a `SolveConfig` (agent/config.py); what it knows
is an `Abstraction` of a model bundle (abstraction/abstraction.py).

1. The goal scene is put on the table and perceived; the file only names the boxes
   (agent/beliefs.py). The start scene likewise, then the robot stays in it.
2. The bundle reads both scenes' symbols and writes the problem: the start's certain atoms,
   the goal's atoms (abstraction.goal_atoms; of a goal of relations, those of the pairs
   it names). The planning mode `config.planning` (agent/planning_modes.py) plans on
   symbols, checked with the learned continuous model, or by that model's search alone,
   from abstraction.Observations (the scene, its symbols, its boxes), each made once.
3. Each step is executed by the back-end on the perceived objects (the arm: IK-planned
   pick/place in full physics); the scene perceived after it keeps the names through
   perception's association. A plan on symbols is completed as it runs (with
   `config.refine`, the CLI's default; `--no-refine` turns it off): before a step runs,
   its offsets are chosen among its offset variants by the geometric scorer, landing the
   source nearer its goal (abstraction/offsets.py; bilevel planning chose a plan's
   offsets with the same chooser and the learned model's scorer), and a box that the
   symbols leave off its goal position on the table may be put down beside another
   first, a `Reposition` step (agent/completion.py, agent/reposition.py).
4. Monitoring: after each step the bundle compares the perceived symbols with what the
   step's operator predicted (a plan checked in continuous space: the perceived positions
   with the predicted ones); where the rest of the plan no longer reaches the goal from
   what is seen, the agent replans from the perceived state (if that replan fails, the
   current plan runs on).
   When the plan has run out, the goal must be seen (the mode's goal_seen), or it replans
   too; at most `max_replans` times. Without monitoring the first plan runs open loop.
5. The check, on the scene perceived after the last step: every object within
   GOAL_TOLERANCE (5 cm) of its perceived goal position (boxes.goal_reached), or, for a
   goal of relations, the relations held wherever they stand (relations.unmet). The
   simulator's view is reported beside it, for evaluation only: no decision reads it.
"""

from __future__ import annotations

import time

from drake_symplan.abstraction.abstraction import Abstraction, Observation, Plan
from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.relation_goal import relation_goal
from drake_symplan.agent import beliefs
from drake_symplan.agent.completion import Completion, Planned
from drake_symplan.agent.config import DEFAULT_SOLVE, SolveConfig
from drake_symplan.agent.planning_modes import make_planner
from drake_symplan.agent.reposition import (
    reposition_step,
)
from drake_symplan.agent.result import PhaseClock, SolveResult
from drake_symplan.agent.verdict import verdict
from drake_symplan.boxes import GOAL_TOLERANCE
from drake_symplan.planning.nodes import EXPANDED
from drake_symplan.relations import riders
from drake_symplan.robot.backends import Backend, Execution, PerceptionFailure, make_backend
from drake_symplan.skills.geometry import set_down_unseen
from drake_symplan.symbolic.structs import PlanStep
from drake_symplan.world.visualization import StartMeshcat

# Planner statuses -> the agent's status (= failure cause) when the plan cannot be had.
PLANNER_STATUS = {"unsolvable": "no_plan", "timeout": "timeout", "error": "error"}
# Plans made at subgoals per object at most: a tower of n boxes is n - 1 (unstacking: ~2x).
SUBGOALS_PER_OBJECT = 3
# Steps the arm refused (nothing moved) planned around per object at most, apart from the
# replans on a departure: a refusal costs a plan, not a step.
REFUSALS_PER_OBJECT = 2


class Agent:
    """A robot with cameras that solves goals. `robot`: "arm" (the UR10 in full physics),
    "hand" (the fast hand), or a robot.backends.Backend to use as it is; `meshcat` shows
    a robot built here live, `camera_noise` is its cameras' sensor model (--camera-noise)."""

    def __init__(self, robot: str | Backend = "arm", meshcat=None, camera_noise: str = "none"):
        self.robot = (make_backend(robot, meshcat=meshcat, camera_noise=camera_noise)
                      if isinstance(robot, str) else robot)

    def look(self, scene, clock: PhaseClock | None = None, views=None,
             named=beliefs.name_by_file) -> beliefs.Named:
        """Puts `scene` on the table (robot home, physics settled) and perceives it (or
        `views`, frames on disk), the boxes `named` after its objects; on `clock`."""
        self.robot.reset(scene)
        with (clock or PhaseClock(self.robot))("perceive"):
            return self.see(scene, views, named)

    def see(self, scene, views=None, named=beliefs.name_by_file) -> beliefs.Named:
        """Perceives the table now (or `views`), the boxes `named` after `scene`'s objects."""
        return named(self.robot.perceive(**({} if views is None else {"views": views})), scene)

    def solve(self, start_scene, goal_scene, abstraction: Abstraction,
              config: SolveConfig = DEFAULT_SOLVE, record=None, on_plan=None,
              given=None, relations=(), frames=beliefs.NO_FRAMES) -> SolveResult:
        """Solves `goal_scene` from `start_scene` (world.scenes.Scene); `record`: an HTML
        file for the Meshcat recording of the execution (with a Meshcat); `on_plan(plan,
        start, goal)` is told the first plan (abstraction.Plan, solved or not) and the
        perceived scenes (beliefs.Named) before anything moves; `given`: the actions the
        oracle replays (a mode that needs_recorded_actions); `relations`: a goal of
        relations (relations.Relation), `goal_scene` an example of them, judged by the
        relations alone wherever they stand (else: every box within 5 cm of the scene);
        `frames`: perceptions from frames on disk (beliefs.Frames; a goal's: no goal_scene)."""
        if frames.goal is None:
            beliefs.check_scene_pair(start_scene, goal_scene)
        clock = PhaseClock(self.robot)
        t0 = time.perf_counter()
        run = _Run(self, abstraction, clock, config, on_plan, given, tuple(relations))
        try:
            goal = self.look(goal_scene, clock) if frames.goal is None else \
                self.look(start_scene, clock, frames.goal, beliefs.name_by_type)
            with self.robot.recording(record):  # from the start scene on
                start = self.look(start_scene, clock, frames.start)
                result = run.go(start, goal)
        except PerceptionFailure as e:  # perception raised: the loop cannot go on
            result = run.result
            result.status, result.failure_cause, result.message = "failure", "perception", str(e)
        result.seconds = dict(clock.seconds, total=time.perf_counter() - t0)
        return result


class _Stop(Exception):
    """Ends a solve: the last perceived scene, the failure cause, a message."""

    def __init__(self, scene, cause: str, message: str = ""):
        super().__init__(message)
        self.scene, self.cause, self.message = scene, cause, message


class _Run(Completion):
    """The loop of one solve (module docstring): `go` plans, then executes the plan step
    by step (`_execute`), monitoring each (`_monitor`) and the end (`_goal_seen`). `scene`
    is the scene perceived last, `now` the Observation last read (they differ open loop,
    where nothing is read after the start)."""

    def __init__(self, agent: Agent, abstraction: Abstraction, clock: PhaseClock,
                 config: SolveConfig, on_plan=None, given=None, relations: tuple = ()):
        self.agent, self.abs, self.clock, self.config = agent, abstraction, clock, config
        self.relations = relations
        self.on_plan = on_plan
        self.planner = make_planner(abstraction, config, given)
        self.result = SolveResult("failure")
        self.goal_scene = None
        self.goal: Observation | None = None
        self.goal_atoms = frozenset()
        self.scene = None
        self.now: Observation | None = None
        self.believed = frozenset()
        self.todo: list[Planned] = []
        self.repositions = 0
        self.refused: set = set()  # actions the arm refused in the scene as it stands
        self.unblocked: set[str] = set()  # steps _unblock looked at

    @property
    def rest(self) -> list[PlanStep]:
        """The steps still to run."""
        return [p.step for p in self.todo]

    def go(self, start: beliefs.Named, goal: beliefs.Named) -> SolveResult:
        self.goal_scene = goal.scene
        if goal.lost or start.lost:
            lost = [f"{n} (goal)" for n in goal.lost] + [f"{n} (start)" for n in start.lost]
            return self._end(start.scene, "perception", f"perception lost {', '.join(lost)}")
        try:
            with self.clock("symbols"):
                self.goal = self.abs.observe(self.goal_scene)
                if self.relations:
                    self.goal = relation_goal(self.goal, self.relations)
                self.goal_atoms = self.abs.goal_atoms(self.goal.reading)
                self._perceived(start.scene)
            first = self._search()
            if self.on_plan is not None:
                self.on_plan(first, start, goal)
            self.result.candidates, self.result.level = first.candidates, first.level
            self.todo = self._steps(first)
            self.result.plan = self.rest
            while True:
                while self._next():
                    self._execute(self.todo.pop(0))
                if not self._goal_seen():
                    break
        except _Stop as stop:
            return self._end(stop.scene, stop.cause, stop.message)
        return self._end(self.scene, "execution", "")

    # --- plan -----------------------------------------------------------------------

    def _search(self) -> Plan:
        """Plans from the scene perceived now, its search nodes counted in the result's."""
        before = EXPANDED.total
        try:
            with self.clock("plan"):
                return self.planner.plan(self.now, self.goal)
        finally:
            self.result.nodes += EXPANDED.total - before

    def _steps(self, found: Plan) -> list[Planned]:
        """The steps of a plan found; _Stop when the planner found none."""
        if not found.solved:
            cause = PLANNER_STATUS.get(found.status, "error")
            raise _Stop(self.scene, cause, f"planner {self.config.planner}: {found.status}: "
                                           f"{found.message}".strip())
        predicted = list(found.predicted)
        return [Planned(s, predicted[i] if i < len(predicted) else None)
                for i, s in enumerate(found.steps)]

    def _replan(self, scheduled: bool = False) -> list[Planned]:
        """A new plan from the scene perceived now: `scheduled` where the last plan
        ended at its subgoal (counted apart from the replans on a departure)."""
        if scheduled:
            self.result.subgoals += 1
        else:
            self.result.replans += 1
        return self._steps(self._search())

    # --- execute --------------------------------------------------------------------

    def _next(self) -> bool:
        """Is there a step to run? Completing a plan on symbols, a repositioning goes first
        where a box the rest of the plan leaves alone is off its goal spot."""
        if self._completes() and self.todo:
            self._unblock()
        if self._completes() and self._repositions_left() and not self.relations:
            extra = reposition_step(self.rest, self.scene, self.goal_scene, GOAL_TOLERANCE)
            if extra is not None:
                self.todo.insert(0, Planned(extra))
                self.repositions += 1
        return bool(self.todo)

    def _execute(self, planned: Planned) -> None:
        """Runs a step with the robot (its offsets chosen first), perceives the result. A
        step that would set its source down out of the cameras' view is refused as the arm
        refuses one (skills/geometry.set_down_unseen): the box would be lost from view."""
        step = self._offsets(planned.step)
        objects = self.scene.object_states()
        load = riders(step.action.source, objects)
        if set_down_unseen(step.action, objects):
            execution = Execution("infeasible", message=f"{step.action.source} would be set "
                                  "down out of the cameras' view", at="release")
        else:
            with self.clock("execute"):
                execution = self.agent.robot.execute(step.action, self.scene, lift=False)
        if execution.status == "infeasible":
            self.refused.add(step.action)
            self._refused(step, f"{step}: {execution.message}", execution.obstacles,
                          execution.at)
            return
        self.refused.clear()
        self.result.executed.append(step)
        if execution.status != "ok":
            raise _Stop(self.scene, "error", f"{step}: {execution.message}")
        seen = self._follow(self.scene, execution.after, step.action)
        if seen.lost:
            raise _Stop(seen.scene, "perception",
                        f"after {step} perception lost {', '.join(seen.lost)}")
        self.scene = seen.scene
        if load and not set(load) <= set(riders(step.action.source,
                                                self.scene.object_states())):
            self.result.dropped_riders += 1
        if self.config.monitor:
            self._monitor(step, planned.predicted)
        else:  # open loop: the state is what the step predicts
            self.believed = step.apply(self.believed)

    def _follow(self, before, after, action) -> beliefs.Named:
        """`after` named by association; an object lost with the prior is looked for once
        more from scratch (no prior) before it counts as lost."""
        seen = beliefs.follow(before, after, action)
        if seen.lost:
            again = beliefs.follow(before, self.agent.robot.perceive(), action)
            if len(again.lost) < len(seen.lost):
                seen = again
        return seen

    # --- monitor --------------------------------------------------------------------

    def _perceived(self, scene) -> None:
        self.scene = scene
        self.now = self.abs.observe(scene)
        self.believed = self.abs.believed(self.now.reading)

    def _monitor(self, step: PlanStep, predicted: Boxes | None) -> None:
        """Reads the symbols now; if the scene departs from the step's prediction
        (planning_modes.PlanningMode.departs), replans."""
        with self.clock("symbols"):
            before = self.now
            self._perceived(self.scene)
            self.planner.observed(step, predicted, before, self.now)
            wrong = self.planner.departs(step, predicted, self.now, self.rest,
                                         self.believed, self.goal_atoms, self.goal)
        if wrong and self.result.replans < self.config.max_replans:
            try:
                self.todo = self._replan()
            except _Stop:
                if not self.todo:
                    raise
                # The planner found nothing from here (timeout, no plan): the current
                # plan runs on, as it would open loop.

    def _refused(self, step: PlanStep, message: str, obstacles: tuple[str, ...] = (),
                 at: str = "") -> None:
        """The arm could not run `step` (nothing moved; `obstacles`: the boxes in its way,
        where it knows them; `at`: the side it refused at, "grasp" or "release"):
        monitored, with refusals left (REFUSALS_PER_OBJECT), the planner is told and plans
        again from the same scene; else the solve stops."""
        limit = REFUSALS_PER_OBJECT * len(self.scene.names)
        if not (self.config.monitor and self.result.refusals < limit):
            self.result.executed.append(step)
            raise _Stop(self.scene, "infeasible", message)
        self.result.refusals += 1
        clear = self._clearing(step, obstacles)
        if clear is not None:  # what stands in the way is set aside, and the step tried again
            self.todo = [Planned(clear), Planned(step), *self.todo]
            return
        where = self.now.boxes.where()
        self.planner.refused(step, {n: where[n] for n in obstacles if n in where}, at)
        try:
            self.todo = self._steps(self._search())
        except _Stop:
            self.result.executed.append(step)
            raise _Stop(self.scene, "infeasible", message) from None

    def _goal_seen(self) -> bool:
        """The plan has run out. The monitor checks that the goal's atoms are seen too (a
        step can pass its own check and still disturb another object): True when it
        replanned and there are steps to run. A plan that ended at its subgoal is
        followed by the next (at most SUBGOALS_PER_OBJECT per object, apart from
        `max_replans`)."""
        if not self.config.monitor:
            return False
        scheduled = self.planner.subgoal_plan and \
            self.result.subgoals < SUBGOALS_PER_OBJECT * len(self.scene.names)
        if not scheduled and self.result.replans >= self.config.max_replans:
            return False
        with self.clock("symbols"):
            reached = self.planner.goal_seen(self.now, self.goal_atoms, self.goal)
        if reached:
            return False
        self.todo = self._replan(scheduled)
        return bool(self.todo)

    def _end(self, final, cause: str, message: str) -> SolveResult:
        """The check on the last perceived scene `final` (module docstring, 5.), else the
        status for `cause` (agent/verdict.py)."""
        goal_atoms = self.goal_atoms if self.goal is not None else None
        return verdict(self.result, self.agent.robot.ground_truth_states(), self.goal_scene,
                       final, self.relations, self.abs, goal_atoms, cause, message)


def solve(start_scene, goal_scene, abstraction: Abstraction,
          config: SolveConfig = DEFAULT_SOLVE, meshcat=None, record=None,
          robot: str = "arm", camera_noise: str = "none", **options) -> SolveResult:
    """Solves one goal with a new robot (its cameras' sensor model `camera_noise`);
    `record`: write a Meshcat HTML recording there (a `meshcat` is started for it if none
    is given); `options`: Agent.solve's (relations, frames). seconds["setup"]: the station build."""
    t0 = time.perf_counter()
    if record is not None and meshcat is None:
        meshcat = StartMeshcat()
    agent = Agent(robot, meshcat=meshcat, camera_noise=camera_noise)
    setup = time.perf_counter() - t0
    result = agent.solve(start_scene, goal_scene, abstraction, config, record, **options)
    result.seconds["setup"] = setup
    return result
