"""Results as records kept in the repo, and the tables rendered from them.

`keep` turns one `eval planning --records` file into a small record (results/NAME.json):
per problem set its successes, the simulator's verdict beside them, the median plan
time and the failures by how their solves ended, with the settings, the command, the
code's commit, the date and the host's cores.
One record answers one question: a rerun replaces it, the old one stays in git. `render`
writes each table (a record's "table") as markdown, one column per record, one row per
problem set, with when and on what it was measured; `replace_blocks` puts the tables
between `<!-- report:NAME -->` and `<!-- /report -->` in a page, so that the README's
numbers are the records' (tests/test_report.py fails on a changed digit). `plot` draws a
table's success rate against the number of objects, a line per column
(`success_by_objects` computes its points). A block named TABLE-failures renders table
TABLE's failures by how they ended instead (`render_failures`), TABLE-nodes its median
search nodes (`render_nodes`). `keep_learning` makes a record of what a
trained run learned instead (its effect error, its operators on held-out data): its
table has a row per measure.
"""

from __future__ import annotations

import os
import re
import statistics
import subprocess
from collections import Counter, defaultdict
from datetime import date
from pathlib import Path

from drake_symplan.json_files import read_json
from drake_symplan.planning.nodes import median_nodes

# a report block's name with one of these endings renders another view of the table it
# ends: its failures by how they ended, its median search nodes
FAILURES, NODES = "-failures", "-nodes"
# how a failed solve ended (agent/verdict.py's causes), as the failures' table names it
ENDINGS = {"infeasible": "refused", "execution": "unmet", "timeout": "timed out",
           "perception": "lost from view", "no_plan": "no plan", "error": "error"}
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


def structure_of(record: dict) -> str:
    """"bridge" where the problem's goal names a bridge, else "no bridge": the record's
    spec, or (records made before they kept it) its problem.json's."""
    spec = record.get("spec")
    if spec is None:
        spec = read_json(Path(record["problem"]) / "problem.json").get("spec") or []
    return "bridge" if any(s.split()[0] == "bridge" for s in spec) else "no bridge"


def row_of(record: dict, root: str, rows: str) -> str:
    """The row a per-solve record counts in (`keep`'s `rows`)."""
    key = set_of(record["problem"], root)
    if rows == "kind":
        return key.split(os.sep)[0]
    return f"{key}, {structure_of(record)}" if rows == "structure" else key


def keep(records: list[dict], settings: dict, name: str, table: str, column: str,
         command: str, rows: str = "set", repo: Path | None = None) -> dict:
    """The record of one evaluation (`records`: its per-solve records, `settings`: its
    JSON's settings). `rows`: "set" (one row per problem set), "kind" (sets merged by
    their first folder: row4/o6 and row4/o8 are one row) or "structure" (each set split
    by whether the goal names a bridge, `structure_of`)."""
    root = settings["problems_dir"]
    sets = defaultdict(list)
    for r in records:
        sets[row_of(r, root, rows)].append(r)
    return {
        **_envelope(name, table, column, command, repo), "settings": settings,
        "sets": {key: {"problems": len(rs),
                       "success": sum(r["status"] == "success" for r in rs),
                       "success_true": sum(bool(r["success_true"]) for r in rs),
                       "objects": sorted({r["n_objects"] for r in rs}),
                       "actions": [min(r["k"] for r in rs), max(r["k"] for r in rs)],
                       "plan_seconds_median": round(statistics.median(
                           r["seconds"]["plan"] for r in rs), 2),
                       "failures": failures(rs),
                       **({} if (nodes := median_nodes(rs)) is None
                          else {"nodes_median": nodes})}
                 for key, rs in sorted(sets.items())},
    }


def failures(records: list[dict]) -> dict[str, int]:
    """The per-solve `records` that failed on the perceived verdict, counted by how their
    solve ended (its failure cause, else its status), causes in alphabetical order."""
    ended = Counter(r.get("failure_cause") or r["status"] for r in records
                    if r["status"] != "success")
    return dict(sorted(ended.items()))


def keep_learning(effects: dict, operators: dict, name: str, table: str, column: str,
                  command: str, repo: Path | None = None) -> dict:
    """The record of a trained run's learning (`effects`: `eval effects --json` of the run
    alone; `operators`: `eval operators --json` of its bundle on held-out data)."""
    run = effects["runs"][0]
    measures = {"effect error, cm (test split)": round(run["error_cm"], 2),
                "operators": operators["operators"],
                "coverage, % (held out)": round(100 * operators["coverage"], 1),
                "precision, % (held out)": round(100 * operators["precision"], 1)}
    for k, cell in operators["by_k"].items():
        measures[f"{k}-step goals solved, %"] = round(100 * cell["solved"], 1)
    return {**_envelope(name, table, column, command, repo),
            "settings": {"run": run["run"], "heldout": operators.get("data")},
            "measures": measures}


def _envelope(name: str, table: str, column: str, command: str, repo: Path | None) -> dict:
    """What every record says of itself: its question, its place in a table, when, on
    what and by which code and command it was measured."""
    return {"name": name, "table": table, "column": column,
            "measured": date.today().isoformat(), "host": {"cpus": os.cpu_count()},
            "commit": _commit(repo or Path.cwd()), "command": command}


def _render_measures(chosen: list[dict]) -> list[str]:
    names = list(dict.fromkeys(m for r in chosen for m in r["measures"]))
    lines = ["| measure | " + " | ".join(r["column"] for r in chosen) + " |",
             "|---|" + "---|" * len(chosen)]
    for m in names:
        lines.append(f"| {m} | " + " | ".join(
            str(r["measures"].get(m, "-")) for r in chosen) + " |")
    return lines


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
    for ending, view in ((FAILURES, render_failures), (NODES, render_nodes)):
        if table.endswith(ending) and not any(r["table"] == table for r in records):
            return view(records, table[:-len(ending)])
    chosen = _chosen(records, table)
    if all("measures" in r for r in chosen):
        return _finish(_render_measures(chosen), chosen, "")
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
    return _finish(lines, chosen, "; each cell: solved on the perceived verdict (on the "
                   "simulator's), median plan seconds")


def render_failures(records: list[dict], table: str) -> str:
    """The markdown table of table `table`'s failures: a row per problem set, a column
    per record that keeps them (records made before `keep` counted them are left out),
    each cell the failed solves by how they ended (ENDINGS)."""
    return _render_view(records, table, "failures", lambda s: ", ".join(
        f"{ENDINGS.get(c, c)} {n}" for c, n in s["failures"].items()) or "none",
        "the solves failed on the perceived verdict, by how they ended")


def render_nodes(records: list[dict], table: str) -> str:
    """The markdown table of table `table`'s search nodes: a row per problem set, a
    column per record that keeps them, each cell the median over the set's solves of the
    nodes their plans expanded (planning/nodes.py)."""
    return _render_view(records, table, "nodes_median", lambda s: f"{s['nodes_median']:g}",
                        "the median search nodes a solve's plans expanded")


def _render_view(records: list[dict], table: str, key: str, cell, meaning: str) -> str:
    """A view of table `table`: a row per problem set, a column per record whose every
    set keeps `key`, each cell `cell(set)` ("-" where the record lacks the set)."""
    chosen = [r for r in _chosen(records, table)
              if "sets" in r and all(key in s for s in r["sets"].values())]
    if not chosen:
        raise ValueError(f"no record of the table {table!r} keeps its {key}")
    rows = sorted({k for r in chosen for k in r["sets"]}, key=_natural)
    lines = ["| set | " + " | ".join(r["column"] for r in chosen) + " |",
             "|---|" + "---|" * len(chosen)]
    for row in rows:
        lines.append(f"| {row} | " + " | ".join(
            cell(r["sets"][row]) if row in r["sets"] else "-" for r in chosen) + " |")
    return _finish(lines, chosen, f"; each cell: {meaning}")


def _finish(lines: list[str], chosen: list[dict], cells: str) -> str:
    """The table's lines and a line saying when, where and by what it was measured."""
    when = sorted({r["measured"] for r in chosen})
    # a record made of several runs names their commits, comma-separated
    commits = sorted({c for r in chosen for c in str(r["commit"]).split(", ")})
    cpus = sorted({str(r["host"]["cpus"]) for r in chosen})
    lines.append("")
    lines.append(f"Measured {', '.join(when)} at commit {', '.join(commits)} on "
                 f"{', '.join(cpus)} CPU cores{cells}. Records: "
                 + ", ".join(f"`results/{r['name']}.json`" for r in chosen) + ".")
    return "\n".join(lines) + "\n"


def _chosen(records: list[dict], table: str) -> list[dict]:
    chosen = sorted((r for r in records if r["table"] == table), key=lambda r: r["name"])
    if not chosen:
        raise ValueError(f"no records for the table {table!r}; the records have "
                         f"{sorted({r['table'] for r in records})}")
    return chosen


def success_by_objects(records: list[dict], table: str) -> dict[str, list[tuple[int, float]]]:
    """The points of table `table`'s plot: {column: [(objects, success rate), ...]}, a
    set at its fewest objects, sets of equal objects pooled (their successes over their
    problems), objects ascending, columns in the order of their records' names."""
    pooled: dict[str, dict[int, list[int]]] = {}
    for record in _chosen(records, table):
        if "sets" not in record:
            raise ValueError(f"the table {table!r} holds measures, not problem sets")
        by_objects = pooled.setdefault(record["column"], {})
        for s in record["sets"].values():
            counts = by_objects.setdefault(min(s["objects"]), [0, 0])
            counts[0] += s["success"]
            counts[1] += s["problems"]
    return {column: [(n, success / problems) for n, (success, problems)
                     in sorted(by_objects.items()) if problems]
            for column, by_objects in pooled.items()}


def plot(records: list[dict], table: str, path: str | Path) -> Path:
    """Writes table `table`'s success rate against the number of objects to `path` (a
    PNG), a line per column; returns the path."""
    points = success_by_objects(records, table)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from drake_symplan.atomic import save_figure

    fig, ax = plt.subplots(figsize=(6, 4))
    for i, (column, xy) in enumerate(points.items()):  # lines that coincide stay apart
        ax.plot([n for n, _ in xy], [rate for _, rate in xy], label=column,
                marker="osD^v"[i % 5], linestyle=("-", "--", ":", "-.")[i % 4],
                markersize=max(3, 9 - 2 * i))
    ax.set_xticks(sorted({n for xy in points.values() for n, _ in xy}))
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("objects")
    ax.set_ylabel("success rate (perceived verdict)")
    ax.set_title(f"Table {table}: success rate by number of objects")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def _natural(key: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", key)]


def replace_blocks(text: str, records: list[dict]) -> str:
    """`text` with every report block's body rendered anew from `records`."""
    return BLOCK.sub(lambda m: m.group(1) + render(records, m.group("name")) + m.group(4),
                     text)
