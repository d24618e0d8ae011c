"""Results as records kept in the repo, and the tables rendered from them.

`keep` turns one `eval planning --records` file into a small record (results/NAME.json):
per problem set its successes, the simulator's verdict beside them and the median plan
time, with the settings, the command, the code's commit, the date and the host's cores.
One record answers one question: a rerun replaces it, the old one stays in git. `render`
writes each table (a record's "table") as markdown, one column per record, one row per
problem set, with when and on what it was measured; `replace_blocks` puts the tables
between `<!-- report:NAME -->` and `<!-- /report -->` in a page, so that the README's
numbers are the records' (tests/test_report.py fails on a changed digit).
"""

from __future__ import annotations

import os
import re
import statistics
import subprocess
from collections import defaultdict
from datetime import date
from pathlib import Path

from drake_symplan.json_files import read_json

BLOCK = re.compile(r"(<!-- report:(?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- /report -->)",
                   flags=re.S)


def _commit(repo: Path) -> str | None:
    try:
        out = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def set_of(problem: str, root: str) -> str:
    """The problem set a problem folder belongs to, relative to the evaluated `root`
    (out/written/row4/o6/p003 under out/written -> row4/o6)."""
    rel = os.path.relpath(problem, root)
    parent = os.path.dirname(rel)
    return parent if parent else "."


def keep(records: list[dict], settings: dict, name: str, table: str, column: str,
         command: str, rows: str = "set", repo: Path | None = None) -> dict:
    """The record of one evaluation (`records`: its per-solve records, `settings`: its
    JSON's settings). `rows`: "set" (one row per problem set) or "kind" (sets merged by
    their first folder: row4/o6 and row4/o8 are one row)."""
    root = settings["problems_dir"]
    sets = defaultdict(list)
    for r in records:
        key = set_of(r["problem"], root)
        sets[key.split(os.sep)[0] if rows == "kind" else key].append(r)
    return {
        "name": name, "table": table, "column": column, "measured": date.today().isoformat(),
        "host": {"cpus": os.cpu_count()}, "commit": _commit(repo or Path.cwd()),
        "command": command, "settings": settings,
        "sets": {key: {"problems": len(rs),
                       "success": sum(r["status"] == "success" for r in rs),
                       "success_true": sum(bool(r["success_true"]) for r in rs),
                       "objects": sorted({r["n_objects"] for r in rs}),
                       "actions": [min(r["k"] for r in rs), max(r["k"] for r in rs)],
                       "plan_seconds_median": round(statistics.median(
                           r["seconds"]["plan"] for r in rs), 2)}
                 for key, rs in sorted(sets.items())},
    }


def load_records(folder: Path) -> list[dict]:
    return [read_json(p) for p in sorted(Path(folder).glob("*.json"))]


def _cell(s: dict | None) -> str:
    if s is None:
        return "-"
    return (f"{s['success']}/{s['problems']} ({s['success_true']}), "
            f"{s['plan_seconds_median']:.2f} s")


def render(records: list[dict], table: str) -> str:
    """The markdown table `table` of `records`: a row per problem set, a column per record
    (successes on the perceived verdict, the simulator's in brackets, the median plan
    seconds), and a line saying when, where and by what it was measured."""
    chosen = sorted((r for r in records if r["table"] == table), key=lambda r: r["name"])
    if not chosen:
        raise ValueError(f"no records for the table {table!r}")
    keys = sorted({k for r in chosen for k in r["sets"]}, key=_natural)
    lines = ["| set | boxes | actions | " + " | ".join(r["column"] for r in chosen) + " |",
             "|---|---|---|" + "---|" * len(chosen)]
    for key in keys:
        first = next(r["sets"][key] for r in chosen if key in r["sets"])
        objs, acts = first["objects"], first["actions"]
        boxes = str(objs[0]) if len(objs) == 1 else f"{objs[0]}-{objs[-1]}"
        acts = str(acts[0]) if acts[0] == acts[1] else f"{acts[0]}-{acts[1]}"
        lines.append(f"| {key} | {boxes} | {acts} | "
                     + " | ".join(_cell(r["sets"].get(key)) for r in chosen) + " |")
    when = sorted({r["measured"] for r in chosen})
    commits = sorted({str(r["commit"]) for r in chosen})
    cpus = sorted({str(r["host"]["cpus"]) for r in chosen})
    lines.append("")
    lines.append(f"Measured {', '.join(when)} at commit {', '.join(commits)} on "
                 f"{', '.join(cpus)} CPU cores; each cell: solved on the perceived verdict "
                 "(on the simulator's), median plan seconds. Records: "
                 + ", ".join(f"`results/{r['name']}.json`" for r in chosen) + ".")
    return "\n".join(lines) + "\n"


def _natural(key: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", key)]


def replace_blocks(text: str, records: list[dict]) -> str:
    """`text` with every report block's body rendered anew from `records`."""
    return BLOCK.sub(lambda m: m.group(1) + render(records, m.group("name")) + m.group(4),
                     text)
