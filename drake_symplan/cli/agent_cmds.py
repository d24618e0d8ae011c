"""`symplan solve`, `symplan problems make`, `symplan eval planning`: the closed loop.

    symplan solve --start start.yaml --goal goal.yaml [--model DIR] [--planner fd|pyperplan]
                  [--timeout 10] [--no-monitor] [--meshcat] [--record out.html] --json
    symplan solve --start start.yaml [--start-frames DIR] --goal-frames DIR ...
    symplan problems make --out DIR --objects N --k K [K ...] --count C --seed S
    symplan problems make --out DIR --set NAME   (a set of configs/problem_sets.yaml)
    symplan eval planning --runs RUN [RUN ...] --problems DIR --json --plot out.png

Each takes --camera-noise none|realsense|heavy, the cameras' sensor model: problem.json
and problems.json, eval planning's settings and records and a noisy solve's result say
which.

Exit status: 0 solved (made, evaluated), 1 a verdict that is not success, 2 bad input (one
line on stderr). Drake and torch are imported inside the command functions.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from drake_symplan.cli.learning_cmds import eval_subparsers
from drake_symplan.cli.main import CommandError, NegativeAnswer, nonnegative_int, positive_int
from drake_symplan.cli.options import (
    ROBOTS,
    add_camera_noise_argument,
    add_goal_spec_argument,
    add_json_argument,
    add_model_argument,
    add_robot_argument,
    add_solve_arguments,
    check_objects,
    check_output_dir,
    check_output_file,
    load_bundle,
    load_scene_pair,
    probability,
    solve_config,
)
from drake_symplan.goals.sampling import TASKS


def register(subparsers) -> None:
    _register_solve(subparsers)
    _register_problems(subparsers)
    _register_eval_planning(subparsers)


def _register_solve(subparsers) -> None:
    p = subparsers.add_parser(
        "solve", help="solve a goal scene from a start scene in full physics",
        description="Perceives both scenes, plans with a model bundle's symbols and domain, "
        "executes the plan with the robot and checks every object within 5 cm of the "
        "perceived goal. Scene files come from `symplan scene sample` (a start) or a "
        "problem set of `symplan problems make` (PROBLEM/start.yaml, PROBLEM/goal.yaml); "
        "models/demo/ holds the demo's. Either scene may be perceived from depth frames on "
        "disk instead (`symplan frames record`, or a real camera's: docs/perception.md).")
    p.add_argument("--start", required=True, type=Path,
                   help="start scene YAML (world/scenes.py format): the world the robot acts in")
    p.add_argument("--start-frames", type=Path, metavar="DIR",
                   help="perceive the start from this frames folder (of the start scene) "
                   "instead of the simulator's cameras; the world still comes from --start")
    goal = p.add_mutually_exclusive_group(required=True)
    goal.add_argument("--goal", type=Path,
                      help="goal scene YAML with the start's objects (only perceived; the "
                      "file names the objects)")
    add_goal_spec_argument(goal, "built from the start by the robot before solving")
    goal.add_argument("--goal-frames", type=Path, metavar="DIR",
                      help="perceive the goal from this frames folder (no goal scene file): "
                      "its boxes take the names of the start's, per type, moving them least")
    add_model_argument(p)
    add_solve_arguments(p)
    add_robot_argument(p)
    add_camera_noise_argument(p)
    p.add_argument("--meshcat", action="store_true", help="serve the live scene on localhost")
    p.add_argument("--record", type=Path, help="write a self-contained HTML recording here")
    add_json_argument(p)
    p.set_defaults(func=cmd_solve)


def _register_problems(subparsers) -> None:
    problems = subparsers.add_parser("problems", help="planning problem sets")
    problems_sub = problems.add_subparsers(dest="problems_command", required=True)
    p = problems_sub.add_parser(
        "make", help="random non-trivial problems: a start scene, k random actions, the end "
        "state as goal")
    p.add_argument("--out", required=True, type=Path, help="directory (a re-run resumes)")
    p.add_argument("--set", default=None, metavar="NAME",
                   help="make every subset of the evaluation set NAME of "
                   "configs/problem_sets.yaml (written, scale, ...) under --out DIR, as "
                   "DIR/SUBFOLDER; the set gives each subset's --objects, --k, --count, "
                   "--task, --seed, --long-fraction, --max-attempts and --backend")
    p.add_argument("--objects", type=positive_int, help="objects per scene (required "
                   "without --set)")
    p.add_argument("--k", type=positive_int, nargs="+",
                   help="actions per problem; several values are taken in turn (required "
                   "without --set)")
    p.add_argument("--count", type=positive_int, help="problems to keep (required without "
                   "--set)")
    p.add_argument("--seed", type=nonnegative_int, default=None,
                   help="seed of the set: attempt i samples from (seed, i) (default 0)")
    add_robot_argument(p)
    p.set_defaults(backend=None)  # "arm" unless given: told apart from a --set's own
    add_camera_noise_argument(p)
    p.add_argument("--max-attempts", type=positive_int, default=None,
                   help="give up after this many attempts (default 20 x count)")
    p.add_argument("--reproducible", action="store_true",
                   help="keep a goal only if its actions, replayed from the start as saved, "
                   "reach it again (drops chaotic goals; the oracle then solves every one)")
    p.add_argument("--task", choices=TASKS, default=None,
                   help="goals built by design, k actions away (goals/compiler.py): a tower "
                   "of k + 1 boxes, a row of k + 1 cubes, two towers of k + 2 boxes, a "
                   "bridge (a row of two cubes, towers of k // 2 on them, a long block "
                   "across, a cube on it for an odd k), mixed: a tower beside a bridge; many: "
                   "towers, bridges on towers and rows on boxes of their own; tower4, "
                   "towers3, bridge2, row4, bridge_towers: goals as a person writes them; "
                   "default: k random actions")
    p.add_argument("--long-fraction", type=probability, default=None,
                   help="the share of long blocks among the start's boxes (default 0.5)")
    p.add_argument("--start-k", type=nonnegative_int, default=0,
                   help="with --task: the start is two towers that this many actions build "
                   "from scattered boxes, and a goal whose build takes any of the k is kept, "
                   "the boxes set down to take them apart counted (default 0: scattered)")
    add_json_argument(p)
    p.set_defaults(func=cmd_problems_make)


def _register_eval_planning(subparsers) -> None:
    p = eval_subparsers(subparsers).add_parser(
        "planning", help="success rates of model bundles on a problem set, with and "
        "without monitoring")
    p.add_argument("--runs", required=True, nargs="+", type=Path,
                   help="model bundle directories")
    p.add_argument("--problems", required=True, type=Path,
                   help="problem set directory (problems at any depth)")
    add_solve_arguments(p, monitor_flag=False, oracle=True)
    add_robot_argument(p)
    add_camera_noise_argument(p)
    p.add_argument("--monitor", choices=("both", "on", "off"), default="both",
                   help="solve each problem monitored, open loop, or both (default both)")
    p.add_argument("--limit", type=positive_int, default=None, help="first N problems only")
    p.add_argument("--records", type=Path, default=None,
                   help="append one JSON line per solve here; a re-run resumes from it")
    p.add_argument("--plot", type=Path, default=None, help="write the figure to this PNG")
    p.add_argument("--workers", type=positive_int, default=1,
                   help="solve on this many local worker processes, a station each "
                   "(default 1: in this process)")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="solve on Ray workers, one per CPU: on this machine (no ADDRESS) or "
                   "the cluster whose head is at ADDRESS (HOST:PORT); needs .[ray]")
    add_json_argument(p)
    p.set_defaults(func=cmd_eval_planning)


def cmd_solve(args: argparse.Namespace) -> dict:
    # Inputs first, so that bad ones are told before Drake is loaded.
    config = solve_config(args)
    check_output_file(args.record, "--record")
    if args.goal is not None:
        start, goal = load_scene_pair(args.start, args.goal)
    else:
        from drake_symplan.cli.world_cmds import load_scene_file

        start, goal = load_scene_file(args.start), None
    frames = solve_frames(args.start_frames, args.goal_frames)
    structures = []
    if args.goal_spec:
        from drake_symplan.cli.goal_cmds import checked_specs, goal_of_specs

        structures = checked_specs(start, args.goal_spec)
        bundle = load_bundle(args.model)
        goal = goal_of_specs("solve", start, structures, args.backend, args.camera_noise)
        if isinstance(goal, NegativeAnswer):
            return goal
    else:
        bundle = load_bundle(args.model)

    from drake_symplan.abstraction.abstraction import Abstraction
    from drake_symplan.agent.solve import solve
    from drake_symplan.world.visualization import StartMeshcat

    meshcat = None
    if args.meshcat or args.record:
        with contextlib.redirect_stdout(sys.stderr):  # stdout is for the result
            meshcat = StartMeshcat()
    result = solve(start, goal, Abstraction(bundle), config, meshcat=meshcat,
                   record=args.record, robot=args.backend, camera_noise=args.camera_noise,
                   relations=structures if config.goal_check == "relations" else (),
                   **frames)
    out = result.to_json()
    for key, folder in (("start_frames", args.start_frames), ("goal_frames", args.goal_frames)):
        if folder is not None:
            out[key] = str(folder)
    if args.goal_spec:
        out["goal_spec"] = [" ".join(spec.split()) for spec in args.goal_spec]
    if args.camera_noise != "none":
        out["camera_noise"] = args.camera_noise
    if args.record:
        out["recording"] = str(args.record)
    if not args.json:
        print(f"{result.status}: {len(result.executed)} step(s) executed, {result.replans} "
              f"replan(s), {result.seconds['total']:.1f} s")
        if result.unmet is not None:
            print(f"  relations: {'; '.join(result.unmet) if result.unmet else 'all held'}")
        else:
            for name, o in result.objects.items():
                print(f"  {name}: {o['error_cm']} cm from its goal")
        if result.message:
            print(f"  {result.failure_cause}: {result.message}")
    if args.meshcat:
        print("Meshcat is serving the scene; press Enter to quit.", file=sys.stderr)
        input()
    return out if result.success else NegativeAnswer(out)


def solve_frames(start: Path | None, goal: Path | None) -> dict:
    """{"frames": the agent.beliefs.Frames of --start-frames and --goal-frames}, read and
    checked ({} without them): a folder that cannot be read (perception/frames.py's
    BadFrames) is bad input."""
    if start is None and goal is None:
        return {}
    from drake_symplan.agent.beliefs import Frames
    from drake_symplan.perception.frames import BadFrames, read_frames

    try:
        return {"frames": Frames(*(None if f is None else read_frames(f)
                                   for f in (start, goal)))}
    except BadFrames as e:
        raise CommandError(str(e)) from e


def check_task(task: str | None, ks: list[int], objects: int, start_k: int) -> None:
    """Bad input for a request no start could meet: --start-k without --task, or a
    structure k actions away on too few boxes (each box placed once and set down out of
    the way at most once: 2 x --objects actions at most)."""
    if start_k and task is None:
        raise CommandError("--start-k needs --task (the start's towers are taken apart to "
                           "build a structure)")
    if task is not None and max(ks) > 2 * objects:
        raise CommandError(f"--k {max(ks)}: a structure of {objects} boxes takes at most "
                           f"{2 * objects} actions to build")


# What a --set gives each of its subsets (goals/sets.py Subset): not options beside it.
SET_GIVES = ("objects", "k", "count", "task", "seed", "long_fraction", "max_attempts",
             "backend")


def _summary_line(out: Path, summary: dict) -> str:
    return (f"{summary['kept']} problem(s) in {out} after {summary['attempts']} "
            f"attempt(s); dropped: {summary['rejected']}")


def cmd_problems_make(args: argparse.Namespace) -> dict:
    if args.set is not None:
        return _make_set(args)
    if missing := [f"--{name}" for name in ("objects", "k", "count")
                   if getattr(args, name) is None]:
        raise CommandError(f"the following arguments are required without --set: "
                           f"{', '.join(missing)}")
    args.seed = 0 if args.seed is None else args.seed
    args.long_fraction = 0.5 if args.long_fraction is None else args.long_fraction
    args.backend = args.backend or "arm"
    check_objects(args.objects)
    check_task(args.task, args.k, args.objects, args.start_k)
    check_output_dir(args.out)
    from drake_symplan.goals.problems import make_problems

    summary = make_problems(args.out, args.objects, args.k, args.count, args.seed,
                            args.backend, args.max_attempts,
                            reproducible=args.reproducible, camera_noise=args.camera_noise,
                            task=args.task, start_k=args.start_k,
                            long_fraction=args.long_fraction)
    out = {"out": str(args.out), **summary}
    if not args.json:
        print(_summary_line(args.out, summary))
    return out if summary["kept"] >= args.count else NegativeAnswer(out)


def _make_set(args: argparse.Namespace) -> dict:
    """`problems make --set NAME`: every subset of the set, each as the plain command."""
    from drake_symplan.goals.sets import make_set, problem_set

    if given := [f"--{name.replace('_', '-')}" for name in SET_GIVES
                 if getattr(args, name) is not None]:
        raise CommandError(f"argument --set: not allowed with {', '.join(given)} (the set "
                           "gives each subset its own, configs/problem_sets.yaml)")
    chosen = problem_set(args.set, backends=ROBOTS)
    for subset in chosen.subsets:
        check_task(subset.task, list(subset.k), subset.objects, args.start_k)
    check_output_dir(args.out)

    def progress(subset, summary) -> None:
        if not args.json:
            print(_summary_line(args.out / subset.folder, summary))

    summaries = make_set(chosen, args.out, progress=progress,
                         reproducible=args.reproducible, camera_noise=args.camera_noise,
                         start_k=args.start_k)
    out = {"out": str(args.out), "set": chosen.name, "subsets": summaries}
    short = [s.folder for s in chosen.subsets if summaries[s.folder]["kept"] < s.count]
    return NegativeAnswer(out) if short else out


def cmd_eval_planning(args: argparse.Namespace) -> dict:
    from drake_symplan.abstraction.abstraction import Abstraction
    from drake_symplan.evaluation.planning import evaluate_planning, plot_planning

    config = solve_config(args)
    for run in args.runs:
        if not run.is_dir():
            raise CommandError(f"no model directory {run}")
    check_output_file(args.records, "--records")
    check_output_file(args.plot, "--plot")
    monitor = {"both": (True, False), "on": (True,), "off": (False,)}[args.monitor]
    result = evaluate_planning(
        args.runs, args.problems, config, args.backend, monitor, args.limit, args.records,
        load=lambda run: Abstraction(load_bundle(run)), ray_address=args.ray,
        workers=args.workers, camera_noise=args.camera_noise,
        warn=lambda text: print(f"symplan eval planning: warning: {text}", file=sys.stderr))
    out = {"settings": result["settings"], "runs": result["runs"]}
    if "solves_by_node" in result:
        out["solves_by_node"] = result["solves_by_node"]
    if args.plot:
        plot_planning(result["runs"], args.plot)
        out["plot"] = str(args.plot)
    if not args.json:
        for run, modes in result["runs"].items():
            for mode, s in modes.items():
                nodes = "" if s["nodes_median"] is None else \
                    f", median {s['nodes_median']:g} search nodes"
                print(f"{run} ({mode}): {s['success']:.0%} of {s['problems']} solved; median "
                      f"plan {s['plan_seconds']['median']:.2f} s{nodes}; failures "
                      f"{s['failure_causes']}")
    return out
