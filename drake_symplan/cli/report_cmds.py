"""`symplan report`: results kept as records in the repo, and the tables rendered from them.

    symplan report keep --records R.jsonl --eval E.json --name NAME --table TABLE \\
        --column COLUMN [--rows set|kind|structure] --command "..." [--out results/NAME.json]
    symplan report keep-learning --effects E.json --operators O.json --name NAME \\
        --table TABLE --column COLUMN --command "..." [--out results/NAME.json]
    symplan report render [--results results] [TABLE ...] [--write FILE ...] [--check FILE ...]
    symplan report plot TABLE --out FILE.png [--results results]

`keep` makes one record of an `eval planning` run (its --records file and its --json
output), `keep-learning` one of a trained run (`eval effects --json` of the run,
`eval operators --json` of its bundle); `render` prints tables, `--write` puts them between a page's
`<!-- report:TABLE -->` markers, `--check` exits 1 where a page's tables differ from the
records (evaluation/report.py); `plot` draws a table's success rate against the number of
objects, a line per column.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from drake_symplan.cli.main import CommandError, NegativeAnswer
from drake_symplan.cli.options import check_output_file


def register(subparsers) -> None:
    p = subparsers.add_parser("report", help="results kept as records, tables rendered from them",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="report_command", required=True)
    keep = sub.add_parser("keep", help="one record of an eval planning run")
    keep.add_argument("--records", required=True, type=Path, help="its --records JSONL")
    keep.add_argument("--eval", required=True, type=Path, help="its --json output")
    keep.add_argument("--rows", choices=("set", "kind", "structure"), default="set",
                      help="a row per problem set, per kind (its first folder), or per set "
                      "and structure (whether the goal names a bridge) (default set)")
    _add_record_arguments(keep)
    keep.set_defaults(func=cmd_keep)
    learned = sub.add_parser("keep-learning", help="one record of a trained run's learning")
    learned.add_argument("--effects", required=True, type=Path,
                         help="`eval effects RUN --json` of the run alone")
    learned.add_argument("--operators", required=True, type=Path,
                         help="`eval operators --model BUNDLE --json` of its bundle")
    _add_record_arguments(learned)
    learned.set_defaults(func=cmd_keep_learning)
    render = sub.add_parser("render", help="tables from the records")
    render.add_argument("tables", nargs="*", help="tables to print (default: all)")
    render.add_argument("--results", type=Path, default=Path("results"),
                        help="the folder of records (default results)")
    render.add_argument("--write", type=Path, nargs="*", default=[],
                        help="pages whose report blocks are rendered anew (default none)")
    render.add_argument("--check", type=Path, nargs="*", default=[],
                        help="pages whose report blocks must match the records, else exit 1 "
                        "(default none)")
    render.set_defaults(func=cmd_render)
    plot = sub.add_parser("plot", help="a table's success rate against the number of objects")
    plot.add_argument("table", help="the table (a record's \"table\")")
    plot.add_argument("--out", required=True, type=Path, help="the figure (a PNG) to write")
    plot.add_argument("--results", type=Path, default=Path("results"),
                      help="the folder of records (default results)")
    plot.set_defaults(func=cmd_plot)


def _add_record_arguments(p: argparse.ArgumentParser) -> None:
    """What `keep` and `keep-learning` ask of every record (report._envelope)."""
    p.add_argument("--name", required=True, help="the record's name (the question)")
    p.add_argument("--table", required=True, help="the table it is a column of")
    p.add_argument("--column", required=True, help="its column's heading")
    # dest: `command` is the subcommand's name, which error lines print
    p.add_argument("--command", required=True, dest="made_by",
                   help="the command(s) that made it")
    p.add_argument("--commit", default=None,
                   help="the code's commit the run was made at (default: HEAD now)")
    p.add_argument("--out", type=Path, default=None,
                   help="where to write it (default results/NAME.json)")


def _record_path(args: argparse.Namespace) -> Path:
    out = args.out or Path("results") / f"{args.name}.json"
    check_output_file(out, "--out")
    return out


def cmd_keep(args: argparse.Namespace) -> dict:
    from drake_symplan.evaluation.planning import read_records
    from drake_symplan.evaluation.report import keep
    from drake_symplan.json_files import read_json

    out = _record_path(args)
    settings = read_json(args.eval).get("settings")
    records = read_records(args.records)
    if not isinstance(settings, dict) or not records:
        raise CommandError(f"{args.eval} holds no eval planning settings or {args.records} "
                           "no records")
    record = keep(records, settings, args.name, args.table, args.column, args.made_by,
                  args.rows)
    _write(record, out, args.commit)
    return {"out": str(out), "sets": len(record["sets"])}


def cmd_keep_learning(args: argparse.Namespace) -> dict:
    from drake_symplan.evaluation.report import keep_learning
    from drake_symplan.json_files import read_json

    out = _record_path(args)
    effects, operators = read_json(args.effects), read_json(args.operators)
    if not (isinstance(effects, dict) and len(effects.get("runs") or ()) == 1):
        raise CommandError(f"{args.effects} is not the eval effects output of one run")
    if not (isinstance(operators, dict) and {"operators", "coverage", "precision", "by_k"}
            <= set(operators)):
        raise CommandError(f"{args.operators} is not an eval operators output")
    record = keep_learning(effects, operators, args.name, args.table, args.column,
                           args.made_by)
    _write(record, out, args.commit)
    return {"out": str(out), "measures": len(record["measures"])}


def _write(record: dict, out: Path, commit: str | None) -> None:
    if commit:
        record["commit"] = commit
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=1) + "\n")


def cmd_render(args: argparse.Namespace) -> dict:
    from drake_symplan.evaluation.report import load_records, render, replace_blocks

    records = load_records(args.results)
    if not records:
        raise CommandError(f"no records (*.json) in {args.results}")
    for page in [*args.write, *args.check]:
        if not page.is_file():
            raise CommandError(f"no page {page}")
    for page in args.write:
        page.write_text(replace_blocks(page.read_text(), records))
    stale = [str(p) for p in args.check if replace_blocks(p.read_text(), records)
             != p.read_text()]
    if not args.write and not args.check:
        tables = args.tables or sorted({r["table"] for r in records})
        for table in tables:
            try:
                print(f"## {table}\n\n{render(records, table)}", file=sys.stdout)
            except ValueError as e:
                raise CommandError(str(e)) from e
    if stale:
        print(f"symplan report: tables differ from the records in {', '.join(stale)}",
              file=sys.stderr)
        return NegativeAnswer({"stale": stale})
    return {"written": [str(p) for p in args.write], "checked": [str(p) for p in args.check]}


def cmd_plot(args: argparse.Namespace) -> dict:
    from drake_symplan.evaluation.report import load_records, plot, success_by_objects

    check_output_file(args.out, "--out")
    records = load_records(args.results)
    if not records:
        raise CommandError(f"no records (*.json) in {args.results}")
    points = success_by_objects(records, args.table)  # an unknown table: bad input
    plot(records, args.table, args.out)
    print(f"{args.out}: the table {args.table}'s success rate by objects, "
          f"{', '.join(points)}")
    return {"out": str(args.out), "table": args.table,
            "points": {column: [list(p) for p in xy] for column, xy in points.items()}}
