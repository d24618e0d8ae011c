"""What `symplan operators` writes: domain.pddl, operators.json and a readable report.md.

`write_operators(ops, data, source, out_dir)` writes all three (and the symbols the
operators were learned from, when asked) and returns the summary the command prints.
"""

from __future__ import annotations

import json
from pathlib import Path

from drake_symplan.atomic import write_atomic
from drake_symplan.datasets import SymbolDataset
from drake_symplan.symbolic.bundle import operators_json
from drake_symplan.symbolic.effect_operators import PAPER
from drake_symplan.symbolic.operators import OperatorSet, example_action
from drake_symplan.symbolic.pddl import domain_pddl
from drake_symplan.symbolic.states import SymbolicState

DOMAIN = "domain.pddl"
OPERATORS = "operators.json"
REPORT = "report.md"
SYMBOLS = "symbols.npz"


def write_operators(ops: OperatorSet, data: SymbolDataset, source: str, out_dir: str | Path,
                    save_symbols: bool = False) -> dict:
    """Writes domain.pddl, operators.json, report.md (and `data` as symbols.npz when
    `save_symbols`) to `out_dir`, each atomically; returns the summary: source, the
    paths, `ops.summary()` and its threshold report (operators.json adds the operators)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if save_symbols:
        data.save(out_dir / SYMBOLS)
    domain = write_atomic(out_dir / DOMAIN, domain_pddl(
        ops.operators, ops.n_unary, ops.n_relations, n_transitions=ops.n_transitions))
    result = {
        "source": source,
        "domain": str(domain),
        "report": str(out_dir / REPORT),
        **ops.summary(),
        "thresholds": ops.threshold_report(),
    }
    full = operators_json(ops.operators, PAPER, result)
    write_atomic(out_dir / OPERATORS, json.dumps(full, indent=2))
    write_atomic(out_dir / REPORT, report_markdown(ops, data, source))
    return result


def report_markdown(ops: OperatorSet, data: SymbolDataset, source: str) -> str:
    """A readable report: thresholds, then operators by frequency with an example."""
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
            f"effect in {op.effect_count} of them ({op.outcomes} distinct effect(s)); "
            f"parameters: ?o0 source, ?o1 target"
            + (f", {' '.join(op.params[2:])} in contact" if op.n_params > 2 else "") + ".",
            "",
            "- preconditions: " + " ".join(a.pddl() for a in op.preconditions()
                                          if a[0] != "different"),
            "- add: " + (" ".join(a.pddl() for a in add) or "(none)"),
            "- delete: " + (" ".join(a.pddl() for a in delete) or "(none)"),
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
                + (" ".join(a.pddl() for a in changed) or "nothing new")
            )
        lines.append("")
    return "\n".join(lines)
