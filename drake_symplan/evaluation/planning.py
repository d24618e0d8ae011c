"""The planning evaluation (paper IV-C and its planning figure): model bundles solve the
same problem set, with execution monitoring and without it (open-loop, as the paper), under one `SolveConfig`.

`evaluate_planning` runs every (run, monitoring, problem) with one station (or on local
worker processes or Ray worker actors, a station each) and returns per
run and monitoring mode: the success rate overall, by object count and by k; the planning
time; the length of the first plan against k; the failure causes with counts, execution
failures split by whether the goal's atoms were seen at the end (then the symbols could not
tell the goal positions apart) or not (the plan missed them); and beside
the perceived check, the simulator's (`success_true`: every object's simulated final
position within 5 cm of its position in goal.yaml; evaluation only). `records` holds one
line per solve; with `records_path` each is appended to a JSON-lines file as it finishes,
and a re-run skips the solves already there (resume).
"""

from __future__ import annotations

import json
import statistics
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from drake_symplan.abstraction.abstraction import Abstraction
from drake_symplan.agent.config import DEFAULT_SOLVE, SolveConfig
from drake_symplan.agent.planning_modes import PLANNING_MODES
from drake_symplan.agent.solve import Agent
from drake_symplan.atomic import save_figure
from drake_symplan.boxes import goal_reached
from drake_symplan.cluster import cluster_cpus, ray_session, run_jobs, run_jobs_local
from drake_symplan.evaluation.report import failures
from drake_symplan.goals.problems import load_problems, recorded_actions
from drake_symplan.json_files import parse_json, type_name
from drake_symplan.planning.nodes import median_nodes
from drake_symplan.relations import parse
from drake_symplan.symbolic.bundle import ModelBundle
from drake_symplan.world.scenes import load_scene

MODES = {True: "monitor", False: "open_loop"}
# What every record holds (solve_job) and `summarise` reads; "level" and
# "symbolic_goal_reached" came later and may be absent.
RECORD_KEYS = ("run", "problem", "monitor", "status", "failure_cause", "success_true",
               "n_objects", "k", "plan_length", "replans", "seconds", "error_cm")
# The targets are set on these bands of (object count, k).
BANDS = {"2-4 objects, k 1-3": ((2, 3, 4), (1, 2, 3)), "2-4 objects, k 4-5": ((2, 3, 4), (4, 5)),
         "8 objects, k 1-3": ((8,), (1, 2, 3))}


def run_label(run) -> str:
    """A run directory's label in the results: its last two path parts."""
    parts = Path(run).resolve().parts
    return "/".join(parts[-2:]) if len(parts) > 1 else str(run)


def true_success(objects: dict, goal_scene) -> bool:
    """The simulator's check: every final_true within GOAL_TOLERANCE of goal.yaml."""
    finals = {o.name: objects.get(o.name, {}).get("final_true") for o in goal_scene.objects}
    return goal_reached({o.name: None if finals[o.name] is None else float(
        np.linalg.norm(np.subtract(finals[o.name], o.position))) for o in goal_scene.objects})


def solve_job(agent: Agent, label: str, abstraction: Abstraction, problem: dict,
              config: SolveConfig, tick=None) -> dict:
    """One evaluation record: run `label`'s abstraction on `problem` (a load_problems
    entry, with its scenes under "scenes" when the driver read them for a Ray worker)."""
    folder = Path(problem["dir"])
    start, goal = problem.get("scenes") or (load_scene(folder / "start.yaml"),
                                            load_scene(folder / "goal.yaml"))
    given = None
    if PLANNING_MODES[config.planning].needs_recorded_actions:  # e.g. the oracle's replay
        given = recorded_actions(problem)
    relations = parse(problem["spec"]) if problem.get("spec") and \
        config.goal_check == "relations" else []
    result = agent.solve(start, goal, abstraction, config, given=given, relations=relations)
    return {
        "run": label, "problem": str(folder), "n_objects": problem["n_objects"],
        "k": problem["k"], "monitor": config.monitor, "status": result.status,
        "failure_cause": result.failure_cause, "message": result.message,
        "goal": "relations" if relations else "scene",
        "spec": [r.text() for r in relations],
        "success_true": not result.unmet_true if relations else true_success(result.objects,
                                                                              goal),
        "symbolic_goal_reached": result.symbolic_goal_reached, "plan_length": len(result.plan),
        "level": result.level,
        "executed": len(result.executed), "replans": result.replans,
        "dropped_riders": result.dropped_riders, "subgoals": result.subgoals,
        "refusals": result.refusals, "nodes": result.nodes,
        "seconds": {k: round(v, 4) for k, v in result.seconds.items()},
        "error_cm": {n: o["error_cm"] for n, o in result.objects.items()},
    }


def evaluate_planning(runs: list, problems_dir, config: SolveConfig = DEFAULT_SOLVE,
                      robot: str = "arm", monitor=(True, False), limit: int | None = None,
                      records_path=None, agent=None, load=None, progress=None,
                      ray_address: str | None = None, workers: int = 1, warn=None,
                      camera_noise: str = "none") -> dict:
    """Solves every problem under `problems_dir` with each run's bundle (`runs`: bundle
    directories) under `config`, in each monitoring mode of `monitor`; returns
    {"settings", "runs": {label: {mode: summary}}, "records": [...]}, and with Ray
    "solves_by_node": {node id: solves this call ran there}. With `ray_address`
    ("" for Ray on this machine) the solves are spread over Ray worker actors, one agent
    (robot) each, one per CPU of the cluster (drake_symplan/cluster.py); with `workers` > 1
    on that many local processes, an agent each. `load(run)` gives a run's Abstraction
    (default: of ModelBundle.load(run)); `warn(text)` is told of a records file's cut last
    line (default: a line on stderr). `camera_noise`: the sensor model of the cameras of
    the agents built here (a given `agent` has its own), in the settings and each record;
    a records file of solves under another is refused."""
    if not runs:
        raise ValueError("give at least one run (a model bundle directory)")
    problems = load_problems(problems_dir)[:limit]
    # Bad runs fail up front, then bad scene files (naming the file).
    load = load or (lambda run: Abstraction(ModelBundle.load(run)))
    abstractions = {run_label(run): load(run) for run in runs}
    _check_problems(problems, config)
    done, records = _resume(records_path, warn)
    other = {r.get("camera_noise", "none") for r in records} - {camera_noise}
    if other:
        raise ValueError(f"{records_path} holds solves with camera noise {sorted(other)}, "
                         f"not {camera_noise!r}; give another records file")
    if records_path is not None:
        Path(records_path).parent.mkdir(parents=True, exist_ok=True)
    # Monitoring mode by mode, run by run: an unfinished evaluation has whole runs of the
    # first mode (the headline) before any of the second.
    todo = [(label, config.replace(monitor=bool(mode)), problem) for mode in monitor
            for label in abstractions for problem in problems
            if (label, bool(mode), str(Path(problem["dir"]))) not in done]

    def finish(record: dict) -> None:
        record["camera_noise"] = camera_noise
        records.append(record)
        if records_path is not None:
            with open(records_path, "a") as f:
                f.write(json.dumps(record) + "\n")
        if progress:
            progress(record)

    engine = (ray_address, workers, agent)
    solves_by_node = _solve_all(todo, (robot, camera_noise), abstractions, engine, finish)
    order = {(label, bool(mode), str(Path(p["dir"]))): i for i, (label, mode, p) in enumerate(
        (label, mode, p) for label in abstractions for mode in monitor for p in problems)}
    records = sorted((r for r in records if (r["run"], r["monitor"], r["problem"]) in order),
                     key=lambda r: order[(r["run"], r["monitor"], r["problem"])])
    out = {"settings": {"problems_dir": str(problems_dir), "problems": len(problems),
                        "backend": robot, "camera_noise": camera_noise,
                        **config.to_dict()},
           "runs": summarise(records), "records": records}
    if solves_by_node is not None:  # Ray: the solves each node's workers ran this time
        out["solves_by_node"] = solves_by_node
    return out


def _check_problems(problems: list[dict], config: SolveConfig) -> None:
    """Bad scene files (naming the file), and problems without the recorded actions a
    mode replays, fail before anything is solved."""
    for problem in problems:
        for name in ("start.yaml", "goal.yaml"):
            load_scene(Path(problem["dir"]) / name)
        if PLANNING_MODES[config.planning].needs_recorded_actions:
            recorded_actions(problem)


def _solve_all(todo: list, station: tuple, abstractions: dict, engine: tuple,
               finish) -> dict | None:
    """Solves `todo`, each record to `finish`, with agents of `station` (robot, camera
    noise) where `engine` (ray_address, workers, agent) says: on Ray (then {node id:
    solves}), local worker processes, or here."""
    ray_address, workers, agent = engine
    if ray_address is not None:
        with ray_session(ray_address) as ray:
            if todo:
                return run_jobs(
                    ray, _worker_state, (station, abstractions), _solve_in_worker, _jobs(todo),
                    min(cluster_cpus(ray), len(todo)),
                    lambda i, record: finish(record)).jobs_by_node
        return None
    if workers > 1 and todo:
        run_jobs_local(_worker_state, (station, abstractions), _solve_in_worker, _jobs(todo),
                       min(workers, len(todo)), lambda i, record: finish(record))
    elif todo:
        agent = agent or _agent(station)
        for label, mode_config, problem in todo:
            finish(solve_job(agent, label, abstractions[label], problem, mode_config))
    return None


def _agent(station: tuple) -> Agent:
    robot, camera_noise = station
    return Agent(robot, camera_noise=camera_noise)


def _worker_state(station: tuple, abstractions: dict) -> tuple:
    """A worker's state: its own agent of `station` (robot, camera noise) and every run's
    abstraction, sent once."""
    return _agent(station), abstractions


def _solve_in_worker(state: tuple, label: str, problem: dict, config: SolveConfig,
                     tick=None) -> dict:
    agent, abstractions = state
    return solve_job(agent, label, abstractions[label], problem, config)


def _jobs(todo: list) -> list[tuple]:
    """The worker jobs of `todo`, the scenes read here so that workers need no files."""
    jobs = []
    for i, (label, config, problem) in enumerate(todo):
        folder = Path(problem["dir"])
        scenes = (load_scene(folder / "start.yaml"), load_scene(folder / "goal.yaml"))
        jobs.append((i, label, {**problem, "scenes": scenes}, config))
    return jobs


def read_records(records_path) -> list[dict]:
    """The records of a JSON-lines file (none if there is no such file)."""
    if records_path is None or not Path(records_path).is_file():
        return []
    return parse_records(Path(records_path).read_text(), records_path)


def parse_records(text: str, path) -> list[dict]:
    """The records in the JSON lines `text` of the file `path`; ValueError naming the file
    and line of one that is not a record."""
    records = []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        where = f"{path}, line {n}"
        record = parse_json(line, where, expect=object)
        if not isinstance(record, dict):
            raise ValueError(f"{where}: not an evaluation record ({type_name(record)}, not "
                             "an object)")
        missing = [k for k in RECORD_KEYS if k not in record]
        if missing:
            raise ValueError(f"{where}: not an evaluation record (it lacks {missing})")
        if not isinstance(record["seconds"], dict) or "plan" not in record["seconds"] \
                or not isinstance(record["error_cm"], dict):
            raise ValueError(f"{where}: not an evaluation record (its seconds or error_cm "
                             "are not what a solve records)")
        records.append(record)
    return records


def _resume(records_path, warn=None) -> tuple[set, list[dict]]:
    """The solves done so far. A last line cut short (the run was killed while writing
    it) is dropped from the file, so that the next record starts a line of its own, and
    `warn` is told; a line that is not a record is bad input (the file left as it is)."""
    path = Path(records_path) if records_path is not None else None
    text = path.read_text() if path is not None and path.is_file() else ""
    cut = bool(text) and not text.endswith("\n")
    if cut:
        text = text[:text.rfind("\n") + 1]
    records = parse_records(text, path)
    if cut:
        path.write_text(text)
        (warn or _warn)(f"{path}: its incomplete last line (a solve cut off while it was "
                        f"written) was dropped; resuming after its {len(records)} record(s)")
    return {(r["run"], r["monitor"], r["problem"]) for r in records}, records


def _warn(text: str) -> None:
    print(f"warning: {text}", file=sys.stderr)


def _rate(records: list[dict], key: str = "status") -> float:
    if key == "status":
        return sum(r["status"] == "success" for r in records) / len(records)
    return sum(bool(r[key]) for r in records) / len(records)


def _group(records: list[dict], field: str) -> dict[str, dict]:
    groups = defaultdict(list)
    for r in records:
        groups[r[field]].append(r)
    out = {}
    for value in sorted(groups):
        rs = groups[value]
        out[str(value)] = {"problems": len(rs), "success": round(_rate(rs), 4),
                           "success_true": round(_rate(rs, "success_true"), 4),
                           "plan_length_mean": round(float(np.mean([r["plan_length"]
                                                                    for r in rs])), 3)}
    return out


def _seconds(records: list[dict]) -> dict:
    """Median wall seconds per solve: in all, and executing (the arm's actions)."""
    return {phase: round(statistics.median(r["seconds"][phase] for r in records), 4)
            for phase in ("total", "execute") if all(phase in r["seconds"] for r in records)}


def _goal_error_summary(records: list[dict]) -> dict | None:
    """Perceived distances of the goal objects from their goal positions in successful
    solves (placement accuracy): median and 90th percentile over objects, in cm."""
    errors = [e for r in records for e in r["error_cm"].values() if e is not None]
    if not errors:
        return None
    return {"objects": len(errors), "median": round(statistics.median(errors), 3),
            "p90": round(float(np.percentile(errors, 90)), 3)}


def summarise(records: list[dict]) -> dict:
    """{run: {"monitor"|"open_loop": summary}} over evaluation records."""
    out: dict[str, dict] = {}
    by_run = defaultdict(list)
    for r in records:
        by_run[(r["run"], MODES[r["monitor"]])].append(r)
    for (run, mode), rs in sorted(by_run.items()):
        plan_s = [r["seconds"]["plan"] for r in rs]
        solved = [r for r in rs if r["plan_length"] > 0]
        out.setdefault(run, {})[mode] = {
            "problems": len(rs),
            "success": round(_rate(rs), 4),
            "success_true": round(_rate(rs, "success_true"), 4),
            "by_objects": _group(rs, "n_objects"),
            "by_k": _group(rs, "k"),
            # Which level found the first plan (records from before it say nothing).
            "by_level": _group([r for r in rs if r.get("level")], "level"),
            "by_band": {band: {"problems": len(b), "success": round(_rate(b), 4)}
                        for band, (ns, ks) in BANDS.items()
                        for b in [[r for r in rs if r["n_objects"] in ns and r["k"] in ks]]
                        if b},
            "plan_seconds": {"median": round(statistics.median(plan_s), 4),
                             "mean": round(float(np.mean(plan_s)), 4)},
            "solve_seconds": _seconds(rs),
            # Search nodes a solve's plans expanded (planning/nodes.py; records made
            # before the count have none)
            "nodes_median": median_nodes(rs),
            "goal_error_cm": _goal_error_summary([r for r in rs if r["status"] == "success"]),
            "plan_length_minus_k": round(float(np.mean(
                [r["plan_length"] - r["k"] for r in solved])), 3) if solved else None,
            "replans_mean": round(float(np.mean([r["replans"] for r in rs])), 3),
            # Steps the arm refused, planned round (records made before the count have none)
            "refusals": sum(r.get("refusals", 0) for r in rs),
            "failure_causes": failures(rs),
            # Failures after which a rider the arm carried was seen off its base (records
            # made before the count have none).
            "failures_with_dropped_riders": sum(r["status"] != "success"
                                                and r.get("dropped_riders", 0) > 0
                                                for r in rs),
            # An execution failure whose goal atoms are all seen: the symbols do not tell
            # the goal positions apart; one whose atoms are not: the plan missed them.
            "execution_failures": {
                "symbolic_goal_reached": sum(r["failure_cause"] == "execution"
                                             and bool(r.get("symbolic_goal_reached"))
                                             for r in rs),
                "symbolic_goal_missed": sum(r["failure_cause"] == "execution"
                                            and not r.get("symbolic_goal_reached")
                                            for r in rs)},
        }
    return out


def plot_planning(summary: dict, path) -> None:
    """Success rate against k and against the object count, plan length against k, and the
    failure causes, one line or bar per run and monitoring mode."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(18, 4.2))
    causes = sorted({c for modes in summary.values() for s in modes.values()
                     for c in s["failure_causes"]})
    series = [(f"{run} ({mode})", s) for run, modes in summary.items()
              for mode, s in modes.items()]
    width = 0.8 / max(len(series), 1)
    for i, (label, s) in enumerate(series):
        style = "-o" if "monitor" in label else "--s"
        ks = sorted(s["by_k"], key=int)
        axes[0].plot([int(k) for k in ks], [s["by_k"][k]["success"] for k in ks], style,
                     label=label)
        ns = sorted(s["by_objects"], key=int)
        axes[1].plot([int(n) for n in ns], [s["by_objects"][n]["success"] for n in ns], style,
                     label=label)
        axes[2].plot([int(k) for k in ks], [s["by_k"][k]["plan_length_mean"] for k in ks],
                     style, label=label)
        axes[3].bar(np.arange(len(causes)) + i * width,
                    [s["failure_causes"].get(c, 0) for c in causes], width, label=label)
    ks_all = sorted({int(k) for _, s in series for k in s["by_k"]})
    if ks_all:
        axes[2].plot(ks_all, ks_all, ":", color="grey", label="plan length = k")
    for ax, xlabel, ylabel in ((axes[0], "k (actions that made the goal)", "success rate"),
                               (axes[1], "objects", "success rate"),
                               (axes[2], "k", "first plan length (mean)")):
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    ns_all = sorted({int(n) for _, s in series for n in s["by_objects"]})
    for ax, ticks in ((axes[0], ks_all), (axes[1], ns_all), (axes[2], ks_all)):
        ax.set_xticks(ticks)
    axes[0].set_ylim(-0.02, 1.02)
    axes[1].set_ylim(-0.02, 1.02)
    axes[3].set_xticks(np.arange(len(causes)) + 0.4 - width / 2, causes, rotation=20)
    axes[3].set_ylabel("failures")
    axes[0].legend(fontsize=7)
    fig.suptitle("Planning evaluation: solved within 5 cm (perceived check)")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
