"""`symplan bundle`: a trained run (or the hand-made symbols) and the operators learned on
its symbols as one model directory, or a continuous model or goal patterns added to one.

    symplan bundle --run RUN --data DIR --out BUNDLE [--generalize TOL --bystanders]
    symplan bundle --run BUNDLE --data DIR --out NEW --extend BUNDLE

Heavy imports happen inside the command functions.
"""

from __future__ import annotations

from pathlib import Path

from drake_symplan.cli.main import CommandError
from drake_symplan.cli.options import (
    LEARNERS,
    add_json_argument,
    check_input_dir,
    check_output_dir,
    nonnegative_float,
    positive_int,
    probability,
)


def register_bundle(subparsers) -> None:
    b = subparsers.add_parser(
        "bundle",
        help="make a model bundle: a trained run and its learned operators in one directory",
        description="Reads the symbols of a data set's whole scenes out of RUN (or, with "
        "--symbols handmade, the hand-made reference symbols long and on), learns "
        "operators (effect-first by default; 'paper': the paper's method as implemented) and "
        "writes the bundle (model.pt, operators.json, domain.pddl, domain_strips.pddl, "
        "provenance.json) that `symplan solve` and `symplan eval operators` read.")
    b.add_argument("--run", type=Path, help="trained run directory, or a model bundle (its "
                   "model.pt; required unless --symbols or --continuous is added to an "
                   "existing bundle)")
    b.add_argument("--symbols", choices=("handmade",), default=None,
                   help="instead of --run: symbols made by hand (learning/handmade.py: "
                   "long, on, from the features), the ceiling of symbols of this kind")
    b.add_argument("--data", type=Path,
                   help="data set collected with whole scenes (the run's training set)")
    b.add_argument("--out", type=Path, required=True, help="bundle directory to write")
    b.add_argument("--continuous", type=Path, nargs="+", default=None, metavar="RUN",
                   help="trained runs whose models bilevel planning rolls forward "
                   "(continuous.pt; several: an ensemble, its disagreement the uncertainty); "
                   "without --run, added to the bundle in --out as it is")
    b.add_argument("--learner", choices=LEARNERS, default="effect", metavar="LEARNER",
                   help="one of %(choices)s: effect, effect-first operators with "
                   "reliabilities; paper, the paper's method as implemented (default effect)")
    b.add_argument("--min-count", type=positive_int, default=10,
                   help="transitions an operator needs (default 10)")
    b.add_argument("--support", type=probability, default=0.95,
                   help="effect learner: share of a group a precondition holds in (0.95)")
    b.add_argument("--contact-degree", choices=("on", "off"), default="on",
                   help="effect learner: states hold each object's contact degree "
                   "(touching0..3: 'nothing else touches ?o0'); off: more coverage and "
                   "precision, no operator can require that (default on)")
    b.add_argument("--patterns", action="store_true",
                   help="also read the goal relations (on, bears, beside) in the symbols "
                   "from --data's scenes (patterns.json, symbolic/relation_patterns.py); "
                   "without --run, added to the bundle in --out")
    b.add_argument("--margin", type=nonnegative_float, default=3.0,
                   help="a bit is uncertain when |logit| < margin (default 3)")
    b.add_argument("--generalize", type=probability, default=None, metavar="TOLERANCE",
                   help="effect learner: drop each unary precondition of the target and the "
                   "other objects whose absence costs the operator at most TOLERANCE of its "
                   "reliability on the data (symbolic/generalize.py; default: keep them all)")
    b.add_argument("--bystanders", action="store_true",
                   help="with --generalize: also drop each object no effect names (a box "
                   "that only stood near), with every precondition on it, on the same test")
    b.add_argument("--extend", type=Path, default=None, metavar="BUNDLE",
                   help="keep BUNDLE's operators and goal patterns as they are and add those "
                   "learned here whose effect relates the moved box to two others (a "
                   "block laid across two supports); --run must be BUNDLE's model")
    add_json_argument(b)
    b.set_defaults(func=cmd_bundle)


def cmd_bundle(args) -> dict:
    import shlex
    import shutil
    import sys

    from drake_symplan.data.storage import relevance_radius
    from drake_symplan.json_files import read_json
    from drake_symplan.learning.checkpoint import load_run
    from drake_symplan.learning.handmade import HANDMADE_RULE, HandmadeSymbols
    from drake_symplan.learning.readout import readout_scenes
    from drake_symplan.shards import fingerprint
    from drake_symplan.symbolic.bundle import learn_bundle_operators, write_bundle

    check_output_dir(args.out)
    if args.symbols is not None and args.run is not None:
        raise CommandError("give --run or --symbols, not both")
    if args.run is None and args.symbols is None and (args.patterns or args.continuous):
        return _added(args)
    if (args.run is None and args.symbols is None) or args.data is None:
        raise CommandError("give --run (or --symbols) and --data (or --continuous RUN alone, "
                           "to add it to the bundle in --out)")
    check_input_dir(args.data, "--data")
    if args.bystanders and args.generalize is None:
        raise CommandError("--bystanders needs --generalize TOLERANCE")
    if args.extend is not None and args.run is None:
        raise CommandError("--extend needs --run (the bundle's own model)")
    base = _extension(args) if args.extend is not None else None
    if args.symbols is not None:
        model, source = HandmadeSymbols(), {"symbols": args.symbols, "rule": HANDMADE_RULE}
    else:
        model, source = load_run(args.run)[0], {"run": str(args.run), "run_config": (
            read_json(args.run / "config.json") if (args.run / "config.json").is_file()
            else {})}
    data, _ = readout_scenes(model, args.data, args.margin)
    operators, semantics, info = learn_bundle_operators(
        data, args.learner, args.min_count, args.support, args.contact_degree == "on",
        args.generalize, args.bystanders)
    info["relevance_radius"] = relevance_radius(args.data)
    provenance = {"command": shlex.join(["symplan", *sys.argv[1:]]), **source,
                  "data": str(args.data), "data_fingerprint": fingerprint(args.data)}
    if args.extend is not None:
        operators, info = _extended(args, base, operators, semantics, info)
        provenance["extends"] = str(args.extend)
    write_bundle(args.out, model if args.symbols else args.run, operators, semantics, info,
                 provenance, args.margin, args.continuous)
    out = {"out": str(args.out), "operators": len(operators), **info}
    if args.extend is not None and (args.extend / "patterns.json").is_file():
        shutil.copyfile(args.extend / "patterns.json", args.out / "patterns.json")
    elif args.patterns:
        out["patterns"] = _bundle_patterns(args.out, args.data)
    return out


def _extension(args):
    """--extend's bundle, loaded; CommandError where its model is not --run's."""
    from drake_symplan.learning.checkpoint import BUNDLE_MODEL
    from drake_symplan.symbolic.bundle import ModelBundle

    base = ModelBundle.load(args.extend)
    run_model = args.run / BUNDLE_MODEL if args.run.is_dir() else args.run
    if not run_model.is_file() or \
            run_model.read_bytes() != (args.extend / BUNDLE_MODEL).read_bytes():
        raise CommandError(f"--extend {args.extend}: its {BUNDLE_MODEL} is not --run's "
                           "model; give --run the bundle itself")
    return base


def _extended(args, base, learned, semantics, info) -> tuple[list, dict]:
    """--extend: `base`'s operators, and those `learned` here that span two boxes
    (symbolic/bundle.extend_operators); CommandError where its semantics are not these."""
    from drake_symplan.symbolic.bundle import extend_operators

    if base.semantics != semantics:
        raise CommandError(f"--extend {args.extend}: its operators read the symbols under "
                           "other semantics than these (--contact-degree)")
    operators = extend_operators(base.operators, learned)
    added = len(operators) - len(base.operators)
    return operators, {**base.info, "extended": {"data": str(args.data), "added": added,
                                                 "learned": info}}


def _bundle_patterns(folder: Path, data: Path) -> dict:
    """The goal relations' patterns read from `data` in the bundle in `folder`, written
    there (patterns.json); what was read."""
    from drake_symplan.shards import fingerprint
    from drake_symplan.symbolic import relation_patterns
    from drake_symplan.symbolic.bundle import ModelBundle

    kept, info = relation_patterns.read_patterns(ModelBundle.load(folder), data)
    info = {"data": str(data), "data_fingerprint": fingerprint(data),
            "min_share": relation_patterns.MIN_SHARE, "purity": relation_patterns.PURITY,
            **info}
    path = relation_patterns.save(kept, folder, info)
    return {"file": str(path), **info, "patterns": {k: len(v) for k, v in kept.items()}}




def _added(args) -> dict:
    """Without --run: --patterns read from --data, or --continuous runs, added to the
    bundle in --out."""
    from drake_symplan.learning.checkpoint import load_run
    from drake_symplan.symbolic.bundle import CONTINUOUS, ModelBundle, copy_model

    if args.continuous is None:
        if args.data is None:
            raise CommandError("--patterns needs --data (the scenes to read them in)")
        check_input_dir(args.data, "--data")
        return _bundle_patterns(args.out, args.data)
    ModelBundle.load(args.out)  # an existing bundle, or a one-line error
    for run in args.continuous:
        load_run(run)
    path = copy_model(args.continuous, args.out / CONTINUOUS)
    return {"out": str(args.out), "continuous": str(path)}
