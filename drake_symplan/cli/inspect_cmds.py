"""`symplan inspect` and `symplan explain`: seeing what the learned symbols are.

    symplan inspect --scene scene.yaml [--model DIR] [--goal goal.yaml | --goal-spec SPEC ...]
                    [--stages] [--record out.html]
                    [--meshcat] [--planner fd|pyperplan] [--timeout 10] --json
    symplan explain [--model DIR] --data DIR [--margin 3] [--plot out.png] --json

`inspect` perceives the scene, reads its symbols with a model bundle and draws them in
Meshcat (agent/inspection.py); with --goal also the goal's symbols and the plan step by
step. `explain` says, for each learned predicate, which description computed from the
perceived features and contacts agrees with it best (learning/explain.py).

Exit status: 0 done, 1 inspect found no plan for the goal, 2 bad input (one line on
stderr). Drake and torch are imported inside the command functions.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from drake_symplan.cli.main import CommandError, NegativeAnswer
from drake_symplan.cli.options import (
    add_camera_noise_argument,
    add_goal_spec_argument,
    add_json_argument,
    add_planner_arguments,
    add_planning_argument,
    check_output_file,
    solve_config,
)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "inspect", help="show a perceived scene's symbols (and a plan to a goal) in Meshcat",
        description="Perceives the scene, reads its symbols with a model bundle and draws "
        "the boxes coloured by their unary bit pattern and the relations between objects in "
        "contact as coloured rods; with --goal the goal's symbols (translucent) and the plan "
        "as arcs. The legend, the symbols and the plan's steps (operator, preconditions, "
        "effects) are printed and written into the recording's page.")
    p.add_argument("--scene", required=True, type=Path, help="scene YAML")
    goal = p.add_mutually_exclusive_group()
    goal.add_argument("--goal", type=Path, default=None, help="goal scene YAML (same objects)")
    add_goal_spec_argument(goal, "built from the scene by the arm first")
    p.add_argument("--model", type=Path, default=None,
                   help="model bundle directory (default: the shipped models/learned/)")
    p.add_argument("--record", type=Path, default=None,
                   help="write a self-contained HTML page of the drawing here")
    p.add_argument("--meshcat", action="store_true",
                   help="keep serving the live scene on localhost until Enter is pressed")
    add_planner_arguments(p)
    add_planning_argument(p)
    add_camera_noise_argument(p)
    p.add_argument("--clouds", action="store_true",
                   help="also draw what each camera's sensor gave (with --camera-noise: its "
                   "noise, holes and flying pixels), and count its points in the JSON")
    p.add_argument("--stages", action="store_true",
                   help="with --goal-spec: plan its relations stage by stage on the symbols "
                   "alone and, for the first stage with no plan, name the steps nearest to "
                   "it and the atoms each lacks")
    add_json_argument(p)
    p.set_defaults(func=cmd_inspect)

    p = subparsers.add_parser(
        "explain", help="what each learned symbol means, from perceived features and contacts",
        description="For each unary and relational predicate of a model, the description "
        "computed from the perceived features and contacts of a data set's whole scenes "
        "that agrees with it best (accuracy, or balanced accuracy for a rare bit), with the "
        "bit's frequency. Relations are read between objects perceived in contact.")
    p.add_argument("--model", type=Path, default=None,
                   help="model bundle (model.pt) or run directory (best.pt); default: the "
                   "shipped models/learned/")
    p.add_argument("--data", required=True, type=Path,
                   help="data set directory with whole scenes (collected by current code)")
    p.add_argument("--margin", type=float, default=3.0,
                   help="a bit is uncertain when |logit| < margin (default 3.0)")
    p.add_argument("--plot", type=Path, default=None,
                   help="write a PNG of the best descriptions and example scenes")
    add_json_argument(p)
    p.set_defaults(func=cmd_explain)


def _model_dir(path: Path | None) -> Path:
    from drake_symplan.symbolic.bundle import default_bundle_dir

    if path is None:
        path = default_bundle_dir()
        if not path.is_dir():
            raise CommandError(f"no default model at {path} (not shipped yet); give --model DIR")
    if not path.is_dir():
        raise CommandError(f"no model directory {path}")
    return path


def cmd_inspect(args: argparse.Namespace) -> dict:
    from drake_symplan.agent.beliefs import check_scene_pair
    from drake_symplan.cli.world_cmds import load_scene_file

    # Inputs first, so that bad ones are told before Drake is loaded.
    config = solve_config(args)
    check_output_file(args.record, "--record")
    if args.stages and not args.goal_spec:
        raise CommandError("--stages needs --goal-spec (the stages of a goal of relations)")
    start = load_scene_file(args.scene)
    goal = load_scene_file(args.goal) if args.goal is not None else None
    if goal is not None:
        check_scene_pair(start, goal)
    if args.goal_spec:
        from drake_symplan.cli.goal_cmds import checked_specs, goal_of_specs

        structures = checked_specs(start, args.goal_spec)
    from drake_symplan.symbolic.bundle import ModelBundle

    bundle = ModelBundle.load(_model_dir(args.model))
    if args.goal_spec:
        goal = goal_of_specs("inspect", start, structures, "arm", args.camera_noise)
        if isinstance(goal, NegativeAnswer):
            return goal

    from drake_symplan.abstraction.abstraction import Abstraction
    from drake_symplan.agent.inspection import inspect, inspection_sections
    from drake_symplan.world.visualization import StartMeshcat

    meshcat = None
    if args.meshcat or args.record:
        with contextlib.redirect_stdout(sys.stderr):  # stdout is for the result
            meshcat = StartMeshcat()
    from drake_symplan.robot.backends import PerceptionFailure

    try:
        result = inspect(start, Abstraction(bundle), goal, meshcat, args.record, config,
                         title=f"symplan inspect {args.scene.name}",
                         camera_noise=args.camera_noise, clouds=args.clouds,
                         relations=structures if args.goal_spec else (), stages=args.stages)
    except (RuntimeError, PerceptionFailure) as e:  # the scene file cannot be perceived
        raise CommandError(f"{args.scene}: {e}") from e
    result["scene"] = str(args.scene)
    if args.goal_spec:
        result["goal_spec"] = [s.text() for s in structures]
    if args.camera_noise != "none":
        result["camera_noise"] = args.camera_noise
    if not args.json:
        print("\n".join(summary_lines(result, inspection_sections)))
    if args.meshcat:
        print(f"Meshcat is serving the scene at {meshcat.web_url()}; press Enter to quit.",
              file=sys.stderr)
        input()
    no_plan = goal is not None and result["plan_status"] != "solved"
    return NegativeAnswer(result) if no_plan else result


def summary_lines(result: dict, sections=None) -> list[str]:
    """The inspection as text: legend, objects, relations, goal atoms, plan steps."""
    from drake_symplan.agent.inspection import (
        OUTCOMES_SHOWN,
        outcome_text,
        stage_lines,
        subgoal_texts,
    )

    start = result["start"]
    lines = ["legend (unary bit pattern p0.. -> box colour): " + ", ".join(
        f"{p} {c}" for p, c in sorted(start["legend"]["unary"].items())),
        "relations (rod colour): " + ", ".join(
            f"{k} {c}" for k, c in start["legend"]["relations"].items())]
    for o in start["objects"]:
        rel = [f"{r['relation']}({r['x']}, {r['y']})" for r in start["relations"]
               if r["x"] == o["name"]]
        lines.append(f"  {o['name']:4s} {o['type']:5s} p={o['pattern']} {o['colour']}  "
                     + ", ".join(rel))
    if "goal" in result:
        lines.append("goal atoms: " + ", ".join(result["goal"]["atoms"]))
        lines.append(f"plan ({result['plan_status']}, {len(result['plan'])} steps):")
        for i, s in enumerate(result["plan"], 1):
            if s["operator"] is None:  # a move no operator names
                lines.append(f"  {i}. {s['readable']}")
                continue
            lines += [f"  {i}. {s['readable']}   [{s['operator']}, reliability "
                      f"{s['reliability']:.0%}]",
                      f"     pre: {', '.join(s['preconditions'])}",
                      f"     add: {', '.join(s['add']) or '-'}; del: {', '.join(s['delete']) or '-'}"]
            lines += [f"     or {outcome_text(o)}   [{o['operator']}]"
                      for o in s.get("other_outcomes", [])[:OUTCOMES_SHOWN]]
        lines += [f"subgoal: {text}" for text in subgoal_texts(result)]
        lines += [f"rejected {c['source']}: {' '.join(c['steps']) or 'no steps'}: {c['why']}"
                  for c in result.get("candidates", []) if not c["accepted"]]
    lines += stage_lines(result.get("stages", []))
    if "recording" in result:
        lines.append(f"recording written to {result['recording']}")
    return lines


def cmd_explain(args: argparse.Namespace) -> dict:
    from drake_symplan.learning.explain import explain_model, explanation_line, plot_examples

    model = _model_dir(args.model)
    if not args.data.is_dir():
        raise CommandError(f"no data set directory {args.data}")
    if not args.margin >= 0:
        raise CommandError(f"--margin must be 0 or more, got {args.margin:g}")
    result, arrays = explain_model(model, args.data, args.margin)
    result["lines"] = [explanation_line(e) for e in result["unary"] + result["relations"]]
    if args.plot:
        result["plot"] = str(plot_examples(result, arrays, args.plot))
    if not args.json:
        print(f"{result['scenes']} scenes, {result['objects']} object reads, "
              f"{result['pairs_in_contact']} ordered pairs in contact")
        print("\n".join(result["lines"]))
    return result
