"""The results' tables in markdown, from the JSON the evaluations write: Table I (effect
error), the operators table (symbolic-level planning) and the arm planning table, each as
mean +- std over training seeds; `write_results` puts them in a reproduction's results.md."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np

from drake_symplan.atomic import write_atomic
from drake_symplan.evaluation.planning import (
    MODES,
    plot_planning,
    read_records,
    run_label,
    summarise,
)
from drake_symplan.goals.problems import load_problems
from drake_symplan.json_files import read_json


def stat(values) -> dict:
    return {"mean": float(np.mean(values)), "std": float(np.std(values)), "n": len(values)}


def pm(s: dict, scale: float = 100.0, digits: int = 0) -> str:
    return f"{s['mean'] * scale:.{digits}f} ± {s['std'] * scale:.{digits}f}"


def _table(head: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in rows])


# --- Table I ---------------------------------------------------------------------------


def effects_markdown(models: dict) -> str:
    """`eval effects --json`'s "models": error in cm by model and object count."""
    counts = sorted({c for m in models.values() for c in m.get("by_count", {})}, key=int)
    rows = [[name, f"{m['error_cm']['mean']:.2f} ± {m['error_cm']['std']:.2f}",
             str(m["error_cm"].get("runs", len(m["runs"])))]
            + [f"{m['by_count'][c]['mean']:.2f}" if c in m.get("by_count", {}) else "–"
               for c in counts] for name, m in models.items()]
    return _table(["model", "effect error (cm)", "runs"] + [f"{c} objects" for c in counts],
                  rows)


# --- operators (`eval operators` reports of bundles in RUN_s<seed>/bundle_<learner>) -------


def collect_operator_reports(runs: Path) -> dict:
    """{(variant, learner): [report, ...]} over RUNS/*_s*/bundle_*/eval.json."""
    rows = defaultdict(list)
    for path in sorted(Path(runs).glob("*_s*/bundle_*/eval.json")):
        variant = path.parents[1].name.rsplit("_s", 1)[0]
        learner = path.parent.name.removeprefix("bundle_")
        rows[(variant, learner)].append(read_json(path))
    return rows


def summarise_operators(rows: dict) -> dict:
    """Per variant and learner, mean +- std over seeds of solved and reliability by k,
    solved by k and object count, coverage, precision and the stability report."""
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
        if all("selective" in r for r in reports):
            rows_by_seen = [{row["min_seen"]: row for row in r["selective"]} for r in reports]
            entry["selective"] = {str(n): {m: stat([rs[n][m] for rs in rows_by_seen])
                                           for m in ("coverage", "precision")}
                                  for n in rows_by_seen[0]}
        out[f"{variant}/{learner}"] = entry
    return out


SELECTIVE_SEEN = "10"  # the table's selective column: situations seen 10 times in training


def operators_markdown(table: dict) -> str:
    ks = sorted({c.split("_k")[1] for e in table.values() for c in e if c.startswith("solved_k")},
                key=int)
    selective = all(SELECTIVE_SEEN in e.get("selective", {}) for e in table.values())
    head = ["model / operators", "seeds", "operators", "coverage", "precision"]
    head += [f"seen >= {SELECTIVE_SEEN}x: coverage / precision"] if selective else []
    head += [f"solved k={k} (reliability)" for k in ks]
    rows = [[name, str(e["seeds"]), pm(e["operators"], 1), pm(e["coverage"]),
             pm(e["precision"])]
            + ([" / ".join(pm(e["selective"][SELECTIVE_SEEN][m]) for m in (
                "coverage", "precision"))] if selective else [])
            + [f"{pm(e[f'solved_k{k}'])} ({e[f'reliability_k{k}']['mean'] * 100:.0f})"
               for k in ks] for name, e in table.items()]
    return _table(head, rows)


# --- planning in the arm (`eval planning --json`) --------------------------------------


def summarise_planning(result: dict) -> dict:
    """{model: {mode: {"success", "by_objects", "by_k": stat over seeds}}}; a run's model
    is its directory name without the seed (relational_s0/bundle_effect -> relational)."""
    groups = defaultdict(lambda: defaultdict(list))
    for label, modes in result["runs"].items():
        model = label.split("/")[0].rsplit("_s", 1)[0]
        for mode, summary in modes.items():
            groups[model][mode].append(summary)
    out = {}
    for model, modes in groups.items():
        for mode, summaries in modes.items():
            entry = {"seeds": len(summaries),
                     "problems": summaries[0]["problems"],
                     "success": stat([s["success"] for s in summaries])}
            for key in ("by_objects", "by_k"):
                labels = sorted({g for s in summaries for g in s[key]}, key=int)
                entry[key] = {g: stat([s[key][g]["success"] for s in summaries if g in s[key]])
                              for g in labels}
            bands = sorted({b for s in summaries for b in s.get("by_band", {})})
            entry["by_band"] = {b: stat([s["by_band"][b]["success"] for s in summaries
                                         if b in s["by_band"]]) for b in bands}
            causes = defaultdict(int)
            for s in summaries:
                for cause, n in s["failure_causes"].items():
                    causes[cause] += n
            entry["failure_causes"] = dict(causes)
            entry["execution_symbols_reached"] = sum(
                s.get("execution_failures", {}).get("symbolic_goal_reached", 0)
                for s in summaries)
            out.setdefault(model, {})[mode] = entry
    return out


def planning_markdown(table: dict) -> str:
    ns = sorted({n for m in table.values() for e in m.values() for n in e["by_objects"]}, key=int)
    ks = sorted({k for m in table.values() for e in m.values() for k in e["by_k"]}, key=int)
    bands = list(dict.fromkeys(b for m in table.values() for e in m.values()
                               for b in e.get("by_band", {})))
    head = ["model", "execution", "seeds", "problems", "success", *bands]
    head += [f"{n} objects" for n in ns] + [f"k={k}" for k in ks] + ["failures (all seeds)"]
    rows = []
    for model, modes in table.items():
        for mode, e in modes.items():
            rows.append([model, mode.replace("_", " "), str(e["seeds"]), str(e["problems"]),
                         pm(e["success"])]
                        + [pm(e["by_band"][b]) if b in e.get("by_band", {}) else "–"
                           for b in bands]
                        + [pm(e["by_objects"][n]) if n in e["by_objects"] else "–" for n in ns]
                        + [pm(e["by_k"][k]) if k in e["by_k"] else "–" for k in ks]
                        + [failures_text(e)])
    return _table(head, rows)


def failures_text(entry: dict) -> str:
    """'execution 159 (110 with the goal's symbols), timeout 54, ...' over all seeds."""
    parts = []
    for cause, n in entry["failure_causes"].items():
        reached = entry.get("execution_symbols_reached", 0) if cause == "execution" else 0
        parts.append(f"{cause} {n}" + (f" ({reached} with the goal's symbols)" if reached
                                        else ""))
    return ", ".join(parts) or "–"


def finished_planning(rep) -> tuple[dict, str]:
    """The planning evaluation's result for results.md and a note: the stage's own
    output once it has finished; before that, the (run, mode) pairs whose every problem is
    in its records so far, summarised the same way."""
    res = rep.results
    if (res / "planning.json").exists():
        return read_json(res / "planning.json"), ""
    records = read_records(res / "planning.jsonl")
    problems = {str(Path(p["dir"])) for p in load_problems(rep.out / "problems")} \
        if (rep.out / "problems").is_dir() else set()
    groups = defaultdict(dict)
    for r in records:
        if r["problem"] in problems:
            groups[(r["run"], r["monitor"])][r["problem"]] = r
    pairs = [(run_label(run), True) for run in rep.planning_runs()]
    whole = [pair for pair in pairs if problems and len(groups[pair]) == len(problems)]
    summary = summarise([r for pair in whole for r in groups[pair].values()])
    if whole:
        plot_planning(summary, res / "planning.png")
    done = sum(len(groups[pair]) for pair in pairs)
    note = (f"Unfinished: {done} of {len(pairs) * len(problems)} solves done; the table "
            "holds the runs whose every problem is solved: "
            + (", ".join(f"{run} ({MODES[mode]})" for run, mode in whole) or "none") + ".")
    return {"runs": summary}, note


def modes_planning(rep, planning_result: dict) -> dict:
    """The planning modes compared on the same problems with the first seed's Relational
    bundle: its row of the main evaluation (monitored) and the finished mode stages
    (reproduce.Reproduction.mode_stages), as planning rows {mode: {execution: entry}}."""
    first = run_label(rep.planning_runs()[0])
    runs = defaultdict(dict)
    if first in planning_result["runs"]:
        runs[rep.solve.planning] = {k: v for k, v in planning_result["runs"][first].items()
                                    if k == MODES[True]}
    for stage in rep.mode_stages():
        if stage.done.exists():
            mode = stage.argv[stage.argv.index("--planning") + 1]
            for summary in read_json(stage.done)["runs"].values():
                runs[mode].update(summary)
    return summarise_planning({"runs": runs}) if len(runs) > 1 else {}


# --- the continuous model (`eval rollout --json`) -------------------------------------


def rollout_markdown(reports: list[dict]) -> str:
    """Position error (cm) after k actions rolled forward, mean ± std over the runs."""
    ks = sorted({k for r in reports for k in r["by_k"]}, key=int)
    rows = []
    for k in ks:
        rows_k = [r["by_k"][k] for r in reports if k in r["by_k"]]
        rows.append([k, pm(stat([x["error_cm"]["mean"] for x in rows_k]), 1, 1),
                     pm(stat([x["error_cm"]["median"] for x in rows_k]), 1, 1),
                     pm(stat([x["scenes_within_5cm"] for x in rows_k]))])
    return _table(["actions rolled forward", "error mean (cm)", "error median (cm)",
                   "scenes with every box within 5 cm (%)"], rows)


# --- a reproduction's results.md --------------------------------------------------------


def write_results(rep) -> Path:
    """results.md (and operators_table.json, planning_table.json, planning_modes_table.json)
    of a reproduce.Reproduction."""
    res = rep.results
    effects = read_json(res / "effects.json")
    operators = summarise_operators(collect_operator_reports(rep.out / "runs"))
    planning_result, planning_note = finished_planning(rep)
    planning = summarise_planning(planning_result)
    modes = modes_planning(rep, planning_result)
    write_atomic(res / "operators_table.json", json.dumps(operators, indent=1))
    write_atomic(res / "planning_table.json", json.dumps(planning, indent=1))
    write_atomic(res / "planning_modes_table.json", json.dumps(modes, indent=1))
    rollouts = [read_json(st.done) for st in rep.rollout_stages()
                if st.done.exists()]
    s = rep.scale
    text = "\n".join([
        f"# Results: `symplan reproduce --scale {rep.name}`", "",
        f"Training data: {s.train} hand transitions (seed {s.train_seed}, {s.objects} objects); "
        f"held-out: {s.heldout} (seed {s.heldout_seed}). Seeds {list(s.seeds)}; "
        "mean ± std over seeds. Provenance: provenance.json.", "",
        "## Effect prediction (Table I), test split", "", effects_markdown(effects["models"]),
        "", "![effects](effects.png)", "",
        "## Planning at the symbolic level, held-out episodes (% solved by Fast Downward)", "",
        operators_markdown(operators), "",
        *([f"## The continuous model on the held-out episodes, Relational ({len(rollouts)} "
           "seeds)", "", rollout_markdown(rollouts), ""] if rollouts else []),
        f"## Planning in the arm, {s.planning_problems} problems per object count "
        f"(% within 5 cm)", "", *([planning_note, ""] if planning_note else []),
        planning_markdown(planning), "", "![planning](planning.png)", "",
        *([f"### Planning modes on the same problems, Relational seed {s.planning_seeds[0]} "
           "(oracle: the problems' own actions replayed open loop)", "",
           planning_markdown(modes), ""] if modes else [])])
    path = res / "results.md"
    write_atomic(path, text)
    return path
