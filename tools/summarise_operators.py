"""Summarise `symplan eval operators` reports of runs (tools/operators_table.sh) into the
operators table: per variant and learner, mean +- std over seeds of solved (by k), plan
reliability, coverage and precision; markdown on stdout, JSON with --out.

    python tools/summarise_operators.py runs/ops_hand50k_s12 [--out table.json]
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np


def collect(runs: Path) -> dict:
    rows = defaultdict(list)
    for path in sorted(runs.glob("*_s*/bundle_*/eval.json")):
        variant = path.parents[1].name.rsplit("_s", 1)[0]
        learner = path.parent.name.removeprefix("bundle_")
        rows[(variant, learner)].append(json.loads(path.read_text()))
    return rows


def stat(values) -> dict:
    return {"mean": float(np.mean(values)), "std": float(np.std(values)), "n": len(values)}


def summarise(rows: dict) -> dict:
    out = {}
    for (variant, learner), reports in sorted(rows.items()):
        ks = sorted(reports[0]["by_k"], key=int)
        entry = {"seeds": len(reports), "operators": stat([r["operators"] for r in reports]),
                 "coverage": stat([r["coverage"] for r in reports]),
                 "precision": stat([r["precision"] for r in reports])}
        for k in ks:
            entry[f"solved_k{k}"] = stat([r["by_k"][k]["solved"] for r in reports])
            entry[f"reliability_k{k}"] = stat([r["by_k"][k]["reliability"] for r in reports])
        by_n = defaultdict(list)
        for r in reports:
            for key, cell in r["by_k_objects"].items():
                by_n[key].append(cell["solved"])
        entry["solved_by_k_objects"] = {k: stat(v) for k, v in sorted(by_n.items())}
        entry["stability"] = {k: stat([r["stability"][k] for r in reports])
                              for k in reports[0]["stability"]}
        out[f"{variant}/{learner}"] = entry
    return out


def markdown(table: dict) -> str:
    ks = sorted({c.split("_k")[1] for e in table.values() for c in e if c.startswith("solved_k")},
                key=int)
    head = ["model / operators", "seeds", "operators", "coverage", "precision"]
    head += [f"solved k={k} (reliability)" for k in ks]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def pm(s, pct=True):
        f = 100 if pct else 1
        return f"{s['mean'] * f:.0f} ± {s['std'] * f:.0f}"

    for name, e in table.items():
        cells = [name, str(e["seeds"]), pm(e["operators"], False), pm(e["coverage"]),
                 pm(e["precision"])]
        cells += [f"{pm(e[f'solved_k{k}'])} ({e[f'reliability_k{k}']['mean'] * 100:.0f})"
                  for k in ks]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=Path)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    table = summarise(collect(args.runs))
    if args.out:
        args.out.write_text(json.dumps(table, indent=1))
    print(markdown(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
