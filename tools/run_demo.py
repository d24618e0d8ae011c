"""The demo: the robot solves a goal with the symbols it learned, in full physics.

    python tools/run_demo.py [--model DIR] [--seed N [--objects 3] [--k 2|3]]
                             [--start start.yaml --goal goal.yaml] [--out out/demo.html]
                             [--planner fd] [--timeout 10] [--no-record] [--meshcat] [--json]

1. The problem: by default the shipped one, models/demo/ (start.yaml, goal.yaml: two
   cubes and two long blocks, the goal two arm actions away), the same on every machine.
   `--seed N` samples a new one: a random scene with `--objects` boxes, then k = 2 or 3
   random pick/place actions executed by the UR10; the scene they leave is the goal
   (agent/problems.py, as the planning evaluation makes them), kept only if the same
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

Exit status: 0 success, 1 a verdict that is not success, no plan, or no goal
could be made, 2 bad input (one line on stderr).
"""

from __future__ import annotations

import argparse
import contextlib
import html
import json
import sys
import time
from pathlib import Path

import numpy as np

from drake_symplan.cli.main import CommandError
from drake_symplan.cli.options import add_solve_arguments, solve_config

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "models" / "demo"  # the default problem: start.yaml, goal.yaml, problem.json
MAX_ATTEMPTS = 12  # random problems tried before giving up (non-trivial, reproducible)
# --from-scratch: shares of the budget by which collection and training must end.
COLLECT_SHARE, TRAIN_SHARE = 0.4, 0.85
FIRST_ROUND = 100  # transitions collected first, to measure the rate


WHY = {True: "the goal's symbols hold in the final scene: the learned symbols do not tell "
             "the goal positions apart (they say what is on what, not where on the table)",
       False: "the goal's symbols do not hold in the final scene: an operator's prediction "
              "or the execution went wrong"}


def shown(path) -> str:
    """`path` as printed: relative to the working directory when it lies under it."""
    path = Path(path).resolve()
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return str(path)


class BadInput(Exception):
    """Told in one line on stderr, exit status 2."""


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", type=Path, default=None,
                   help="model bundle directory (default: the shipped models/learned/)")
    p.add_argument("--seed", type=int, default=None,
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
    p.add_argument("--out", type=Path, default=REPO / "out" / "demo.html",
                   help="the HTML recording (default out/demo.html)")
    p.add_argument("--no-record", action="store_true", help="write no recording")
    add_solve_arguments(p)
    p.add_argument("--meshcat", action="store_true",
                   help="watch live on localhost; keeps serving until Enter is pressed")
    p.add_argument("--json", action="store_true", help="print the result as JSON only")
    p.add_argument("--from-scratch", action="store_true",
                   help="collect, train and make operators first, then solve with that model")
    p.add_argument("--budget-minutes", type=float, default=15.0,
                   help="--from-scratch: minutes for collection and training (default 15)")
    p.add_argument("--work", type=Path, default=REPO / "out" / "from_scratch",
                   help="--from-scratch: directory for the data set, run and bundle")
    return p.parse_args(argv)


def check_inputs(args):
    """(bundle, start, goal) or BadInput; nothing heavier than the bundle is loaded."""
    from drake_symplan.symbolic.bundle import BundleError, ModelBundle, default_bundle_dir
    from drake_symplan.world.scenes import MAX_OBJECTS

    if (args.start is None) != (args.goal is None):
        raise BadInput("give --start and --goal together")
    if args.start is not None and args.seed is not None:
        raise BadInput("give --seed (a sampled problem) or --start/--goal, not both")
    if args.start is None and args.seed is None:
        args.start, args.goal = SHIPPED / "start.yaml", SHIPPED / "goal.yaml"
    if args.start is None and not 2 <= args.objects <= MAX_OBJECTS:
        raise BadInput(f"--objects must be in [2, {MAX_OBJECTS}], got {args.objects}")
    start = goal = None
    if args.start is not None:
        from drake_symplan.agent.beliefs import check_scene_pair
        from drake_symplan.cli.world_cmds import load_scene_file

        start, goal = load_scene_file(args.start), load_scene_file(args.goal)
        check_scene_pair(start, goal)
    if args.from_scratch:
        if args.model is not None:
            raise BadInput("give --model or --from-scratch, not both")
        if not args.budget_minutes >= 2:
            raise BadInput(f"--budget-minutes must be at least 2, got {args.budget_minutes:g}")
        return None, start, goal
    path = args.model or default_bundle_dir()
    if not path.is_dir():
        raise BadInput(f"no model at {path}" + (" (the default model is not shipped yet; "
                                                "give --model DIR)" if args.model is None else ""))
    try:
        return ModelBundle.load(path), start, goal
    except BundleError as e:
        raise BadInput(str(e)) from e


def symplan(argv, say, timeout=None) -> None:
    """Runs `symplan ARGV` as a child process; on timeout it is stopped (SIGTERM)."""
    import subprocess

    cmd = [sys.executable, "-m", "drake_symplan.cli.main", *map(str, argv)]
    say("  $ symplan " + " ".join(map(str, argv)))
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.terminate()
        proc.communicate()
        say("    stopped at the budget")
        return
    if proc.returncode != 0:
        raise RuntimeError(f"symplan {argv[0]} failed ({proc.returncode}): {err.strip()[-300:]}")


def from_scratch(args, say):
    """Collects, trains and bundles within the budget; returns the loaded bundle."""
    import os

    from drake_symplan.symbolic.bundle import ModelBundle

    budget, t0 = args.budget_minutes * 60, time.perf_counter()
    seed = 0 if args.seed is None else args.seed
    work = args.work / f"seed{seed}"
    data, run, out = work / "data", work / "run", work / "bundle"
    try:
        bundle = ModelBundle.load(out)
        say(f"from scratch: reusing the model learned before in {out}")
        return bundle
    except (ValueError, OSError):
        pass
    workers = max(1, min(2, os.cpu_count() or 1))
    say(f"from scratch in {work}, {args.budget_minutes:g} min: collect, train, operators")

    def collect(n):
        symplan(["collect", "--backend", "hand", "--transitions", n, "--workers", workers,
                 "--out", data, "--seed", seed, "--objects", "2-4", "--no-progress"], say)

    manifest = data / "manifest.json"
    if manifest.is_file():  # a re-run: the data set collected before, as it is
        total = int(json.loads(manifest.read_text())["config"]["transitions"])
    else:
        collect(FIRST_ROUND)
        rate = FIRST_ROUND / (time.perf_counter() - t0)
        total = max(FIRST_ROUND, int(rate * COLLECT_SHARE * budget))
        if total > FIRST_ROUND:
            collect(total)
    say(f"  data set: {total} transitions ({time.perf_counter() - t0:.0f} s)")
    left = TRAIN_SHARE * budget - (time.perf_counter() - t0)
    symplan(["train", "--model", "relational", "--data", data, "--out", run, "--seed",
             seed, "--model-option", "invariant=true", "--threads", workers,
             "--epochs", 300, "--no-progress"] + (["--resume"] if (run / "last.pt").is_file()
                                                  else []), say, timeout=max(left, 30))
    # Operators need support: with a small data set, fewer transitions per operator.
    min_count = max(3, min(10, total // 500))
    symplan(["bundle", "--run", run, "--data", data, "--out", out, "--min-count", min_count],
            say)
    say(f"  model ready in {time.perf_counter() - t0:.0f} s")
    bundle = ModelBundle.load(out)  # BundleError (a ValueError) when it holds no operators
    say(f"  {len(bundle.operators)} operators from {total} transitions")
    return bundle


def make_goal(agent, args, say):
    """(start, goal, info) of the first non-trivial random problem, or None."""
    from drake_symplan.agent.problems import make_problem, problem_seed

    k = args.k or int(np.random.default_rng(args.seed).integers(2, 4))
    for attempt in range(MAX_ATTEMPTS):
        seed = problem_seed(args.seed, attempt)
        made = make_problem(agent, seed, args.objects, k, reproducible=True)
        if not isinstance(made, str):
            start, goal, info = made
            return start, goal, {"seed": args.seed, "problem_seed": seed, "k": k, **info}
        say(f"  attempt {attempt}: dropped ({made})")
    return None


def explain_no_plan(abstraction, plan, start, goal, timeout: float) -> str:
    """Why there is no plan, in words: the planner's status and the goal atoms that do
    not hold at the start."""
    task = abstraction.task(abstraction.read_scene(start.scene),
                            abstraction.read_scene(goal.scene))
    missing = ", ".join(a.text() for a in sorted(task.goal - task.init))
    if plan.status == "unsolvable":
        why = ("the learned domain cannot reach the goal's symbols from the start's (the "
               "planner proved it)")
    elif plan.status == "timeout":
        why = f"the planner found no plan within --timeout {timeout:g} s"
    else:
        why = f"the planner failed: {plan.message}"
    return f"no plan: {why}; goal atoms to reach: {missing or 'none'}"


def panel(result: dict, demo: dict) -> str:
    """The recording's panel: problem, plan, executed steps, distances, verdict."""
    from drake_symplan.agent.inspection import panel_html

    def items(lines):
        return "<ol style='padding-left:18px;margin:2px 0'>" + "".join(
            f"<li>{line}</li>" for line in lines) + "</ol>"

    errors = "".join(f"<div>{n}: {o['error_cm']} cm</div>" for n, o in result["objects"].items())
    if result.get("symbolic_goal_reached") is not None:
        errors += f"<div><i>{WHY[result['symbolic_goal_reached']]}</i></div>"
    rejected = [html.escape(f"{c['source']}: {' '.join(c['steps']) or 'no steps'}: {c['why']}")
                for c in result.get("candidates", []) if not c["accepted"]]
    sections = [("Goal", "<div>translucent green boxes; k = "
                 f"{demo.get('k', '-')} random actions from the start</div>"),
                ("Plan", items(demo["plan_readable"]) or "<div>none</div>"),
                *([("Rejected candidate plans", items(rejected))] if rejected else []),
                (f"Executed ({result['replans']} replan(s))",
                 items(demo["executed_readable"])),
                (f"Verdict: {result['status']}", errors)]
    return panel_html(f"symplan demo (seed {demo.get('seed', '-')})", sections)


def main(argv=None) -> int:
    args = parse_args(argv)
    out_stream = sys.stderr if args.json else sys.stdout

    def say(text=""):
        print(text, file=out_stream, flush=True)

    try:
        bundle, start, goal = check_inputs(args)
        config = solve_config(args)
    except (BadInput, CommandError, ValueError, OSError) as e:
        print(f"run_demo.py: error: {e}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    if args.from_scratch:
        try:
            bundle = from_scratch(args, say)
        except (RuntimeError, ValueError, OSError) as e:
            say(f"from scratch: {e}" + ("; the data set is too small: give more "
                                        "--budget-minutes" if "no operators" in str(e) else ""))
            return 1
    from drake_symplan.abstraction.abstraction import Abstraction
    from drake_symplan.agent.inspection import (
        annotate_html,
        draw_goal_scene,
        look_at,
        plan_quality,
        readable_step,
    )
    from drake_symplan.agent.solve import Agent
    from drake_symplan.boxes import GOAL_TOLERANCE
    from drake_symplan.world.scenes import save_scene
    from drake_symplan.world.visualization import StartMeshcat

    meshcat = None
    if args.meshcat or not args.no_record:  # a recording is Meshcat's page
        with contextlib.redirect_stdout(sys.stderr):  # Meshcat's URL: not on stdout
            meshcat = StartMeshcat(announce=args.meshcat)
    agent = Agent("arm", meshcat=meshcat)
    abstraction = Abstraction(bundle)
    say(f"model {shown(bundle.path)}: {bundle.n_unary} unary symbol(s), "
        f"{bundle.n_relations} relations, {len(bundle.operators)} operators")
    demo = {"seed": args.seed}
    if start is None:
        say(f"making a goal: {args.objects} objects, random actions by the UR10 ...")
        made = make_goal(agent, args, say)
        if made is None:
            say(f"no non-trivial, reproducible goal in {MAX_ATTEMPTS} attempts; "
                "try another --seed")
            return 1
        start, goal, info = made
        demo.update(info)
        say(f"goal: {info['k']} random actions away ({'; '.join(info['actions'])}), "
            f"farthest object moved {info['moved_cm']} cm")
    else:
        info = args.start.parent / "problem.json"  # beside a problem set's start.yaml
        if info.is_file():
            demo.update({k: v for k, v in json.loads(info.read_text()).items()
                         if k in ("k", "seed", "actions", "moved_cm")})
        demo["problem"] = {"start": shown(args.start), "goal": shown(args.goal)}
        say(f"problem: {shown(args.start)} -> {shown(args.goal)}"
            + (f" ({demo['k']} arm actions apart)" if "k" in demo else ""))
    record = None if args.no_record else args.out
    if record is not None:
        record.parent.mkdir(parents=True, exist_ok=True)
        stem = record.with_suffix("")
        demo["scenes"] = {"start": f"{stem}_start.yaml", "goal": f"{stem}_goal.yaml"}
        save_scene(start, demo["scenes"]["start"])
        save_scene(goal, demo["scenes"]["goal"])
        draw_goal_scene(meshcat, goal)
        look_at(meshcat, [o.position for o in start.objects + goal.objects])

    def planned(plan, start_seen, goal_seen):
        demo["plan_readable"] = [readable_step(s) for s in plan.steps]
        for c in plan.candidates:
            if not c.accepted:
                say(f"rejected {c.source}: {' '.join(c.steps) or 'no steps'}: {c.why}")
        if not plan.solved:
            demo["no_plan"] = explain_no_plan(abstraction, plan, start_seen, goal_seen,
                                              config.timeout)
            say(demo["no_plan"])
            return
        if not plan.steps:
            say("plan: empty, the goal's symbols already hold in the start scene")
        else:
            say(f"plan ({len(plan.steps)} step(s), {plan_quality(plan, goal_seen)}, "
                f"{plan.seconds:.1f} s" + ("" if plan.level == "symbolic"
                                           else f", {plan.level}") + "):")
        if plan.message:
            say(f"  ({plan.message})")
        for i, step in enumerate(plan.steps, 1):
            say(f"  {i}. {readable_step(step)}    {step}")
        say("executing with the UR10 in full physics, perceiving after each step ...")

    result = agent.solve(start, goal, abstraction, config, record=record, on_plan=planned)
    out = result.to_json()
    demo["executed_readable"] = [readable_step(s) for s in result.executed]
    demo["seconds"] = round(time.perf_counter() - t0, 1)
    out["demo"] = demo
    if result.status in ("no_plan", "timeout") and not result.executed:
        if args.json:
            print(json.dumps(out, indent=2))
        return 1
    if result.executed != result.plan:
        say("executed (repositionings and replans included): "
            + "; ".join(demo["executed_readable"]))
    for name, o in out["objects"].items():
        say(f"  {name}: {o['error_cm']} cm from its goal")
    say(f"verdict: {result.status} (every object within {GOAL_TOLERANCE * 100:g} cm: "
        f"{'yes' if result.success else 'no'}), {len(result.executed)} step(s), "
        f"{result.replans} replan(s)" + (f"; {result.failure_cause}: {result.message}"
                                       if result.message else ""))
    if result.symbolic_goal_reached is not None:
        say(WHY[result.symbolic_goal_reached])
    if record is not None and record.is_file():
        record.write_text(annotate_html(record.read_text(), panel(out, demo)))
        out["recording"] = str(record)
        say(f"recording written to {shown(record)} ({demo['seconds']} s)")
    if args.json:
        print(json.dumps(out, indent=2))
    if args.meshcat:
        print(f"Meshcat at {meshcat.web_url()}; press Enter to quit", file=sys.stderr)
        input()
    return 0 if result.success else 1


if __name__ == "__main__":
    sys.exit(main())
