"""`symplan collect`, `symplan data stats`, `head` and `join`: exploration data sets."""

from __future__ import annotations

import argparse

from drake_symplan.cli.options import (
    add_camera_noise_argument,
    add_device_argument,
    add_json_argument,
    add_robot_argument,
    check_device,
    check_output_dir,
    fraction_lost,
    nonnegative_float,
    positive_float,
    positive_int,
    probability,
    relevance_radius,
    seed,
)


def register(subparsers) -> None:
    collect = subparsers.add_parser(
        "collect", help="collect exploration transitions (random or active; resumable, parallel)")
    add_robot_argument(collect, default="hand")
    collect.add_argument("--transitions", type=positive_int, required=True, help="how many in all (exactly); rerun with a larger N to extend a collection")
    collect.add_argument("--workers", type=positive_int, default=None,
                         help="worker processes (default: one per CPU; with --ray, one per "
                         "CPU of the Ray cluster)")
    collect.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                         help="run the workers on Ray: on this machine (no ADDRESS) or on "
                         "the cluster whose head is at ADDRESS (HOST:PORT); needs .[ray]")
    collect.add_argument("--out", required=True, help="data set directory")
    collect.add_argument("--seed", type=seed, default=0,
                         help="seed of scenes and actions (chunk c draws from seed and c)")
    add_data_arguments(collect)
    add_exploration_arguments(collect)
    collect.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_json_argument(collect)
    collect.set_defaults(func=cmd_collect)

    data = subparsers.add_parser("data", help="data set tools")
    data_sub = data.add_subparsers(dest="data_command", required=True)
    stats = data_sub.add_parser("stats", help="summary of a collected data set")
    stats.add_argument("dir", help="data set directory (shards + manifest.json)")
    stats.add_argument("--verify", action="store_true",
                       help="read every byte of every shard and name each missing, stray or "
                       "damaged one (exit 1 if any)")
    add_json_argument(stats)
    stats.set_defaults(func=cmd_data_stats)
    head = data_sub.add_parser(
        "head", help="a view of a data set's first N transitions (links, no copy)")
    head.add_argument("dir", help="data set directory (shards + manifest.json)")
    head.add_argument("--transitions", type=positive_int, required=True,
                      help="how many: a whole number of shards (chunks are seeded by their "
                      "index, so the view is what `collect --transitions N` would make)")
    head.add_argument("--out", required=True, help="the view's directory")
    add_json_argument(head)
    head.set_defaults(func=cmd_data_head)
    join = data_sub.add_parser(
        "join", help="a view of several data sets' transitions, one after the other "
        "(links, no copy), to train on them together")
    join.add_argument("dirs", nargs="+", metavar="dir", help="complete data sets, in order")
    join.add_argument("--out", required=True, help="the view's directory")
    add_json_argument(join)
    join.set_defaults(func=cmd_data_join)


def add_data_arguments(collect) -> None:
    """--recipe and the options that override it: what the data set holds (CollectConfig)."""
    collect.add_argument("--recipe", default=None, metavar="NAME",
                         help="a data recipe of configs/recipes.yaml: paper, the shipped "
                         "model's kind of data (what `reproduce` and `curve` collect); "
                         "shipped, its very set (to extend it); current, the present world; "
                         "vicinity, relevance by vicinity; bridges, vicinity with starts "
                         "that hold two towers side by side and a long block (5-6 boxes); "
                         "bridges_table, the same with two cubes side by side (3-4 boxes). "
                         "Options given here override the recipe; without one, each option "
                         "has the default shown")
    # The data's options default to None, so that an option given overrides the recipe.
    collect.set_defaults(backend=None, camera_noise=None)
    collect.add_argument("--objects", default=None,
                         help="objects per scene: N or MIN-MAX (default 2-4)")
    collect.add_argument("--episode-length", type=positive_int, default=None,
                         help="actions per episode before a new scene (default 10)")
    collect.add_argument("--long-fraction", type=probability, default=None,
                         help="chance that an object is a long block rather than a cube "
                         "(default 0.5)")
    collect.add_argument("--chunk-size", type=positive_int, default=None,
                         help="transitions per shard (default 100)")
    collect.add_argument("--noise-sigma", type=nonnegative_float, default=None,
                         help="depth noise (m) (default 0)")
    collect.add_argument("--noise-dropout", type=fraction_lost, default=None,
                         help="fraction of depth pixels lost (default 0)")
    add_camera_noise_argument(collect)
    collect.add_argument("--hand-twin", choices=("on", "off"), default=None,
                         help="on (default): the hand carries as the arm does where they "
                              "differ (the careful carry's points; a twin arm for what the "
                              "arm's wrist or fingers would touch): the data tell the truth "
                              "about the arm, at about half the speed; off: the hand alone, "
                              "as the shipped model's data (--recipe paper)")
    collect.add_argument("--time-step", type=positive_float, default=None,
                         help="physics step (s) (default 0.01); 0.005 extends a collection "
                              "made before 10 ms became the step")
    collect.add_argument("--relevance", type=relevance_radius, default=None,
                         metavar="contact|vicinity|METRES",
                         help="which objects a transition records beside the action's "
                              "arguments: contact (default, the paper's rule) or vicinity "
                              "(surfaces within 3.5 cm), or a radius in metres")
    collect.add_argument("--box-modulus", type=positive_float, default=None,
                         help="the boxes' hydroelastic modulus (Pa) (default 1e6); the "
                              "shipped model's data had stiffer boxes (--recipe paper)")


def add_exploration_arguments(collect) -> None:
    """--explorer and the active explorer's settings."""
    explore = collect.add_argument_group(
        "exploration", "how actions are chosen (explorers/active.py); random stays the "
        "default, and held-out sets stay random")
    explore.add_argument("--explorer", choices=("random", "active"), default=None,
                         help="random (default): uniform actions; active: rounds of actions "
                         "chosen where the robot expects to learn most")
    explore.add_argument("--warmup", type=positive_int, default=1000,
                         help="active: random transitions before the first round")
    explore.add_argument("--round-size", type=positive_int, default=1000,
                         help="active: transitions per round (the explorer is learned "
                         "again after each)")
    explore.add_argument("--mix", type=probability, nargs=2, default=(0.2, 0.4),
                         metavar=("P_RANDOM", "P_GOAL"),
                         help="active: shares of random actions and babbled goals; the "
                         "rest by ensemble disagreement")
    explore.add_argument("--members", type=positive_int, default=3,
                         help="active: effect models in the ensemble (>= 2)")
    explore.add_argument("--round-epochs", type=positive_int, default=30,
                         help="active: training epochs per round (warm start)")
    add_device_argument(explore, "active: where each round's ensemble trains")


def parse_objects(text: str) -> tuple[int, int]:
    try:
        lo, _, hi = text.partition("-")
        lo_i, hi_i = int(lo), int(hi or lo)
    except ValueError as e:
        raise ValueError(f"--objects must be N or MIN-MAX, got {text!r}") from e
    return lo_i, hi_i


def collect_config(args: argparse.Namespace):
    """The CollectConfig the options ask for: --recipe's settings (none: CollectConfig's
    defaults), the data options given on top."""
    import dataclasses

    from drake_symplan.data.collect import CollectConfig
    from drake_symplan.data.recipes import recipe

    given = {"backend": args.backend, "episode_length": args.episode_length,
             "long_fraction": args.long_fraction, "chunk_size": args.chunk_size,
             "noise_sigma": args.noise_sigma, "noise_dropout": args.noise_dropout,
             "time_step": args.time_step, "camera_noise": args.camera_noise,
             "box_modulus": args.box_modulus, "explorer": args.explorer,
             "relevance_radius": args.relevance,
             "hand_twin": None if args.hand_twin is None else args.hand_twin == "on"}
    if args.objects is not None:
        given["min_objects"], given["max_objects"] = parse_objects(args.objects)
    settings = {**(recipe(args.recipe) if args.recipe is not None else {}),
                **{k: v for k, v in given.items() if v is not None}}
    if settings.get("explorer") == "active":
        from drake_symplan.explorers.active import ActiveConfig

        settings["active"] = dataclasses.asdict(ActiveConfig(
            warmup=args.warmup, round_size=args.round_size, p_random=args.mix[0],
            p_goal=args.mix[1], members=args.members, epochs=args.round_epochs))
    return CollectConfig(**settings, transitions=args.transitions, seed=args.seed)


def cmd_collect(args: argparse.Namespace) -> dict:
    import sys

    from drake_symplan.data.collect import collect
    from drake_symplan.data.stats import format_stats

    config = collect_config(args)
    check_output_dir(args.out)
    if config.explorer == "active":
        check_device(args.device)
        from drake_symplan.explorers.rounds import collect_active

        summary = collect_active(args.out, config, workers=args.workers,
                                 progress=not args.no_progress, ray_address=args.ray,
                                 say=lambda text: print(text, file=sys.stderr),
                                 device=args.device)
    else:
        summary = collect(args.out, config, workers=args.workers,
                          progress=not args.no_progress, ray_address=args.ray)
    if not args.json:
        run = summary["this_run"]
        print(format_stats(summary))
        print(f"this run: {run['new_transitions']} new transitions in {run['wall_seconds']} s "
              f"({run['rate_per_s']}/s, {run['workers']} {run['engine']} workers)")
    return summary


def cmd_data_stats(args: argparse.Namespace) -> dict:
    from drake_symplan.data.stats import dataset_stats, format_stats

    if args.verify:
        return _verify(args)
    stats = dataset_stats(args.dir)
    if not args.json:
        print(format_stats(stats))
    return stats


def _complete_sources(dirs, out) -> list:
    """The data sets a view is made of, each a complete collection other than `out`; a
    CommandError naming the first that is not."""
    from pathlib import Path

    from drake_symplan.cli.main import CommandError
    from drake_symplan.data.storage import read_manifest

    sources = [Path(d) for d in dirs]
    for source in sources:
        if not (source / "manifest.json").is_file():
            raise CommandError(f"no data set at {source} (no manifest.json)")
        if Path(out).resolve() == source.resolve():
            raise CommandError("--out must differ from the data set it views")
        if read_manifest(source).get("status") != "complete":
            raise CommandError(f"{source} is not a complete collection")
    return sources


def cmd_data_head(args: argparse.Namespace) -> dict:
    from drake_symplan.cli.main import CommandError
    from drake_symplan.data.storage import link_head

    [source] = _complete_sources([args.dir], args.out)
    try:
        view = link_head(source, args.out, args.transitions)
    except ValueError as e:
        raise CommandError(str(e)) from e
    out = {"dir": str(source), "out": str(view), "transitions": args.transitions}
    if not args.json:
        print(f"{view}: the first {args.transitions} transitions of {source}")
    return out


def _verify(args: argparse.Namespace) -> dict:
    """`data stats --verify`: every shard read whole; the damaged ones named."""
    import sys
    from pathlib import Path

    from drake_symplan.cli.main import CommandError, NegativeAnswer
    from drake_symplan.shards import SHARD_GLOB, damaged_shards

    if not Path(args.dir).is_dir():
        raise CommandError(f"no data directory {args.dir}")
    damaged = damaged_shards(args.dir)
    out = {"dir": str(args.dir), "shards": len(list(Path(args.dir).glob(SHARD_GLOB))),
           "damaged": damaged}
    if not args.json:
        print(f"{args.dir}: {out['shards']} shard file(s), "
              f"{len(damaged) or 'none'} damaged or missing")
        for name, why in damaged.items():
            print(f"  {name}: {why}")
    if damaged:
        print(f"symplan data stats: {len(damaged)} shard(s) damaged or missing in {args.dir}; "
              "the same collect command redoes them", file=sys.stderr)
        return NegativeAnswer(out)
    return out


def cmd_data_join(args: argparse.Namespace) -> dict:
    from drake_symplan.cli.main import CommandError
    from drake_symplan.data.storage import link_join, read_manifest

    sources = _complete_sources(args.dirs, args.out)
    try:
        view = link_join(sources, args.out)
    except ValueError as e:
        raise CommandError(str(e)) from e
    out = {"dirs": [str(s) for s in sources], "out": str(view),
           "transitions": int(read_manifest(view)["transitions"])}
    if not args.json:
        print(f"{view}: the {out['transitions']} transitions of {', '.join(out['dirs'])}")
    return out
