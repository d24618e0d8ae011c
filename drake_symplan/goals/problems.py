"""Random problem sets, as in the paper's planning experiment: a random start scene, k random
actions executed by the robot, the scene they leave is the goal.

Each kept problem is a directory `pNNN/` with
- `start.yaml`: the sampled start scene (world/scenes.py format);
- `goal.yaml`: the end state as the *simulator* left it (positions and orientations of the
  settled bodies; tilted objects with `rpy`). It is a world description, not a belief:
  `solve` only puts it on the table and perceives it, and so the goal a planner sees is the
  perceived one;
- `problem.json`: {"k", "seed", "n_objects"} and bookkeeping (the back-end and its
  cameras' sensor model, the actions, how far the farthest object moved). `seed` alone
  regenerates the problem (with the same sensor model): numpy's default_rng(seed) drives
  the scene sampler and the actions.

Actions are chosen over the *perceived* objects (data/exploration.random_action), each
executed on the perceived scene, whose names follow the objects through perception's
association. Only non-trivial goals are kept: some object ends more than 5 cm from where it
was perceived at the start (`is_nontrivial`; the peer counted goals that already held as
solved). A problem is also dropped when an object leaves the table, perception loses an
object, the goal file does not re-render to what was perceived (`goal_unstable`), or the
goal is not a valid scene; `problems.json` counts the reasons.

With `reproducible`, a goal is kept only if the same actions, replayed from the start as
its file reads back (positions rounded to 0.1 mm), bring every object within 5 cm of the
perceived goal again (`replay`): the `oracle` of `eval planning` then reaches every kept
goal. Without it, about one goal in eight 1-3 actions away is chaotic, and nearly half of
those 4-5 away: a box that tumbled or slid lands elsewhere when the start moves by a
tenth of a millimetre, a goal no planner can aim for (docs/planning.md).
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np

from drake_symplan.actions import Action
from drake_symplan.agent import beliefs
from drake_symplan.agent.solve import Agent
from drake_symplan.atomic import write_atomic
from drake_symplan.boxes import GOAL_TOLERANCE
from drake_symplan.data.exploration import left_workspace, random_action
from drake_symplan.goals import compiler, sampling
from drake_symplan.json_files import read_json
from drake_symplan.relations import SpecError, unmet
from drake_symplan.world.scenes import (
    SceneError,
    as_saved,
    sample_scene,
    save_scene,
    scene_from_poses,
)

NONTRIVIAL_DISTANCE = 0.05  # m: a goal is non-trivial if some object moved farther
GOAL_RERENDER_TOLERANCE = 0.02  # m: the goal file, shown and perceived, vs the end state
MAX_INFEASIBLE = 10  # unreachable actions in a row before the attempt is given up
SUMMARY = "problems.json"


def displacement(start: dict[str, np.ndarray], end: dict[str, np.ndarray]) -> float:
    """The largest distance (m) an object of `start` moved to its position in `end`."""
    missing = sorted(set(start) - set(end))
    if missing:
        raise ValueError(f"objects {missing} have no end position")
    return max((float(np.linalg.norm(np.asarray(end[n]) - np.asarray(p)))
                for n, p in start.items()), default=0.0)


def is_nontrivial(start: dict[str, np.ndarray], end: dict[str, np.ndarray],
                  distance: float = NONTRIVIAL_DISTANCE) -> bool:
    """Does some object end more than `distance` from its start position?"""
    return displacement(start, end) > distance


def problem_seed(seed: int, attempt: int) -> int:
    """The seed of attempt `attempt` of a set seeded `seed` (stored in problem.json)."""
    return int(np.random.SeedSequence([seed, attempt]).generate_state(1)[0])


def make_problem(agent, seed: int, n_objects: int, k: int, long_fraction: float = 0.5,
                 reproducible: bool = False, task: str | None = None, start_k: int = 0):
    """(start, goal, info) for one random problem, or the reason it was dropped (a string);
    with `task` (sampling.TASKS) the goal is a structure k actions away, built by design, from
    a scattered scene, or (`start_k`) from two towers that start_k actions build there, any
    goal whose build takes one of the k (a tuple) actions, towers taken apart counted."""
    rng = np.random.default_rng(seed)
    try:
        start = sample_scene(rng, n_objects, long_fraction=long_fraction)
    except SceneError:  # so many boxes that they do not fit apart
        return "start_crowded"
    if task is not None:
        if start_k:
            start = _stacked_start(agent, rng, start, start_k)
            if isinstance(start, str):
                return start
        return _built_problem(agent, rng, start, task, k, reproducible, exact=start_k > 0)
    seen = agent.look(start)
    if seen.lost or seen.extra:
        return "perception_start"
    first = seen.scene
    now, actions = _random_actions(agent, rng, first, k)
    if isinstance(now, str):
        return now
    made = settle_goal(agent, start, first, now, actions, reproducible)
    return made.split(":", 1)[0] if isinstance(made, str) else (start, *made)


def _random_actions(agent, rng, now, k: int):
    """(scene perceived after `k` random feasible actions from the perceived `now`, their
    texts), or why not (a string, with None)."""
    actions, infeasible = [], 0
    while len(actions) < k:
        action = random_action(rng, now.names)
        after = act(agent, now, action)
        if after == "infeasible":
            infeasible += 1
            if infeasible >= MAX_INFEASIBLE:
                return "too_many_infeasible", None
            continue
        if isinstance(after, str):
            return after, None
        infeasible = 0
        actions.append(str(action))
        now = after
    return now, actions


def _stacked_start(agent, rng, start, start_k: int):
    """The start scene (as its file reads back) with two towers that `start_k` designed
    actions build from the scattered `start` (what a goal then takes apart), or why not
    (a string, prefixed start_)."""
    structures = sampling.sample_structures(rng, start.object_states(), "towers", start_k)
    if isinstance(structures, str):
        return f"start_{structures}"
    try:
        made = build_goal(agent, start, structures, reproducible=False)
    except SpecError:
        return "start_spec_refused"
    if isinstance(made, str):
        return "start_" + made.split(" ", 1)[0].removesuffix(":")
    return made[0]


def _perceived_objects(agent, start):
    """The objects perceived in `start` put on the table (what build_goal checks the
    structures against), or why not (a string)."""
    seen = agent.look(start)
    return "perception_start" if seen.lost or seen.extra else seen.scene.object_states()


def _built_problem(agent, rng, start, task: str, k: int, reproducible: bool,
                   exact: bool = False):
    """(start, goal, info) of a random goal of `task` built from `start`, or why not; with
    `exact`, any goal whose build takes one of the k (a tuple) actions, boxes set down out
    of the way counted, else a structure of k actions."""
    if exact:  # parks depend on the stacks, sampled on what build_goal will perceive
        objects = _perceived_objects(agent, start)
        if isinstance(objects, str):
            return objects
        structures = sampling.sample_goal(rng, objects, task, k)
    else:
        structures = sampling.sample_structures(rng, start.object_states(), task, k)
    if isinstance(structures, str):
        return structures
    try:
        made = build_goal(agent, start, structures, reproducible)
    except SpecError:
        return "spec_refused"
    if isinstance(made, str):
        return made.split(" ", 1)[0].removesuffix(":")  # its class (not_built, ...), counted
    goal, info = made
    return start, goal, {"spec": [s.text() for s in structures], **info}


def settle_goal(agent, start, first, now, actions: list[str], reproducible: bool):
    """(goal, info) of the scene `actions` left (`now` perceived, `first` the start
    perceived), or why it is no goal: trivial, invalid or unstable as a file, or (with
    `reproducible`) not reached again when the actions are replayed from the saved start."""
    end = beliefs.positions(now)
    moved = displacement(beliefs.positions(first), end)
    if moved <= NONTRIVIAL_DISTANCE:
        return "trivial"
    try:  # as its file will read back
        goal = as_saved(scene_from_poses(*agent.robot.ground_truth_poses()))
    except SceneError as e:
        return f"goal_invalid: {e}"
    shown = agent.look(goal)
    if shown.lost or displacement(end, beliefs.positions(shown.scene)) > GOAL_RERENDER_TOLERANCE:
        return "goal_unstable"
    if reproducible:
        try:
            again = replay(agent, as_saved(start), [Action.from_text(a) for a in actions])
        except SceneError:
            return "start_invalid"
        if isinstance(again, str) or displacement(
                beliefs.positions(shown.scene), beliefs.positions(again)) > GOAL_TOLERANCE:
            return "not_reproducible"
    return goal, {"actions": actions, "moved_cm": round(moved * 100, 2)}


def build_goal(agent, start, structures: list, reproducible: bool = True):
    """(goal, info) of the written goal `structures` (relations.py, compiled by goals/compiler.py) built by the
    robot from the `start` scene, or why not (a string); SpecError, before anything
    moves, when the start cannot give them. The author checks the built scene against the
    structures on the simulator's poses (the goal's author may; a planner may not)."""
    seen = agent.look(start)
    if seen.lost or seen.extra:
        return "perception_start"
    objects = seen.scene.object_states()
    now, done = seen.scene, []
    for action in compiler.check(structures, objects):
        now = act(agent, now, action)
        if isinstance(now, str):
            return f"{now} at {action}"
        done.append(str(action))
    wrong = unmet(structures, agent.robot.ground_truth_states())
    if wrong:
        return f"not_built: {wrong[0]}"
    return settle_goal(agent, start, seen.scene, now, done, reproducible)


def act(agent, now, action: Action):
    """Executes `action` on the perceived scene `now`: the scene perceived after it (names
    followed by association), or why not ("infeasible", "sim_failure", "left_table",
    "perception_lost")."""
    execution = agent.robot.execute(action, now, lift=False)
    if execution.status != "ok":
        return "infeasible" if execution.status == "infeasible" else "sim_failure"
    seen = beliefs.follow(now, execution.after, action)
    if left_workspace(agent.robot.ground_truth_states()):
        return "left_table"
    if seen.lost:
        return "perception_lost"
    return seen.scene


def replay(agent, start, actions: list[Action]):
    """The scene perceived after `actions`, executed one by one from the `start` scene
    put on the table, or why one failed (`act`)."""
    now = agent.look(start).scene
    for action in actions:
        now = act(agent, now, action)
        if isinstance(now, str):
            return now
    return now


def make_problems(out_dir, n_objects: int, k, count: int, seed: int, backend: str = "arm",
                  max_attempts: int | None = None, agent=None, progress=None,
                  reproducible: bool = False, camera_noise: str = "none",
                  task: str | None = None, start_k: int = 0,
                  long_fraction: float = 0.5) -> dict:
    """Writes `count` non-trivial problems with `n_objects` objects to `out_dir`/pNNN.

    `k`: actions per problem, an int or a list taken in turn; `start_k` (with `task`): the
    start is two towers built in that many actions (0: scattered boxes), and then any of
    the k is kept (what a goal's build takes depends on the towers); `camera_noise`: the sensor
    model of the cameras that perceive (that of `agent` when one is given). A re-run with
    the same arguments resumes (existing problems are kept; attempts go on from the last
    one). Returns the summary written to `out_dir`/problems.json."""
    ks = [int(k)] if np.isscalar(k) else [int(v) for v in k]
    if not ks or min(ks) < 1:
        raise ValueError(f"k must be at least 1, got {k}")
    if count < 1:
        raise ValueError(f"count must be at least 1, got {count}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / SUMMARY
    summary = read_json(summary_path) if summary_path.is_file() else {}
    settings = {"n_objects": n_objects, "k": ks, "seed": seed, "backend": backend,
                "camera_noise": camera_noise}
    # each only when it is not the default, so that sets made before still resume
    settings.update({key: value for key, value, default in (
        ("reproducible", reproducible, False), ("task", task, None), ("start_k", start_k, 0),
        ("long_fraction", long_fraction, 0.5)) if value != default})
    stored = summary.get("settings")
    if isinstance(stored, dict):  # sets made before the sensor model was recorded: none
        stored = {"camera_noise": "none", **stored}
    if summary and stored != settings:
        raise ValueError(f"{out} holds problems made with {summary.get('settings')}, "
                         f"not {settings}")
    kept = len(list(out.glob("p*/problem.json")))
    attempt = summary.get("attempts", 0)
    rejected = Counter(summary.get("rejected", {}))
    max_attempts = max_attempts if max_attempts is not None else 20 * count
    if agent is None and kept < count:
        agent = Agent(backend, camera_noise=camera_noise)
    while kept < count and attempt < max_attempts:
        pseed = problem_seed(seed, attempt)
        attempt += 1
        made = make_problem(agent, pseed, n_objects,
                            tuple(ks) if start_k else ks[kept % len(ks)],
                            long_fraction=long_fraction,
                            reproducible=reproducible, task=task, start_k=start_k)
        if isinstance(made, str):
            rejected[made] += 1
        else:
            _write_problem(out / f"p{kept:03d}", made, {
                "seed": pseed, "n_objects": n_objects, "backend": backend,
                "camera_noise": camera_noise, "attempt": attempt - 1})
            kept += 1
        summary = {"settings": settings, "kept": kept, "attempts": attempt,
                   "rejected": dict(sorted(rejected.items()))}
        write_atomic(summary_path, json.dumps(summary, indent=1) + "\n")
        if progress:
            progress(summary)
    return summary


def _write_problem(folder: Path, made: tuple, record: dict) -> None:
    """A problem's folder: start.yaml, goal.yaml and problem.json (`record`, its k the
    actions that made it, and what else the maker told: `made`'s info)."""
    start, goal, info = made
    folder.mkdir(exist_ok=True)
    save_scene(start, folder / "start.yaml")
    save_scene(goal, folder / "goal.yaml")
    record = {"k": len(info["actions"]), **record, **info}
    write_atomic(folder / "problem.json", json.dumps(record, indent=1) + "\n")


def load_problems(problems_dir) -> list[dict]:
    """Every problem under `problems_dir` (any depth): its problem.json plus "dir"."""
    root = Path(problems_dir)
    if not root.is_dir():
        raise FileNotFoundError(f"no problems directory {root}")
    found = []
    for path in sorted(root.glob("**/problem.json")):
        record = read_json(path)
        missing = [k for k in ("k", "n_objects") if not isinstance(record.get(k), int)]
        if missing:
            raise ValueError(f"{path}: no {' or '.join(missing)} (an integer each)")
        record["dir"] = str(path.parent)
        found.append(record)
    if not found:
        raise ValueError(f"no problems (*/problem.json) under {root}")
    return found


def recorded_actions(problem: dict) -> list[Action]:
    """The actions that made `problem` (a load_problems entry), which the oracle replays;
    ValueError naming its problem.json when it records none (or not as actions)."""
    where = Path(problem["dir"]) / "problem.json"
    actions = problem.get("actions")
    if not isinstance(actions, list) or not all(isinstance(a, str) for a in actions):
        raise ValueError(f"{where} records no actions (an \"actions\" list), which the "
                         "oracle replays; make the set with `symplan problems make`")
    try:
        return [Action.from_text(a) for a in actions]
    except ValueError as e:
        raise ValueError(f"{where}: {e}") from e
