"""`symplan curve` end to end on toy data: every point of both explorers, smaller points as
views of the larger sets, the table in order, and a second run that redoes nothing."""

from __future__ import annotations

import json

import pytest

from drake_symplan.pipelines.learning_curve import LearningCurve
from drake_symplan.pipelines.scales import Scale

TINY = Scale(sizes=(100, 150), random_only=(200,), multi_seed=(150,), seeds=(0, 1),
             heldout=100, objects="2-3", chunk_size=50, epochs=5, patience=3,
             min_count=3, operator_problems=2,
             active=("--warmup", "100", "--round-size", "50", "--members", "2",
                     "--round-epochs", "3", "--episode-length", "4"))


@pytest.mark.slow
def test_the_curve_measures_every_point_once_on_the_same_held_out_set(tmp_path):
    curve = LearningCurve(TINY, tmp_path / "curve", say=lambda text: None)
    curve.run()
    table = json.loads((curve.results / "curve.json").read_text())["points"]
    assert list(table) == ["random_100", "random_150", "random_200", "active_100",
                           "active_150"]
    assert [table[k]["seeds"] for k in table] == [1, 2, 1, 1, 2]
    for name in table:
        explorer, size = name.split("_")
        report = json.loads((curve.run_dir(explorer, int(size), 0) / "bundle_effect/eval.json")
                            .read_text())
        assert report["data"] == str(curve.heldout_data)
        # Selective scores count situations in the point's own training data.
        assert report["familiar_data"] == str(curve.run_dir(explorer, int(size), 0) / "data")
        assert [row["min_seen"] for row in report["selective"]][:2] == [1, 2]
    small, large = (sorted(p.resolve() for p in (curve.run_dir("active", n, 0) / "data")
                           .glob("shard-*.npz")) for n in (100, 150))
    assert len(small) == 2 and large[:2] == small  # 100 is the head of the 150 set
    manifest = json.loads((curve.data("active") / "manifest.json").read_text())
    assert [r["round"] for r in manifest["active_rounds"]] == [1]
    md = (curve.results / "curve.md").read_text()
    assert md.index("| random 200 |") < md.index("| active 100 |")
    assert "seen >= 10x: coverage / precision" in md
    assert (curve.results / "curve.png").stat().st_size > 0
    again = LearningCurve(TINY, tmp_path / "curve", say=lambda text: None)
    again.run()
    assert again.log and all(entry.get("skipped") for entry in again.log)
