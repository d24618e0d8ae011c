"""`symplan operators` (learn lifted operators, write PDDL) and `symplan plan`.

    symplan operators RUN --data DIR --out DIR      read symbols out of a trained run
    symplan operators --symbols symbols.npz --out DIR
    symplan plan --domain D --problem P --planner fd|pyperplan [--timeout S] --json

Heavy imports (numpy, the learning layer) happen inside the command functions.
"""

from __future__ import annotations

from pathlib import Path

from drake_symplan.cli.bundle_cmds import register_bundle
from drake_symplan.cli.learning_cmds import eval_subparsers
from drake_symplan.cli.main import CommandError, NegativeAnswer
from drake_symplan.cli.options import (
    add_json_argument,
    add_planner_arguments,
    check_input_dir,
    check_output_dir,
    check_output_file,
    nonnegative_int,
    planner_settings,
    positive_int,
    probability,
    seed,
)


def register(subparsers) -> None:
    _register_operators(subparsers)
    register_bundle(subparsers)
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
