"""Options several commands share: choices read from the registries, and the solve settings
(`SolveConfig`) as flags, so `solve`, `inspect`, `eval planning` and `reproduce` spell them
alike."""

from __future__ import annotations

import argparse
import importlib
import math
import os
import tempfile
from pathlib import Path

from drake_symplan.agent.config import DEFAULT_SOLVE, GOAL_CHECKS, SolveConfig
from drake_symplan.agent.planning_modes import PLANNING_MODES, mode_names
from drake_symplan.cli.main import CommandError, bounded, nonnegative_int, positive_float
from drake_symplan.cli.main import positive_int as positive_int  # the options' types, all here
from drake_symplan.planning.planners import WALL_FACTOR

# --- numbers: each option's type says its range -----------------------------------------
# A value out of range is a usage error naming the option and the rule, exit status 2:
# `symplan collect: error: argument --noise-dropout: must be a fraction in [0, 1), got '2'`.
# (Under them, main.Parser refuses a non-finite float or an integer past 64 bits whatever
# an option's type.)

SEED_LIMIT = 2**32  # numpy's legacy seeding, torch's and Drake's: seeds below it

nonnegative_float = bounded(float, lambda v: 0 <= v < math.inf, "a finite number >= 0")
probability = bounded(float, lambda v: 0 <= v <= 1, "a probability in [0, 1]")
# A share of pixels lost: all of them is a camera that sees nothing.
fraction_lost = bounded(float, lambda v: 0 <= v < 1, "a fraction in [0, 1)")
degrees = bounded(float, lambda v: 0 <= v <= 180, "a number of degrees in [0, 180]")
seed = bounded(int, lambda v: 0 <= v < SEED_LIMIT, "an integer seed in [0, 2**32)")
# boxes.CONTACT_TOLERANCE and boxes.VICINITY, spelled here so that the parser imports no numpy
RELEVANCE = {"contact": 0.006, "vicinity": 0.035}
_radius = bounded(float, lambda v: 0.006 <= v <= 0.1, "contact, vicinity or metres in [0.006, 0.1]")


def relevance_radius(text: str) -> float:
    """--relevance: a named rule or a radius in metres."""
    return RELEVANCE[text] if text in RELEVANCE else _radius(text)


class RegistryChoices:
    """argparse `choices` that are the keys of a registry dict, read when first needed:
    importing the registry's module loads torch (models) or Drake (robots), which a
    command that does not need them should not pay for. Give the option a `metavar`
    (argparse lists plain choices when it builds the parser) and `%(choices)s` in its
    help (read when the help is shown)."""

    def __init__(self, module: str, name: str):
        self.module, self.name = module, name

    def keys(self) -> tuple[str, ...]:
        return tuple(getattr(importlib.import_module(self.module), self.name))

    def __contains__(self, value) -> bool:
        return value in self.keys()

    def __iter__(self):
        return iter(self.keys())


PLANNERS = RegistryChoices("drake_symplan.planning.planners", "PLANNERS")
MODELS = RegistryChoices("drake_symplan.learning.models", "MODELS")
ROBOTS = RegistryChoices("drake_symplan.robot.backends", "BACKENDS")
LEARNERS = RegistryChoices("drake_symplan.symbolic.bundle", "LEARNERS")
CAMERA_NOISE = RegistryChoices("drake_symplan.world.depth_sensor", "CAMERA_NOISE")


# learning/device.py's DEVICES, spelled here so that building the parser imports no torch.
DEVICES = ("auto", "cpu", "cuda")


def add_device_argument(p, what: str, default: str | None = "auto") -> None:
    """--device: `what` is where the models train (learning/device.py)."""
    p.add_argument("--device", choices=DEVICES, default=default,
                   help=f"{what}: auto (a CUDA GPU when torch sees one, else the CPU), cpu "
                   f"or cuda (default auto)")


def check_device(name: str) -> None:
    """--device cuda on a machine without a GPU is bad input now, before any work."""
    if name != "cpu":
        from drake_symplan.learning.device import resolve_device

        resolve_device(name)


def add_json_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true",
                   help="print the result as JSON on stdout (messages go to stderr)")


def add_planner_arguments(p: argparse.ArgumentParser, per_plan: bool = False,
                          cpu: bool = False) -> None:
    """--planner and --timeout; `per_plan`: the timeout is a solve's budget per plan;
    `cpu`: each planner call's CPU seconds (else its wall-clock seconds)."""
    p.add_argument("--planner", choices=PLANNERS, default=DEFAULT_SOLVE.planner,
                   metavar="PLANNER", help="planner back-end, one of %(choices)s: fd (Fast "
                   f"Downward, A* with LM-cut), pyperplan (default {DEFAULT_SOLVE.planner})")
    cap = f", with a wall-clock cap of {WALL_FACTOR:g} times that"
    what = ("CPU seconds per plan (bilevel and continuous: the whole search's)" + cap
            if per_plan else "CPU seconds per planner call" + cap if cpu
            else "planner seconds per call")
    p.add_argument("--timeout", type=positive_float, default=DEFAULT_SOLVE.cpu_seconds,
                   help=f"{what} (default {DEFAULT_SOLVE.cpu_seconds:g})")


def add_camera_noise_argument(p: argparse.ArgumentParser) -> None:
    """--camera-noise: the station's depth-sensor model (world/depth_sensor.py)."""
    p.add_argument("--camera-noise", choices=CAMERA_NOISE, default="none", metavar="NOISE",
                   help="the depth cameras' sensor model, one of %(choices)s: none (the "
                   "rendered depth exactly), realsense (a RealSense D400: depth noise growing "
                   "with the square of the depth, holes, flying pixels, 1 mm steps, a fixed "
                   "calibration error per camera), heavy (every term doubled) (default none)")


def add_robot_argument(p: argparse.ArgumentParser, default: str = "arm") -> None:
    p.add_argument("--backend", choices=ROBOTS, default=default, metavar="ROBOT",
                   help="one of %(choices)s: arm, the UR10 in full physics; hand, the fast "
                   f"collision-free hand (default {default})")


def add_goal_spec_argument(p, built: str) -> None:
    """--goal-spec SPEC ... on `p` (a parser or a mutually exclusive group): a goal written
    in one line (goals/compiler.py), `built` saying by whom and from what."""
    p.add_argument("--goal-spec", nargs="+", metavar="SPEC", default=None,
                   help=f"a goal written in one line ('tower o3 o1 o0', docs/goals.md), {built}")


def add_planning_argument(p: argparse.ArgumentParser, oracle: bool = False) -> None:
    """--planning, an agent.planning_modes.PLANNING_MODES key; with `oracle` also the modes
    that replay the problems' recorded actions."""
    names = mode_names(recorded_actions=oracle)
    p.add_argument("--planning", choices=names, default=DEFAULT_SOLVE.planning,
                   help="; ".join(f"{n}: {PLANNING_MODES[n].help}" for n in names)
                   + f" (default {DEFAULT_SOLVE.planning})")


def add_solve_arguments(p: argparse.ArgumentParser, monitor_flag: bool = True,
                        oracle: bool = False) -> None:
    """The SolveConfig flags; `monitor_flag`: --no-monitor (eval planning has --monitor);
    `oracle`: --planning may replay the problems' recorded actions (eval planning)."""
    add_planner_arguments(p, per_plan=True)
    add_planning_argument(p, oracle)
    if monitor_flag:
        p.add_argument("--no-monitor", action="store_true",
                       help="run the first plan open loop (no replanning on a mismatch)")
    p.add_argument("--max-replans", type=nonnegative_int, default=DEFAULT_SOLVE.max_replans,
                   help=f"replans per solve at most (default {DEFAULT_SOLVE.max_replans})")
    p.add_argument("--no-refine", action="store_true",
                   help="execute each step with the offsets the planner chose and put no box "
                   "down at its goal spot (default: an interchangeable operator's offsets that "
                   "land the box nearer its goal, and such repositionings)")
    p.add_argument("--alternatives", type=nonnegative_int, default=DEFAULT_SOLVE.alternatives,
                   help="bilevel: when no skeleton refines, ask the symbolic planner for up "
                   "to this many more, each avoiding the moves of those before "
                   f"(default {DEFAULT_SOLVE.alternatives})")
    p.add_argument("--goal-check", choices=GOAL_CHECKS, default=DEFAULT_SOLVE.goal_check,
                   help="a goal written as relations (a spec) is judged by them wherever they "
                   "stand (relations), or by every box within 5 cm of the example built "
                   f"(scene, the paper's check) (default {DEFAULT_SOLVE.goal_check})")


def solve_config(args: argparse.Namespace) -> SolveConfig:
    """The SolveConfig of parsed flags; bad values are bad input."""
    try:
        return SolveConfig(args.planner, args.timeout, not getattr(args, "no_monitor", False),
                           getattr(args, "max_replans", DEFAULT_SOLVE.max_replans),
                           not getattr(args, "no_refine", False),
                           getattr(args, "planning", DEFAULT_SOLVE.planning),
                           getattr(args, "alternatives", DEFAULT_SOLVE.alternatives),
                           getattr(args, "goal_check", DEFAULT_SOLVE.goal_check))
    except ValueError as e:
        raise CommandError(str(e).replace("max_replans", "--max-replans")
                           .replace("alternatives must", "--alternatives must")
                           .replace("the planner timeout", "--timeout")) from e


def planner_settings(args: argparse.Namespace) -> tuple[str, float]:
    """(--planner, --timeout), checked as a SolveConfig checks them."""
    config = solve_config(args)
    return config.planner, config.cpu_seconds


def add_model_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", type=Path, default=None,
                   help="model bundle directory (default: the shipped models/learned/)")


def load_bundle(path: Path | None, missing: str = "no model directory"):
    """The model bundle at `path` (None: the shipped default); a directory that is not
    there (told as `missing` PATH) or a BundleError is bad input."""
    from drake_symplan.symbolic.bundle import ModelBundle, default_bundle_dir

    where = path if path is not None else default_bundle_dir()
    if not where.is_dir():
        raise CommandError(f"{missing} {where}" + (
            "" if path is not None else " (the default model is not shipped yet; give --model DIR)"))
    return ModelBundle.load(where)


def check_objects(n: int) -> int:
    """--objects of a sampled scene: from 2 to world.scenes.MAX_OBJECTS."""
    from drake_symplan.world.scenes import MAX_OBJECTS

    if not 2 <= n <= MAX_OBJECTS:
        raise CommandError(f"--objects must be in [2, {MAX_OBJECTS}], got {n}")
    return n


def load_scene_pair(start: Path, goal: Path):
    """(start, goal) scenes of --start and --goal, checked to name the same objects."""
    from drake_symplan.agent.beliefs import check_scene_pair
    from drake_symplan.cli.world_cmds import load_scene_file

    scenes = load_scene_file(start), load_scene_file(goal)
    check_scene_pair(*scenes)
    return scenes


# --- paths, checked before a command does anything ---------------------------------------


def _nearest_existing(path: Path) -> Path:
    """`path` or its nearest ancestor that exists."""
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_input_dir(path: Path | None, flag: str) -> None:
    """Bad input unless `path` (when given) is a directory; the message says which."""
    if path is not None and not Path(path).is_dir():
        what = "is not a directory" if Path(path).exists() else "does not exist"
        raise CommandError(f"{flag} {path} {what}")


def probe_writable(folder: Path, flag: str, path: Path) -> None:
    """Bad input unless a file can be made in the existing `folder` (where `flag`'s `path`
    is to be written): a probe file is created there and deleted again, so a read-only
    file system or a folder not ours is told before any work, not after it."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".symplan-probe-", dir=folder)
    except OSError as e:
        raise CommandError(f"{flag} {path} cannot be written: {folder}: "
                           f"{e.strerror or e}") from e
    os.close(fd)
    os.unlink(probe)


def check_output_dir(path: Path | str, flag: str = "--out") -> None:
    """Bad input when the directory `path` cannot be made or used: it, or a folder it
    would be made in, is a file, or nothing can be written there."""
    path = Path(path)
    found = _nearest_existing(path)
    if found == path and not path.is_dir():
        raise CommandError(f"{flag} {path} is a file, not a directory")
    if not found.is_dir():
        raise CommandError(f"{flag} {path} cannot be made (in {found}, a file)")
    probe_writable(found, flag, path)


def check_output_file(path: Path | str | None, flag: str) -> None:
    """Bad input when the file `path` (when given) cannot be written: it is a directory,
    a folder it would be written in is a file, or nothing can be written there."""
    if path is None:
        return
    path = Path(path)
    if path.is_dir():
        raise CommandError(f"{flag} {path} is a directory, not a file")
    found = _nearest_existing(path.parent)
    if not found.is_dir():
        raise CommandError(f"{flag} {path} cannot be written (in {found}, a file)")
    probe_writable(found, flag, path)
    if path.exists() and not os.access(path, os.W_OK):
        raise CommandError(f"{flag} {path} cannot be written: it is read-only")
