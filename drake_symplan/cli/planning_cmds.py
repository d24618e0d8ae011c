"""`symplan operators` (learn lifted operators, write PDDL) and `symplan plan`.

    symplan operators RUN --data DIR --out DIR      read symbols out of a trained run
    symplan operators --symbols symbols.npz --out DIR
    symplan plan --domain D --problem P --planner fd|pyperplan [--timeout S] --json

Heavy imports (numpy, the learning layer) happen inside the command functions.
"""

from __future__ import annotations

import json
from pathlib import Path


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
    from drake_symplan.symbolic.pddl import domain_pddl

    config = LearnConfig(args.min_count, args.min_fraction, args.self_relations,
                         args.drop_uncertain)
    data, source = _load_symbols(args)
    ops = learn_operators(data, config)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.symbols is None:
        data.save(args.out / "symbols.npz")
    domain = args.out / "domain.pddl"
    domain.write_text(domain_pddl(ops.operators, ops.n_unary, ops.n_relations,
                                  n_transitions=ops.n_transitions))
    result = {
        "source": source,
        "domain": str(domain),
        "report": str(args.out / "report.md"),
        **ops.summary(),
        "thresholds": ops.threshold_report(),
    }
    full = dict(result, operators=[op.to_dict() for op in ops.operators])
    (args.out / "operators.json").write_text(json.dumps(full, indent=2))
    (args.out / "report.md").write_text(report_markdown(ops, data, source))
    if not args.json:
        print(f"{ops.n_transitions} transitions -> {ops.n_groups} groups -> "
              f"{len(ops.operators)} operators (count >= {ops.threshold}, "
              f"{100 * result['coverage']:.1f}% of transitions) in {ops.seconds:.2f} s")
        print(f"wrote {domain}, {args.out / 'report.md'}, {args.out / 'operators.json'}")
    return result


def report_markdown(ops, data, source: str) -> str:
    """A readable report: thresholds, then operators by frequency with an example."""
    from drake_symplan.symbolic.operators import example_action
    from drake_symplan.symbolic.states import SymbolicState

    s = ops.summary()
    lines = [
        "# Learned operators",
        "",
        f"Source: {source}. {s['n_transitions']} transitions"
        + (f" ({s['n_dropped_uncertain']} uncertain ones dropped)" if s["n_dropped_uncertain"]
           else "")
        + f", {s['n_groups']} groups; groups seen at least {s['threshold']} times give "
        f"{s['n_operators']} operators covering {100 * s['coverage']:.1f}% of the transitions. "
        f"Self-relations {'kept' if s['self_relations'] else 'ignored'}. "
        f"Learning took {s['seconds']:.2f} s.",
        "",
        "## What other thresholds would keep",
        "",
        "| by | threshold | fraction of data | operators | coverage |",
        "|---|---|---|---|---|",
    ]
    for row in ops.threshold_report():
        lines.append(f"| {row['by']} | {row['threshold']} | {row['fraction']:.2e} | "
                     f"{row['operators']} | {100 * row['coverage']:.1f}% |")
    lines += ["", "## Operators by frequency", ""]
    for op in ops.operators:
        add, delete = op.effects()
        lines += [
            f"### {op.index}. `{op.name}`",
            "",
            f"pick(?o0:{op.grasp}) place(?o1:{op.release}); {op.count} transitions, this "
            f"effect in {op.effect_count} of them ({op.n_effects} distinct effect(s)); "
            f"parameters: ?o0 source, ?o1 target"
            + (f", {' '.join(op.params[2:])} in contact" if op.n_params > 2 else "") + ".",
            "",
            "- preconditions: " + " ".join(f"({' '.join(a)})" for a in op.preconditions()
                                          if a[0] != "different"),
            "- add: " + (" ".join(f"({' '.join(a)})" for a in add) or "(none)"),
            "- delete: " + (" ".join(f"({' '.join(a)})" for a in delete) or "(none)"),
        ]
        if op.example >= 0:
            t, slots = op.example, list(op.example_slots)
            names = [f"o{i}" for i in slots]
            before = SymbolicState(tuple(names), data.unary[t][slots],
                                   data.relational[t][:, slots][:, :, slots])
            after = SymbolicState(tuple(names), data.next_unary[t][slots],
                                  data.next_relational[t][:, slots][:, :, slots])
            changed = sorted(set(after.facts(ops.self_relations))
                             - set(before.facts(ops.self_relations)))
            lines.append(
                f"- example: transition {t}, {example_action(op)} (objects named by slot: "
                + ", ".join(f"?o{i}={n}" for i, n in enumerate(names)) + "); became "
                + (" ".join(f"({' '.join(a)})" for a in changed) or "nothing new")
            )
        lines.append("")
    return "\n".join(lines)


def cmd_plan(args) -> dict:
    from drake_symplan.planning.planners import plan

    options = {}
    if args.search is not None:
        options["search"] = args.search
    if args.heuristic is not None:
        if args.planner != "pyperplan":
            raise ValueError("--heuristic is for --planner pyperplan; give FD's in --search")
        options["heuristic"] = args.heuristic
    result = plan(args.domain, args.problem, args.planner, args.timeout, **options)
    out = {"status": result.status, "plan": result.plan, "seconds": result.seconds,
           "message": result.message, "planner": result.planner}
    if not args.json:
        print(f"{result.status} ({result.planner}, {result.seconds:.2f} s)"
              + (f": {result.message}" if result.message else ""))
        for step in result.plan:
            print(step)
    return out
