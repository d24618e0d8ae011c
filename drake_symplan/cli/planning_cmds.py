"""`symplan operators` (learn lifted operators, write PDDL) and `symplan plan`.

    symplan operators RUN --data DIR --out DIR      read symbols out of a trained run
    symplan operators --symbols symbols.npz --out DIR
    symplan plan --domain D --problem P --planner fd|pyperplan [--timeout S] --json

Heavy imports (numpy, the learning layer) happen inside the command functions.
"""

from __future__ import annotations

from pathlib import Path

from drake_symplan.cli.main import CommandError, NegativeAnswer


def register(subparsers) -> None:
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
    p.add_argument("--min-count", type=int, default=50,
                   help="drop operators seen fewer times (default 50, as in the paper)")
    p.add_argument("--min-fraction", type=float, default=None,
                   help="threshold relative to the data size instead of --min-count")
    p.add_argument("--self-relations", action="store_true",
                   help="keep r_k(o, o) bits as (rK ?x ?x) literals (default: ignored)")
    p.add_argument("--drop-uncertain", action="store_true",
                   help="leave out transitions with an uncertain symbol bit")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=cmd_operators)

    q = subparsers.add_parser(
        "plan",
        help="plan on positive-STRIPS PDDL with Fast Downward or pyperplan",
        description="Runs a planner on any positive-STRIPS domain and problem.",
    )
    q.add_argument("--domain", type=Path, required=True)
    q.add_argument("--problem", type=Path, required=True)
    q.add_argument("--planner", choices=("fd", "pyperplan"), default="fd")
    q.add_argument("--timeout", type=float, default=10.0, help="seconds (default 10)")
    q.add_argument("--search", default=None,
                   help="FD --search string, or a pyperplan search name (default: optimal A*)")
    q.add_argument("--heuristic", default=None, help="pyperplan heuristic (default lmcut)")
    q.add_argument("--json", action="store_true", help="print the result as JSON")
    q.set_defaults(func=cmd_plan)


def _load_symbols(args):
    from drake_symplan.structs import SymbolDataset

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
    if not args.timeout > 0:
        raise CommandError(f"--timeout must be positive, got {args.timeout:g}")
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
