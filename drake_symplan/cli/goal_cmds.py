"""`symplan goal`: a goal scene built by the robot from a start scene and one-line specs.

    symplan goal --start START "tower o3 o1 o0" "bridge o4 o2 o5" --out GOAL [--json]

The specs (goals/compiler.py: on, tower, bridge, row) are checked against the start
scene before anything runs; a spec the world cannot give is one line on stderr, exit 2,
nothing written. The robot then builds the goal with the structures' designed actions, the
built scene is checked against them on the simulator's poses (the goal's author may look;
a planner may not), kept only if it settles and the same actions from the saved start reach
it again (`--no-reproducible` skips that), and written to GOAL with the specs and actions
as its header. A build that fails (an action infeasible, a box fallen, not reproducible)
is a negative answer, exit 1.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from drake_symplan.cli.main import CommandError, NegativeAnswer
from drake_symplan.cli.options import (
    add_camera_noise_argument,
    add_json_argument,
    add_robot_argument,
    check_output_file,
)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "goal", help="build a goal scene from a start scene and one-line specs "
        "(on A B, tower A B ..., bridge L A B, row A B ...)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("specs", nargs="+", metavar="SPEC",
                   help="'on A B', 'tower A B ... Z' (each on the next), 'bridge L A B' "
                   "(long block L across A and B, standing 6-17 cm apart along y), 'row A B "
                   "... Z' (cubes 7.5 cm apart along +y on the table)")
    p.add_argument("--start", required=True, type=Path, help="start scene YAML")
    p.add_argument("--out", required=True, type=Path, help="goal scene YAML to write")
    p.add_argument("--no-reproducible", dest="reproducible", action="store_false",
                   help="keep a built goal even if replaying its actions lands elsewhere "
                   "(default: only a goal the replay reaches again)")
    add_robot_argument(p)
    add_camera_noise_argument(p)
    add_json_argument(p)
    p.set_defaults(func=cmd_goal)


def checked_specs(start, specs: list[str]) -> list:
    """The structures of `specs`, checked against the start scene's file (before Drake
    loads); CommandError (one line, exit 2) naming what the start cannot give."""
    from drake_symplan.goals.compiler import check
    from drake_symplan.relations import SpecError, parse

    try:
        structures = parse(specs)
        check(structures, start.object_states())
    except SpecError as e:
        raise CommandError(str(e)) from e
    return structures


def built_goal(start, structures: list, backend: str, camera_noise: str,
               reproducible: bool = True):
    """(goal scene, info) built by the `backend` robot from `start`, or why not (a string)."""
    from drake_symplan.agent.solve import Agent
    from drake_symplan.goals.problems import build_goal
    from drake_symplan.relations import SpecError

    try:
        return build_goal(Agent(backend, camera_noise=camera_noise), start, structures,
                          reproducible)
    except SpecError as e:  # what was perceived cannot give it
        raise CommandError(str(e)) from e


def goal_of_specs(command: str, start, structures: list, backend: str, camera_noise: str):
    """The goal scene a command solves or shows, built from `start` (checked_specs); or the
    NegativeAnswer it returns (exit 1, why on stderr) when the build fails."""
    import sys

    made = built_goal(start, structures, backend, camera_noise)
    if isinstance(made, str):
        print(f"symplan {command}: the goal was not built: {made}", file=sys.stderr)
        return NegativeAnswer({"status": "not_built", "reason": made})
    return made[0]


def cmd_goal(args: argparse.Namespace) -> dict:
    from drake_symplan.cli.world_cmds import load_scene_file

    check_output_file(args.out, "--out")
    start = load_scene_file(args.start)
    structures = checked_specs(start, args.specs)

    from drake_symplan.world.scenes import save_scene

    made = built_goal(start, structures, args.backend, args.camera_noise, args.reproducible)
    out = {"start": str(args.start), "specs": [s.text() for s in structures],
           "backend": args.backend}
    if isinstance(made, str):
        out.update(status="not_built", reason=made)
        if not args.json:
            print(f"not built: {made}")
        return NegativeAnswer(out)
    goal, info = made
    header = "\n".join([f"goal: {'; '.join(out['specs'])}", f"built from {args.start} by the "
                        f"{args.backend}: {', '.join(info['actions'])}"])
    save_scene(goal, args.out, header)
    out.update(status="built", goal=str(args.out), **info)
    if not args.json:
        print(f"{args.out}: {'; '.join(out['specs'])} in {len(info['actions'])} action(s)")
    return out
