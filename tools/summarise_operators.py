"""Summarise `symplan eval operators` reports of runs (tools/operators_table.sh) into the
operators table: per variant and learner, mean +- std over seeds of solved (by k), plan
reliability, coverage and precision; markdown on stdout, JSON with --out.

    python tools/summarise_operators.py runs/ops_hand50k_s12 [--out table.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from drake_symplan.pipelines.results_tables import (
    collect_operator_reports,
    operators_markdown,
    summarise_operators,
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=Path)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    table = summarise_operators(collect_operator_reports(args.runs))
    if args.out:
        args.out.write_text(json.dumps(table, indent=1))
    print(operators_markdown(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
