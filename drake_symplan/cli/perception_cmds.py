"""`symplan perceive`: perceive a scene with the depth cameras, compared with ground truth,
or from depth frames on disk (`symplan frames record`'s, or a real camera's)."""

from __future__ import annotations

import argparse
from pathlib import Path

from drake_symplan.cli.main import CommandError
from drake_symplan.cli.options import (
    add_camera_noise_argument,
    add_json_argument,
    fraction_lost,
    nonnegative_float,
    seed,
)

SETTLE = 0.5  # physics seconds before looking


def register(subparsers) -> None:
    p = subparsers.add_parser("perceive", help="perceive a scene with the depth cameras")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--scene", help="scene YAML: perceived by the simulator's cameras")
    source.add_argument("--frames", type=Path, metavar="DIR",
                        help="a folder of depth frames (symplan frames record's, or a real "
                        "camera's: perception/frames.py says the format)")
    p.add_argument("--noise", type=nonnegative_float, default=0.0, help="depth noise sigma (m)")
    p.add_argument("--dropout", type=fraction_lost, default=0.0, help="fraction of pixels lost")
    p.add_argument("--settle", type=nonnegative_float, default=None,
                   help=f"physics seconds before looking (default {SETTLE}; not with --frames)")
    add_camera_noise_argument(p)
    p.add_argument("--seed", type=seed, default=0,
                   help="seed of the depth noise and of the cameras' calibration error")
    add_json_argument(p)
    p.set_defaults(func=cmd_perceive)


def cmd_perceive(args: argparse.Namespace) -> dict:
    if args.frames is not None:
        return perceive_frames(args)
    import time

    import numpy as np

    from drake_symplan.cli.world_cmds import load_scene_file

    scene = load_scene_file(args.scene)  # before Drake is loaded: bad input is told fast

    from drake_symplan.evaluation.perception import compare
    from drake_symplan.perception.perceive import Perceiver
    from drake_symplan.world.cameras import DepthNoise, default_cameras
    from drake_symplan.world.station import Station, StationConfig

    station = Station(StationConfig(cameras=default_cameras(), camera_noise=args.camera_noise,
                                    camera_seed=args.seed))
    station.reset(scene)
    station.settle(SETTLE if args.settle is None else args.settle)
    perceiver = Perceiver()
    noise = DepthNoise(args.noise, args.dropout)
    rng = np.random.default_rng(args.seed)
    perceiver.perceive(station, noise, rng)  # first render initialises the renderer
    t = time.perf_counter()
    perceived = perceiver.perceive(station, noise, rng)
    seconds = time.perf_counter() - t
    # Ground truth only to report errors; nothing above used it.
    report = compare(perceived, station.object_states(), station.contact_graph())
    objects = []
    for o in perceived.objects:
        d = o.to_json()
        d["matched"] = report["match"].get(o.name)
        objects.append(d)
    result = {
        "objects": objects,
        "contacts": sorted([list(c) for c in perceived.contacts]),
        "errors": report["errors"],
        "count_ok": report["count_ok"],
        "contacts_ok": report["contacts_ok"],
        "seconds": round(seconds, 4),
    }
    if station.sensor.active:  # what each camera's sensor gave and the filter kept
        result = {"camera_noise": args.camera_noise,
                  "sensor": [r.to_json() for r in perceiver.readings], **result}
    if not args.json:
        print_perceived(result)
    return result


def perceive_frames(args: argparse.Namespace) -> dict:
    """`symplan perceive --frames DIR`: the same pipeline on the folder's depth images."""
    import time

    import numpy as np

    if args.camera_noise != "none" or args.settle is not None:
        raise CommandError("--camera-noise and --settle are the recording's, not with --frames "
                           "(the camera files say the sensor)")
    from drake_symplan.perception.frames import BadFrames, read_frames
    from drake_symplan.perception.perceive import Perceiver
    from drake_symplan.world.cameras import DepthNoise

    try:
        views = read_frames(args.frames)
    except BadFrames as e:
        raise CommandError(str(e)) from e
    perceiver = Perceiver()
    t = time.perf_counter()
    perceived = perceiver.perceive_views(views, DepthNoise(args.noise, args.dropout),
                                         np.random.default_rng(args.seed))
    seconds = time.perf_counter() - t
    result = {"frames": str(args.frames),
              "objects": [o.to_json() for o in perceived.objects],
              "contacts": sorted([list(c) for c in perceived.contacts]),
              "seconds": round(seconds, 4)}
    if views.sensor.active:
        result["sensor"] = [r.to_json() for r in perceiver.readings]
    if not args.json:
        print_perceived(result)
    return result


def print_perceived(result: dict) -> None:
    for d in result["objects"]:
        matched = f" -> {d['matched']}" if "matched" in d else ""
        print(f"{d['name']} {d['type']:5s} {d['position']} yaw={d['yaw_deg']} "
              f"tilt={d['tilt_deg']}{matched}")
    for r in result.get("sensor", []):
        print(f"camera {r['camera']}: {r['returns']} returns, {r['holes']} holes, "
              f"{r['kept']} points kept, table tilt {r['table_tilt_deg']} deg")
    print(f"contacts: {result['contacts']}  ({result['seconds'] * 1000:.1f} ms)")
