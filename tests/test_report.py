"""Results rendered from records (evaluation/report.py, `symplan report`): the README's
tables are the records', to the digit."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
from conftest import assert_bad_input, run

from drake_symplan.evaluation.report import (
    BLOCK,
    keep,
    keep_learning,
    load_records,
    render,
    replace_blocks,
    success_by_objects,
)

REPO = Path(__file__).resolve().parents[1]


def solve(problem, status, k=3, plan=0.5, n=6, cause=None):
    return {"problem": problem, "status": status, "success_true": status == "success",
            "n_objects": n, "k": k, "seconds": {"plan": plan}, "failure_cause": cause}


SETTINGS = {"problems_dir": "out/w", "planning": "symbolic"}
RECORDS = [solve("out/w/row4/o6/p000", "success", plan=0.2),
           solve("out/w/row4/o8/p000", "failure", k=4, plan=0.6, n=8, cause="execution"),
           solve("out/w/tower4/o6/p000", "success", plan=0.4)]


def test_a_record_counts_each_set_and_a_table_renders_it():
    record = keep(RECORDS, SETTINGS, "w-symbolic", "w", "symbols alone", "symplan ...",
                  rows="kind")
    assert record["sets"] == {
        "row4": {"problems": 2, "success": 1, "success_true": 1, "objects": [6, 8],
                 "actions": [3, 4], "plan_seconds_median": 0.4,
                 "failures": {"execution": 1}},
        "tower4": {"problems": 1, "success": 1, "success_true": 1, "objects": [6],
                   "actions": [3, 3], "plan_seconds_median": 0.4, "failures": {}}}
    record.update(measured="2026-12-04", commit="abc1234", host={"cpus": 2})
    assert render([record], "w") == (
        "| set | boxes | actions | symbols alone |\n|---|---|---|---|\n"
        "| row4 | 6-8 | 3-4 | 1/2 (1), 0.40 s |\n| tower4 | 6 | 3 | 1/1 (1), 0.40 s |\n\n"
        "Measured 2026-12-04 at commit abc1234 on 2 CPU cores; each cell: solved on the "
        "perceived verdict (on the simulator's), median plan seconds. Records: "
        "`results/w-symbolic.json`.\n")


def test_a_table_of_failures_counts_how_each_sets_failed_solves_ended():
    records = [*RECORDS, solve("out/w/row4/o8/p001", "infeasible", n=8, cause="infeasible"),
               solve("out/w/row4/o8/p002", "timeout", n=8, cause="timeout"),
               solve("out/w/row4/o8/p003", "failure", n=8, cause="execution")]
    record = keep(records, SETTINGS, "w-symbolic", "w", "symbols alone", "symplan ...",
                  rows="kind")
    assert record["sets"]["row4"]["failures"] == {"execution": 2, "infeasible": 1,
                                                  "timeout": 1}
    record.update(measured="2026-12-06", commit="abc1234", host={"cpus": 2})
    old = {**copy.deepcopy(record), "name": "w-old", "column": "before"}
    for s in old["sets"].values():  # a record made before keep counted failures
        del s["failures"]
    assert render([record, old], "w-failures") == (
        "| set | symbols alone |\n|---|---|\n"
        "| row4 | unmet 2, refused 1, timed out 1 |\n| tower4 | none |\n\n"
        "Measured 2026-12-06 at commit abc1234 on 2 CPU cores; each cell: the solves "
        "failed on the perceived verdict, by how they ended. Records: "
        "`results/w-symbolic.json`.\n")
    with pytest.raises(ValueError, match="keeps its failures"):
        render([old], "w-failures")


def test_a_table_of_search_nodes_gives_each_sets_median():
    records = [{**r, "nodes": n} for r, n in zip(RECORDS, (40, 100, 7), strict=True)]
    record = keep(records, SETTINGS, "w-symbolic", "w", "symbols alone", "symplan ...",
                  rows="kind")
    assert [s["nodes_median"] for s in record["sets"].values()] == [70.0, 7.0]
    assert "nodes_median" not in keep(RECORDS, SETTINGS, "w-old", "w", "before", "...",
                                      rows="kind")["sets"]["row4"]  # records without counts
    record.update(measured="2026-12-06", commit="abc1234", host={"cpus": 2})
    assert render([record], "w-nodes").startswith(
        "| set | symbols alone |\n|---|---|\n| row4 | 70 |\n| tower4 | 7 |\n\n")


def test_structure_rows_split_each_set_by_whether_its_goal_names_a_bridge(tmp_path):
    import json

    old = tmp_path / "w" / "o8" / "p001"  # a record made before records kept the spec
    old.mkdir(parents=True)
    (old / "problem.json").write_text(json.dumps({"spec": ["tower o1 o0", "row o2 o3"]}))
    records = [{**solve(str(tmp_path / "w/o8/p000"), "failure", n=8),
                "spec": ["tower o1 o0", "bridge o4 o1 o2"]},
               solve(str(old), "success", n=8),
               {**solve(str(tmp_path / "w/o6/p000"), "success"), "spec": ["row o0 o1"]}]
    record = keep(records, {"problems_dir": str(tmp_path / "w")}, "s", "s", "c", "...",
                  rows="structure")
    assert {key: (s["problems"], s["success"]) for key, s in record["sets"].items()} == {
        "o6, no bridge": (1, 1), "o8, bridge": (1, 0), "o8, no bridge": (1, 1)}


EFFECTS = {"runs": [{"run": "runs/x/relational_s0", "error_cm": 0.8378}]}
OPERATORS = {"operators": 80, "coverage": 0.5123, "precision": 0.6804, "data": "held",
             "by_k": {"1": {"solved": 0.7}, "2": {"solved": 0.5667}}}


def test_a_learning_record_renders_a_row_per_measure():
    record = keep_learning(EFFECTS, OPERATORS, "n-clean", "n", "clean", "symplan ...")
    assert record["measures"] == {
        "effect error, cm (test split)": 0.84, "operators": 80,
        "coverage, % (held out)": 51.2, "precision, % (held out)": 68.0,
        "1-step goals solved, %": 70.0, "2-step goals solved, %": 56.7}
    record.update(measured="2026-12-05", commit="abc1234", host={"cpus": 2})
    assert render([record], "n").splitlines()[:4] == [
        "| measure | clean |", "|---|---|", "| effect error, cm (test split) | 0.84 |",
        "| operators | 80 |"]
    assert render([record], "n").endswith(
        "Measured 2026-12-05 at commit abc1234 on 2 CPU cores. Records: "
        "`results/n-clean.json`.\n")
    with pytest.raises(ValueError, match="holds measures"):
        success_by_objects([record], "n")


def test_keep_learning_refuses_what_is_not_its_input(tmp_path, capsys):
    import json

    effects, planning = tmp_path / "e.json", tmp_path / "p.json"
    effects.write_text(json.dumps(EFFECTS))
    planning.write_text(json.dumps({"settings": {}}))
    code, out, err = run(["report", "keep-learning", "--effects", effects, "--operators",
                          planning, "--name", "n", "--table", "n", "--column", "c",
                          "--command", "c", "--out", tmp_path / "r.json"], capsys)
    assert_bad_input(code, out, err, "symplan report keep-learning:", "is not an eval operators output")
    assert not (tmp_path / "r.json").exists()


def test_the_readme_tables_are_the_records_and_a_changed_digit_shows():
    readme = (REPO / "README.md").read_text()
    records = load_records(REPO / "results")
    assert BLOCK.search(readme), "the README has no report block"
    assert replace_blocks(readme, records) == readme
    changed = copy.deepcopy(records)
    first = next(iter(next(r for r in changed if "sets" in r)["sets"].values()))
    first["success"] = first["success"] - 1 if first["success"] else 1
    assert replace_blocks(readme, changed) != readme
    results = (REPO / "docs" / "results.md").read_text()  # its report blocks too
    assert BLOCK.search(results) and replace_blocks(results, records) == results


def made_up(name, column, sets, table="t"):
    return {"name": name, "table": table, "column": column,
            "sets": {key: {"problems": p, "success": s, "objects": objects}
                     for key, (p, s, objects) in sets.items()}}


def test_the_plot_points_pool_sets_of_equal_objects():
    records = [made_up("t-2", "search", {"o4": (4, 4, [4]), "o8": (5, 1, [8])}),
               made_up("t-1", "symbols", {"row4": (2, 1, [6, 8]), "tower4": (6, 1, [6]),
                                          "o4": (4, 0, [4]), "empty": (0, 0, [3])}),
               made_up("u-1", "other", {"o4": (1, 1, [4])}, table="u")]
    # columns in the order of the records' names; a set at its fewest objects; 6: 2 / 8
    assert success_by_objects(records, "t") == {"symbols": [(4, 0.0), (6, 0.25)],
                                                "search": [(4, 1.0), (8, 0.2)]}
    with pytest.raises(ValueError, match=r"no records for the table 'v'; the records have "
                                         r"\['t', 'u'\]"):
        success_by_objects(records, "v")


def test_report_plot_draws_a_table_from_the_records(tmp_path, capsys):
    out = tmp_path / "scale.png"
    code, stdout, err = run(["report", "plot", "scale", "--out", out, "--results",
                             REPO / "results"], capsys)
    assert code == 0 and err == "" and str(out) in stdout
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 1000
    code, stdout, err = run(["report", "plot", "nope", "--out", tmp_path / "nope.png",
                             "--results", REPO / "results"], capsys)
    assert_bad_input(code, stdout, err, "symplan report plot: error: no records for the "
                     "table 'nope'")
    assert not (tmp_path / "nope.png").exists()
