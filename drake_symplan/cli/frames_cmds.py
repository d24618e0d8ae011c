"""`symplan frames record`: a scene's depth frames on disk, every camera's 16-bit PNGs (mm)
and camera file in one folder (perception/frames.py), which `symplan perceive --frames`
reads as a real camera's."""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
from pathlib import Path

from drake_symplan.cli.main import CommandError
from drake_symplan.cli.options import (
    add_camera_noise_argument,
    add_json_argument,
    check_output_dir,
    nonnegative_float,
    seed,
)
from drake_symplan.cli.perception_cmds import SETTLE


def register(subparsers) -> None:
    frames = subparsers.add_parser("frames", help="depth frames on disk: record a scene's")
    sub = frames.add_subparsers(dest="frames_command", required=True)
    record = sub.add_parser(
        "record", help="write every camera's depth images (16-bit PNG, mm) and camera file "
        "(intrinsics, pose in the world) of a scene into one folder")
    record.add_argument("--scene", required=True, help="scene YAML")
    record.add_argument("--out", required=True, type=Path, metavar="DIR",
                        help="the folder to write (new, or empty)")
    record.add_argument("--settle", type=nonnegative_float, default=SETTLE,
                        help="physics seconds before looking")
    add_camera_noise_argument(record)
    record.add_argument("--seed", type=seed, default=0,
                        help="seed of the sensor's noise and of the cameras' calibration error")
    add_json_argument(record)
    record.set_defaults(func=cmd_frames_record)


def cmd_frames_record(args: argparse.Namespace) -> dict:
    from drake_symplan.cli.world_cmds import load_scene_file

    out = Path(args.out)
    check_output_dir(out)
    if out.is_dir() and any(out.iterdir()):
        raise CommandError(f"--out {out} is not empty")
    scene = load_scene_file(args.scene)  # before Drake is loaded: bad input is told fast

    from drake_symplan.perception.depth_filter import DepthFilter
    from drake_symplan.perception.frames import write_frames
    from drake_symplan.perception.perceive import station_views
    from drake_symplan.world.cameras import default_cameras
    from drake_symplan.world.station import Station, StationConfig

    station = Station(StationConfig(cameras=default_cameras(), camera_noise=args.camera_noise,
                                    camera_seed=args.seed))
    station.reset(scene)
    station.settle(args.settle)
    views = station_views(station, DepthFilter().frames)
    written = write_atomically(out, lambda folder: write_frames(views, folder))
    result = {"out": str(out), "camera_noise": args.camera_noise, "cameras": written,
              "robot_shapes": len(views.robot_shapes)}
    if not args.json:
        for name, images in written.items():
            print(f"{name}: {name}.yaml, {', '.join(images)}")
        print(f"wrote {len(written)} cameras' frames to {out}")
    return result


def write_atomically(out: Path, write):
    """`write(folder)` into a new folder beside `out`, renamed to `out` when done: a
    failure leaves nothing."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        result = write(tmp)
        if out.is_dir():
            out.rmdir()  # empty: checked before
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return result
