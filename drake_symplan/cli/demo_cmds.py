"""The demo: the robot solves a goal with the symbols it learned, in full physics.

    symplan demo [--model DIR] [--seed N [--objects 3] [--k 2|3]]
                 [--start start.yaml --goal goal.yaml] [--out out/demo.html]
                 [--planner fd] [--timeout 10] [--no-record] [--meshcat] [--json]
    (python tools/run_demo.py takes the same options)

1. The problem: by default the shipped one, models/demo/ (start.yaml, goal.yaml: two
   cubes and two long blocks, the goal two arm actions away), the same on every machine.
   `--seed N` samples a new one: a random scene with `--objects` boxes, then k = 2 or 3
   random pick/place actions executed by the UR10; the scene they leave is the goal
   (goals/problems.py, as the planning evaluation makes them), kept only if the same
   actions replayed from the start as saved reach it again (`symplan problems make
   --reproducible`: a goal that a tenth of a millimetre turns into another is dropped).
   Sampled goals come from simulated physics, which differs slightly between machines, so
   the same seed can give another goal elsewhere.
   Or `--start/--goal` files.
2. The model bundle (default: the shipped models/learned/) reads both perceived scenes into
   symbols and the planner plans once, printed step by step ("pick o3 at its centre,
   release on o1's left"). With no plan the demo says why (the learned domain cannot
   reach the goal's symbols, or the planner ran out of --timeout) and stops: exit 1.
3. The UR10 executes it in full physics, perceiving after each step and replanning when
   the symbols differ from the operator's prediction (agent/solve.py).
4. Each object's distance to its perceived goal position and the verdict against 5 cm.

`--from-scratch --budget-minutes M` first learns its own model within about M minutes
(hand collection with whole scenes, an invariant RelationalDeepSym trained until the
budget's share runs out, effect-first operators: `symplan collect`, `train`, `bundle`,
each a child process, in `--work`/seed<S>, default out/from_scratch/), then solves with
it; a re-run with the same `--work` and `--seed` reuses that model.

One HTML recording (`--out`, default out/demo.html; none with `--no-record`) holds the
start scene, the goal (the translucent green boxes) and the execution, with the plan and
the verdict in a panel. Meshcat serves on localhost only for that page (its URL is
printed with `--meshcat`, which keeps it serving until Enter). `--json` prints the result
object of `symplan solve --json` (plus "demo": the problem and the readable plan) and
nothing else on stdout.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from drake_symplan.cli.main import (
    CommandError,
    HelpFormatter,
    Parser,
    nonnegative_int,
    run,
)
from drake_symplan.cli.options import (
    add_camera_noise_argument,
    add_goal_spec_argument,
    add_model_argument,
    add_solve_arguments,
    check_objects,
    load_bundle,
    load_scene_pair,
    solve_config,
)


class DemoHelpFormatter(HelpFormatter, argparse.RawDescriptionHelpFormatter):
    """The description as written (its numbered steps), each option's default said."""


def add_demo_arguments(p: argparse.ArgumentParser, out_dir: Path,
                       problem_dir: Path | None = None) -> None:
    """The demo's options; `out_dir` holds the recording and --from-scratch's work;
    `problem_dir`, the default problem (None: the package's models/demo/)."""
    add_model_argument(p)
    p.add_argument("--seed", type=nonnegative_int, default=None,
                   help="sample a new problem with this seed: a random scene, then k random "
                   "arm actions make the goal (default: the shipped problem, models/demo/)")
    p.add_argument("--objects", type=int, default=3,
                   help="with --seed: objects in the scene (default 3)")
    p.add_argument("--k", type=int, choices=(1, 2, 3), default=None,
                   help="with --seed: random actions from start to goal (default: 2 or 3, "
                   "by the seed)")
    p.add_argument("--start", type=Path, default=None,
                   help="start scene YAML (with --goal), e.g. a problem of `symplan "
                   "problems make` or a file of `symplan scene sample`")
    p.add_argument("--goal", type=Path, default=None, help="goal scene YAML (with --start)")
    add_goal_spec_argument(p, "built by the arm from --start or, by default, from a "
                           "scattered start of --objects boxes sampled with --seed (default 0)")
    p.add_argument("--out", type=Path, default=out_dir / "demo.html",
                   help="the HTML recording (default out/demo.html)")
    p.add_argument("--no-record", action="store_true", help="write no recording")
    add_solve_arguments(p)
    add_camera_noise_argument(p)
    p.add_argument("--meshcat", action="store_true",
                   help="watch live on localhost; keeps serving until Enter is pressed")
    p.add_argument("--json", action="store_true", help="print the result as JSON only")
    p.add_argument("--from-scratch", action="store_true",
                   help="collect, train and make operators first, then solve with that model")
    p.add_argument("--budget-minutes", type=float, default=15.0,
                   help="--from-scratch: minutes for collection and training (default 15)")
    p.add_argument("--work", type=Path, default=out_dir / "from_scratch",
                   help="--from-scratch: directory for the data set, run and bundle "
                   "(default out/from_scratch)")
    p.set_defaults(func=cmd_demo, problem_dir=problem_dir)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "demo", help="the shipped problem (or a sampled one): plan, execute with the UR10 "
        "in full physics, check within 5 cm, record", description=__doc__,
        formatter_class=DemoHelpFormatter)
    add_demo_arguments(p, Path("out"))


def demo_parser(prog: str, out_dir: Path, problem_dir: Path | None = None):
    """The demo's parser on its own (tools/run_demo.py), usage errors in one line."""
    p = Parser(prog=prog, description=__doc__, formatter_class=DemoHelpFormatter)
    add_demo_arguments(p, out_dir, problem_dir)
    return p


def main(argv: list[str] | None, prog: str, out_dir: Path = Path("out"),
         problem_dir: Path | None = None) -> int:
    """The demo as a program of its own: `prog` names it in its usage and error lines;
    `out_dir` and `problem_dir` as add_demo_arguments takes them."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return run(demo_parser(prog, out_dir, problem_dir), argv, name=prog)


def check_inputs(args: argparse.Namespace):
    """(bundle, start, goal): None for a bundle to learn (--from-scratch) or scenes to
    sample (--seed); bad input is a CommandError. Nothing heavier than the bundle loads."""
    from drake_symplan.pipelines.demo import shipped_problem
    from drake_symplan.pipelines.from_scratch import MIN_BUDGET_MINUTES

    if args.goal_spec:
        return _spec_inputs(args)
    if (args.start is None) != (args.goal is None):
        raise CommandError("give --start and --goal together")
    if args.start is not None and args.seed is not None:
        raise CommandError("give --seed (a sampled problem) or --start/--goal, not both")
    if args.start is None and args.seed is None:
        shipped = args.problem_dir or shipped_problem()
        args.start, args.goal = shipped / "start.yaml", shipped / "goal.yaml"
    if args.start is None:
        check_objects(args.objects)
    start, goal = (None, None) if args.start is None else load_scene_pair(args.start,
                                                                         args.goal)
    if not args.from_scratch:
        return load_bundle(args.model, missing="no model at"), start, goal
    if args.model is not None:
        raise CommandError("give --model or --from-scratch, not both")
    if not args.budget_minutes >= MIN_BUDGET_MINUTES:
        raise CommandError(f"--budget-minutes must be at least {MIN_BUDGET_MINUTES:g}, got "
                           f"{args.budget_minutes:g}")
    return None, start, goal


def _spec_inputs(args: argparse.Namespace):
    """check_inputs for --goal-spec: (bundle, start, None), the start given or scattered."""
    from drake_symplan.cli.goal_cmds import checked_specs
    from drake_symplan.cli.world_cmds import load_scene_file
    from drake_symplan.pipelines.demo import scattered_start

    if args.goal is not None or args.from_scratch:
        raise CommandError("give --goal-spec without --goal and --from-scratch")
    if args.start is not None:
        start = load_scene_file(args.start)
    else:
        check_objects(args.objects)
        args.seed = 0 if args.seed is None else args.seed
        start = scattered_start(args.seed, args.objects)
    checked_specs(start, args.goal_spec)
    return load_bundle(args.model, missing="no model at"), start, None


def cmd_demo(args: argparse.Namespace) -> int:
    """Runs the demo; prints its lines (on stderr with --json), then its JSON; returns the
    exit status (0 success; 1 a failed verdict, no plan, no goal, no model learned)."""
    from drake_symplan.pipelines.demo import DemoSettings, run_demo

    bundle, start, goal = check_inputs(args)
    config = solve_config(args)
    out_stream = sys.stderr if args.json else sys.stdout

    def say(text=""):
        print(text, file=out_stream, flush=True)

    t0 = time.perf_counter()
    if args.from_scratch:
        from drake_symplan.pipelines.from_scratch import learn_from_scratch

        try:
            bundle = learn_from_scratch(args.work, 0 if args.seed is None else args.seed,
                                        args.budget_minutes, say)
        except (RuntimeError, ValueError, OSError) as e:
            say(f"from scratch: {e}" + ("; the data set is too small: give more "
                                        "--budget-minutes" if "no operators" in str(e) else ""))
            return 1
    settings = DemoSettings(args.seed, args.objects, args.k, args.start, args.goal,
                            None if args.no_record else args.out, args.meshcat,
                            args.camera_noise, args.goal_spec)
    outcome = run_demo(bundle, settings, config, start, goal, say, t0)
    if args.json and outcome.result is not None:
        print(json.dumps(outcome.result, indent=2))
    if args.meshcat and outcome.meshcat is not None:
        print(f"Meshcat at {outcome.meshcat.web_url()}; press Enter to quit", file=sys.stderr)
        input()
    return outcome.code
