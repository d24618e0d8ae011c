"""Scales (configs/scales.yaml, pipelines/scales.py): one dataclass for `reproduce` and
`curve`, each scale naming exactly the settings its pipeline reads."""

from __future__ import annotations

import pytest
import yaml

from drake_symplan.pipelines.learning_curve import LearningCurve
from drake_symplan.pipelines.reproduce import Reproduction
from drake_symplan.pipelines.scales import FIELDS, Scale, load_scale, read_scales


def test_a_scale_loads_for_reproduce_and_for_curve(tmp_path):
    name, small = load_scale("reproduce", "small")
    assert name == "small" and small == Scale(
        recipe="paper", train=1500, heldout=300, objects="2-3", epochs=40, patience=10,
        min_count=5, paper_min_count=5, operator_problems=8, planning_objects=(2,),
        planning_k=(1,), planning_problems=3, planning_seeds=(0,), seeds=(0, 1, 2),
        train_seed=12, heldout_seed=97, problem_seed=1000)
    assert Reproduction("small", tmp_path).scale == small
    _, paper = load_scale("curve", "paper")
    assert paper == Scale(
        recipe="paper", sizes=(5000, 10000, 25000, 50000), random_only=(100000,),
        multi_seed=(25000, 50000), seeds=(0, 1, 2), heldout=2000, objects="2-4",
        chunk_size=100, epochs=300, patience=30, min_count=10, operator_problems=30,
        active=(), arm=(25000, 50000), arm_problems=30, train_seed=12, heldout_seed=97,
        problem_seed=3000)
    assert LearningCurve("paper", tmp_path).scale == paper
    assert set(paper.settings("curve")) == set(FIELDS["curve"])
    assert sorted(read_scales("curve")) == ["paper", "session", "small"]
    # Every collection of both pipelines uses the scale's data recipe.
    assert Reproduction("small", tmp_path).collect_stages()[0].argv[1:3] == ["--recipe",
                                                                            "paper"]
    assert LearningCurve("paper", tmp_path).collect_stage(None, 10).argv[1:3] == [
        "--recipe", "paper"]


def test_a_scale_missing_a_setting_or_with_another_pipelines_is_refused(tmp_path):
    path = tmp_path / "scales.yaml"
    settings = {k: list(v) if isinstance(v, tuple) else v
                for k, v in load_scale("curve", "small")[1].settings("curve").items()
                if k not in ("arm", "active")}
    path.write_text(yaml.safe_dump({"curve": {"toy": {**settings, "train": 5}}}))
    with pytest.raises(ValueError, match=r"curve: toy: missing \['active', 'arm'\]; not read "
                                         r"by curve: \['train'\]"):
        read_scales("curve", path)


def test_an_unknown_scale_is_one_line(tmp_path):
    with pytest.raises(ValueError, match=r"unknown scale 'huge'; expected one of \['paper', "
                                         r"'session', 'small'\]"):
        LearningCurve("huge", tmp_path)
