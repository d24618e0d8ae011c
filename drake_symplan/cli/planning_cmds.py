"""`symplan operators` (learn lifted operators, write PDDL) and `symplan plan`.

    symplan operators RUN --data DIR --out DIR      read symbols out of a trained run
    symplan operators --symbols symbols.npz --out DIR
    symplan plan --domain D --problem P --planner fd|pyperplan [--timeout S] --json

Heavy imports (numpy, the learning layer) happen inside the command functions.
"""

from __future__ import annotations

from pathlib import Path

from drake_symplan.cli.learning_cmds import eval_subparsers
from drake_symplan.cli.main import CommandError, NegativeAnswer
from drake_symplan.cli.options import (
    LEARNERS,
    add_json_argument,
    add_planner_arguments,
    check_input_dir,
    check_output_dir,
    check_output_file,
    nonnegative_float,
    nonnegative_int,
    planner_settings,
    positive_int,
    probability,
    seed,
)


def register(subparsers) -> None:
    _register_operators(subparsers)
    _register_bundle(subparsers)
    _register_eval_operators(subparsers)
    _register_eval_rollout(subparsers)
    _register_plan(subparsers)


def _register_operators(subparsers) -> None:
    p = subparsers.add_parser(
        "operators",
        help="learn lifted operators from symbolic transitions and write domain.pddl",
        description="Groups symbolic transitions into lifted operators (paper III-C) and "
        "writes domain.pddl, operators.json and report.md to --out.",
    )
    p.add_argument("run", nargs="?", type=Path, help="trained run directory (read-out source)")
    p.add_argument("--data", type=Path, help="transition data directory (with RUN)")
    p.add_argument("--symbols", type=Path, help="a saved symbolic data set (symbols.npz)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--min-count", type=nonnegative_int, default=50,
                   help="drop operators seen fewer times (default 50, as in the paper)")
    p.add_argument("--min-fraction", type=probability, default=None,
                   help="threshold relative to the data size instead of --min-count")
    p.add_argument("--self-relations", action="store_true",
                   help="keep r_k(o, o) bits as (rK ?x ?x) literals (default: ignored)")
    p.add_argument("--drop-uncertain", action="store_true",
                   help="leave out transitions with an uncertain symbol bit")
    add_json_argument(p)
    p.set_defaults(func=cmd_operators)


def _register_bundle(subparsers) -> None:
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


def add_heldout_arguments(e) -> None:
    """--model and --data of the evaluations on a held-out data set."""
    e.add_argument("--model", type=Path, default=None,
                   help="bundle directory (default: the shipped models/learned)")
    e.add_argument("--data", type=Path, required=True,
                   help="held-out data set with whole scenes (a seed the model never saw)")


def _register_eval_operators(subparsers) -> None:
    e = eval_subparsers(subparsers).add_parser(
        "operators", help="a learned domain on held-out episodes at the symbolic level",
        description="Problems from held-out episodes (start: symbols at step t, goal: at t+k, "
        "relations only between objects in contact), planned once each with the bundle's "
        "domain; solved rate, plan reliability, coverage, precision and symbol stability.")
    add_heldout_arguments(e)
    e.add_argument("--k", type=positive_int, nargs="+", default=[1, 2, 3],
                   help="steps between start and goal, one problem set each")
    e.add_argument("--max-problems", type=positive_int, default=50,
                   help="problems per k and object count (default 50)")
    add_planner_arguments(e, cpu=True)
    e.add_argument("--seed", type=seed, default=0,
                   help="seed of the choice of problems among the held-out chains")
    e.add_argument("--familiar-data", type=Path, metavar="DIR",
                   help="the model's training data: determinism (held-out effects against its "
                   "most frequent ones), and coverage and precision where what the action "
                   "met (its objects' symbols) was seen there at least N times")
    e.add_argument("--out", type=Path, help="also write the report as JSON here")
    e.add_argument("--plot", type=Path, help="write a plot (PNG) here")
    add_json_argument(e)
    e.set_defaults(func=cmd_eval_operators)


def _register_eval_rollout(subparsers) -> None:
    e = eval_subparsers(subparsers).add_parser(
        "rollout", help="the continuous model's position error after k actions, held out",
        description="Rolls the model's predicted positions forward through the recorded "
        "actions of held-out episodes (no simulator) and compares them with the scenes "
        "perceived after k actions: the error bilevel planning depends on.")
    add_heldout_arguments(e)
    e.add_argument("--k", type=positive_int, nargs="+", default=[1, 2, 3, 4, 5],
                   help="actions rolled forward, one table row each")
    e.add_argument("--run", type=Path, nargs="+", default=None,
                   help="trained runs' models (several: an ensemble) instead of the "
                   "bundle's (its continuous.pt if it has one, else its model.pt)")
    e.add_argument("--max-starts", type=positive_int, default=200,
                   help="rollouts per k, sampled with --seed (default 200)")
    e.add_argument("--seed", type=seed, default=0, help="seed of the choice of rollouts")
    add_json_argument(e)
    e.set_defaults(func=cmd_eval_rollout)


def _register_plan(subparsers) -> None:
    q = subparsers.add_parser(
        "plan",
        help="plan on positive-STRIPS PDDL with Fast Downward or pyperplan",
        description="Runs a planner on any positive-STRIPS domain and problem.",
    )
    q.add_argument("--domain", type=Path, required=True, help="PDDL domain file")
    q.add_argument("--problem", type=Path, required=True, help="PDDL problem file")
    add_planner_arguments(q)
    q.add_argument("--search", default=None,
                   help="FD --search string, or a pyperplan search name (default: optimal A*)")
    q.add_argument("--heuristic", default=None, help="pyperplan heuristic (default lmcut)")
    add_json_argument(q)
    q.set_defaults(func=cmd_plan)


def _load_symbols(args):
    from drake_symplan.datasets import SymbolDataset

    if args.symbols is not None:
        if args.run is not None or args.data is not None:
            raise ValueError("give either --symbols FILE or RUN --data DIR, not both")
        return SymbolDataset.load(args.symbols), str(args.symbols)
    if args.run is None or args.data is None:
        raise ValueError("give RUN --data DIR (a trained run and its data) or --symbols FILE")
    for path in (args.run, args.data):
        if not path.is_dir():
            raise FileNotFoundError(f"no directory {path}")
    from drake_symplan.learning.readout import readout_dataset

    return readout_dataset(args.run, args.data), f"{args.run} on {args.data}"


def cmd_operators(args) -> dict:
    from drake_symplan.symbolic.operators import LearnConfig, learn_operators
    from drake_symplan.symbolic.report import OPERATORS, write_operators

    check_output_dir(args.out)
    config = LearnConfig(args.min_count, args.min_fraction, args.self_relations,
                         args.drop_uncertain)
    data, source = _load_symbols(args)
    ops = learn_operators(data, config)
    result = write_operators(ops, data, source, args.out, save_symbols=args.symbols is None)
    if not args.json:
        print(f"{ops.n_transitions} transitions -> {ops.n_groups} groups -> "
              f"{len(ops.operators)} operators (count >= {ops.threshold}, "
              f"{100 * result['coverage']:.1f}% of transitions) in {ops.seconds:.2f} s")
        print(f"wrote {result['domain']}, {result['report']}, {args.out / OPERATORS}")
    return result


def cmd_plan(args) -> dict:
    from drake_symplan.planning.planners import plan
    from drake_symplan.symbolic.pddl import check_pddl_file

    options = {}
    if args.search is not None:
        options["search"] = args.search
    if args.heuristic is not None:
        if args.planner != "pyperplan":
            raise ValueError("--heuristic is for --planner pyperplan; give FD's in --search")
        options["heuristic"] = args.heuristic
    planner_settings(args)
    for path in (args.domain, args.problem):
        check_pddl_file(path)
    result = plan(args.domain, args.problem, args.planner, args.timeout, **options)
    if result.status == "error":  # input the planner refused, or no planner to run
        raise CommandError(f"{args.domain} and {args.problem}: {result.message}")
    out = {"status": result.status, "plan": result.plan, "seconds": result.seconds,
           "message": result.message, "planner": result.planner}
    if not args.json:
        print(f"{result.status} ({result.planner}, {result.seconds:.2f} s)"
              + (f": {result.message}" if result.message else ""))
        for step in result.plan:
            print(step)
    return out if result.solved else NegativeAnswer(out)  # unsolvable or timeout


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
    from drake_symplan.symbolic.bundle import (
        CONTINUOUS,
        ModelBundle,
        copy_model,
        learn_bundle_operators,
        write_bundle,
    )

    check_output_dir(args.out)
    if args.symbols is not None and args.run is not None:
        raise CommandError("give --run or --symbols, not both")
    if args.run is None and args.symbols is None and args.patterns \
            and args.continuous is None:
        if args.data is None:
            raise CommandError("--patterns needs --data (the scenes to read them in)")
        check_input_dir(args.data, "--data")
        return _bundle_patterns(args.out, args.data)
    if args.run is None and args.symbols is None and args.continuous is not None:
        ModelBundle.load(args.out)  # an existing bundle, or a one-line error
        for run in args.continuous:
            load_run(run)
        path = copy_model(args.continuous, args.out / CONTINUOUS)
        return {"out": str(args.out), "continuous": str(path)}
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


def cmd_eval_operators(args) -> dict:
    import json

    from drake_symplan.evaluation.operators import EvalConfig, evaluate_bundle, plot_report
    from drake_symplan.symbolic.bundle import ModelBundle

    planner_settings(args)
    check_input_dir(args.data, "--data")
    check_input_dir(args.familiar_data, "--familiar-data")
    check_output_file(args.out, "--out")
    check_output_file(args.plot, "--plot")
    bundle = ModelBundle.load(args.model)
    config = EvalConfig(ks=tuple(args.k), planner=args.planner, timeout=args.timeout,
                        max_problems=args.max_problems, seed=args.seed)
    report = evaluate_bundle(bundle, args.data, config, args.familiar_data)
    if args.out is not None:
        from drake_symplan.atomic import write_atomic

        write_atomic(args.out, json.dumps(report, indent=1))
    if args.plot is not None:
        plot_report(report, args.plot)
    if not args.json:
        print(f"{report['operators']} operators; of {report['changed']} held-out transitions "
              "whose symbols change:")
        for row in [{"min_seen": 0, **report}, *report.get("selective", [])]:
            where = f"situation seen >= {row['min_seen']}x" if row["min_seen"] else "all"
            print(f"  {where:>24}: coverage {row['coverage']:.1%}, precision "
                  f"{row['precision']:.1%} (most reliable alone {row['precision_top1']:.1%}, "
                  f"median {row['alternatives']:g} applicable)")
        if "determinism" in report:
            print(f"  determinism {report['determinism']:.1%} (the training data's most "
                  f"frequent effect in the same situation; {report['seen']:.1%} of "
                  f"situations seen in training, {report['determinism_seen']:.1%} of those)")
            for b in report["branching"][:3]:
                print(f"    branches: {b['action']} on {', '.join(b['before'])}: "
                      f"{b['heldout_misses']} held-out misses (e.g. row {b['example_row']}); "
                      f"training effects seen {[o['count'] for o in b['outcomes']]} times")
        for k, cell in report["by_k"].items():
            print(f"  k={k}: solved {cell['solved']:.0%} of {cell['problems']}")
    return report


def cmd_eval_rollout(args) -> dict:
    from drake_symplan.evaluation.rollouts import RolloutConfig, evaluate_rollouts
    from drake_symplan.symbolic.bundle import CONTINUOUS, ModelBundle

    if args.run is not None:
        from drake_symplan.learning.checkpoint import load_run

        model = [load_run(run)[0] for run in args.run]
        source = " ".join(str(run) for run in args.run)
    else:
        bundle = ModelBundle.load(args.model)
        model = bundle.continuous
        source = str(bundle.path / (CONTINUOUS if (bundle.path / CONTINUOUS).is_file()
                                    else "model.pt"))
    report = evaluate_rollouts(model, args.data,
                               RolloutConfig(tuple(args.k), args.max_starts, args.seed))
    report["model"] = source
    if not args.json:
        for k, row in report["by_k"].items():
            print(f"k={k}: {row['rollouts']} rollouts, error median {row['error_cm']['median']}"
                  f" cm (moved objects {row['moved_error_cm']['median']} cm), scenes within "
                  f"5 cm {row['scenes_within_5cm']:.0%}; sure of {row['sure_share']:.0%}, "
                  f"of those within 5 cm {row['sure_within_5cm'] or 0:.0%}")
    return report
