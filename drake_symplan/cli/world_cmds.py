"""`symplan scene sample` and `symplan act`: sample scenes, execute one pick/place."""

from __future__ import annotations

import argparse
import sys

from drake_symplan.cli.main import CommandError, NegativeAnswer
from drake_symplan.cli.options import (
    add_json_argument,
    check_output_file,
    degrees,
    positive_int,
    probability,
    seed,
)


def register(subparsers) -> None:
    scene = subparsers.add_parser("scene", help="scene files")
    scene_sub = scene.add_subparsers(dest="scene_command", required=True)
    sample = scene_sub.add_parser("sample", help="write a random valid scene")
    sample.add_argument("--objects", type=positive_int, required=True, help="number of objects (1-8)")
    sample.add_argument("--seed", type=seed, default=0, help="seed of the scene sampler")
    sample.add_argument("--long-fraction", type=probability, default=0.5,
                        help="chance that an object is a long block rather than a cube")
    sample.add_argument("--yaw-jitter-deg", type=degrees, default=0.0,
                        help="random yaw of each object, uniform in +-this many degrees")
    sample.add_argument("--out", required=True, help="scene YAML to write")
    add_json_argument(sample)
    sample.set_defaults(func=cmd_scene_sample)

    act = subparsers.add_parser("act", help="execute one pick/place in full physics")
    act.add_argument("--scene", required=True, help="scene YAML")
    act.add_argument("--pick", required=True, help="SOURCE:left|center|right")
    act.add_argument("--place", required=True, help="TARGET:left|center|right")
    act.add_argument("--meshcat", action="store_true", help="serve the live scene on localhost")
    act.add_argument("--record", help="write a self-contained HTML recording here")
    act.add_argument("--out", metavar="FILE",
                     help="write the scene after the action here (scene YAML as `symplan "
                     "scene sample` writes it, from the simulator's poses: `symplan "
                     "perceive --scene FILE` or another act can follow)")
    add_json_argument(act)
    act.set_defaults(func=cmd_act)


def cmd_scene_sample(args: argparse.Namespace) -> dict:
    import numpy as np

    from drake_symplan.world.scenes import sample_scene, save_scene

    check_output_file(args.out, "--out")
    scene = sample_scene(np.random.default_rng(args.seed), args.objects,
                         long_fraction=args.long_fraction,
                         yaw_jitter=float(np.radians(args.yaw_jitter_deg)))
    save_scene(scene, args.out)
    result = {"out": args.out, "objects": [o.name for o in scene.objects]}
    if not args.json:
        print(scene_line(args.out, scene))
    return result


def scene_line(path, scene) -> str:
    """'wrote scene.yaml: 3 objects (o0 cube, o1 long, o2 cube)'."""
    objects = ", ".join(f"{o.name} {o.type}" for o in scene.objects)
    return f"wrote {path}: {len(scene.objects)} objects ({objects})"


def load_scene_file(path: str):
    """`world.scenes.load_scene`, with a YAML syntax error told in one line naming the file."""
    import yaml

    from drake_symplan.typed_yaml import yaml_problem
    from drake_symplan.world.scenes import load_scene

    try:
        return load_scene(path)
    except ValueError as e:
        if isinstance(e.__cause__, yaml.YAMLError):
            raise CommandError(f"{path}: {yaml_problem(e.__cause__)}") from e
        raise


def cmd_act(args: argparse.Namespace) -> dict:
    from drake_symplan.actions import Action

    # Inputs first, so that bad ones are told before Drake is loaded.
    check_output_file(args.record, "--record")
    check_output_file(args.out, "--out")
    scene = load_scene_file(args.scene)
    action = Action.parse(args.pick, args.place)
    for name in (action.source, action.target):
        scene.object(name)  # clear error for an unknown name

    from drake_symplan.skills.pick_place import PickPlaceMotions, pick_place
    from drake_symplan.world.station import Station
    from drake_symplan.world.visualization import StartMeshcat, recording

    meshcat = StartMeshcat() if (args.meshcat or args.record) else None
    station = Station(meshcat=meshcat)
    planner = PickPlaceMotions()
    station.reset(scene)
    # The scene file is the caller's belief about where the objects are.
    beliefs = {o.name: _belief(o) for o in scene.objects}
    with recording(station, args.record):
        outcome = pick_place(station, planner, action, beliefs)
    result = outcome.to_json()
    if args.record:
        result["recording"] = args.record
    if not args.json:
        print(f"{action}: {outcome.status} in {outcome.seconds:.2f} s {outcome.message}")
    written = args.out is not None and _write_after(station, args.out, args.json)
    if written:
        result["out"] = args.out
    # infeasible (no IK solution) or sim_failure: the action could not be done; a scene
    # after it that is no valid scene file is not written.
    ok = outcome.status == "ok" and (args.out is None or written)
    return result if ok else NegativeAnswer(result)


def _write_after(station, path: str, quiet: bool) -> bool:
    """Writes the scene the simulator holds (the world after the action) to `path`, as
    `scene sample` writes one; False, told on stderr, when it is no valid scene."""
    from drake_symplan.world.scenes import SceneError, as_saved, save_scene, scene_from_poses

    try:
        scene = as_saved(scene_from_poses(station.object_poses(), dict(station.types)))
    except SceneError as e:
        print(f"symplan act: the scene after the action is not a valid scene file ({e}); "
              f"nothing written to {path}", file=sys.stderr)
        return False
    save_scene(scene, path)
    if not quiet:
        print(scene_line(path, scene))
    return True


def _belief(spec):
    import numpy as np

    from drake_symplan.datasets import ObjectState

    return ObjectState(spec.name, spec.type, np.asarray(spec.position, float), spec.yaw, 0.0)
