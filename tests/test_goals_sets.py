"""Evaluation problem sets as data (configs/problem_sets.yaml, goals/sets.py): the shipped
sets load with the values their records' commands name, a bad file is one line naming the
key, and `problems make --set` maps each subset onto the plain command (no simulation here:
make_problems is replaced by a spy)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import assert_bad_input, run

from drake_symplan.goals.sets import ProblemSet, Subset, make_set, problem_set, read_problem_sets

WRITTEN = ("tower4", "towers3", "bridge2", "row4", "bridge_towers")


def test_the_shipped_sets_load_with_their_records_values():
    sets = read_problem_sets(backends=("arm", "hand"))
    assert sorted(sets) == ["relations30", "scale", "scale16", "towers", "written"]
    written = sets["written"]
    assert isinstance(written, ProblemSet) and written.comment
    assert len(written.subsets) == 10
    # TASK outer, N inner, seeds 7001, 7002, ... in that order
    assert [(s.folder, s.seed) for s in written.subsets] == [
        (f"{task}/o{n}", 7001 + i) for i, (task, n) in
        enumerate((t, n) for t in WRITTEN for n in (6, 8))]
    assert written.subsets[0] == Subset(folder="tower4/o6", objects=6, k=(1,), count=5,
                                        seed=7001, task="tower4", long_fraction=0.5,
                                        max_attempts=30, backend="arm")
    assert [(s.folder, s.k, s.seed) for s in sets["scale"].subsets] == [
        ("o4", (2, 3), 8004), ("o8", (4, 5, 6, 7), 8008), ("o12", (6, 7, 8, 9, 10), 8012)]
    assert {(s.task, s.count, s.long_fraction, s.max_attempts, s.backend)
            for s in sets["scale"].subsets} == {("many", 10, 0.3, 40, "arm")}
    (o16,) = sets["scale16"].subsets
    assert (o16.objects, o16.k, o16.seed, o16.backend) == (16, (8, 10, 12, 14), 8016, "hand")
    assert [(s.folder, s.k, s.seed, s.count, s.max_attempts)
            for s in sets["towers"].subsets] == [("o8", (4, 5, 6), 9008, 5, 15),
                                                 ("o12", (6, 8, 10), 9012, 5, 15)]
    assert [(s.objects, s.count, s.backend) for s in sets["relations30"].subsets] == [
        (4, 30, "arm"), (6, 30, "arm"), (8, 30, "arm"), (12, 30, "arm"), (16, 30, "hand")]


def test_a_subset_is_the_plain_commands_arguments(tmp_path):
    subset = problem_set("scale16").subsets[0]
    assert subset.arguments(tmp_path) == {
        "out_dir": tmp_path / "o16", "n_objects": 16, "k": [8, 10, 12, 14], "count": 10,
        "seed": 8016, "backend": "hand", "max_attempts": 40, "task": "many",
        "long_fraction": 0.3}
    asked, seen = [], []
    summaries = make_set(problem_set("towers"), tmp_path, reproducible=True,
                         make=lambda **kw: asked.append(kw) or {"kept": 1},
                         progress=lambda s, summary: seen.append(s.folder))
    assert summaries == {"o8": {"kept": 1}, "o12": {"kept": 1}} and seen == ["o8", "o12"]
    assert [(a["out_dir"], a["seed"], a["reproducible"]) for a in asked] == [
        (tmp_path / "o8", 9008, True), (tmp_path / "o12", 9012, True)]


SUBSET = "{folder: o4, task: many, objects: 4, k: [2], count: 1, seed: 1}"


@pytest.mark.parametrize("subset, message", [
    ("{folder: o4, objects: 4, k: [2], count: 1, seed: 1, colour: red}",
     r"toy: subsets\[0\]: unknown keys \['colour'\]"),
    ("{folder: o4, objects: 4, k: [2], count: 1}", r"toy: subsets\[0\]: missing keys \['seed'\]"),
    ("{folder: o4, objects: 1, k: [2], count: 1, seed: 1}", r"subsets\[0\]: objects: expected"),
    ("{folder: o4, objects: 4, k: [], count: 1, seed: 1}", r"subsets\[0\]: k: expected"),
    ("{folder: o4, objects: 4, k: [9], count: 1, seed: 1, task: many}",
     r"k: expected at most 8"),
    ("{folder: o4, objects: 4, k: [2], count: 1, seed: 1, task: castle}", r"task: expected"),
    ("{folder: ../o4, objects: 4, k: [2], count: 1, seed: 1}", r"folder: expected a relative"),
    ("{folder: o4, objects: 4, k: [2], count: 1, seed: 1, long_fraction: 2}",
     r"long_fraction: expected a probability"),
    ("{folder: o4, objects: four, k: [2], count: 1, seed: 1}",
     r"objects: expected int, got str 'four'"),
    ("{folder: o4, objects: 4, k: [2], count: 1, seed: 1, backend: crane}",
     r"backend: expected one of \['arm', 'hand'\]"),
])
def test_a_bad_subset_is_a_value_error_naming_the_file_and_key(subset, message, tmp_path):
    path = tmp_path / "sets.yaml"
    path.write_text(f"toy:\n  comment: a toy\n  subsets:\n    - {subset}\n")
    with pytest.raises(ValueError, match=f"sets.yaml: {message}" if message.startswith("toy")
                       else message) as caught:
        read_problem_sets(path, backends=("arm", "hand"))
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_a_bad_set_is_a_value_error_naming_the_key(tmp_path):
    path = tmp_path / "sets.yaml"
    path.write_text(f"toy:\n  comment: a toy\n  asks: more\n  subsets: [{SUBSET}]\n")
    with pytest.raises(ValueError, match=r"sets.yaml: toy: unknown keys \['asks'\]"):
        read_problem_sets(path)
    path.write_text(f"toy:\n  subsets: [{SUBSET}]\n")
    with pytest.raises(ValueError, match=r"sets.yaml: toy: missing keys \['comment'\]"):
        read_problem_sets(path)
    path.write_text(f"toy:\n  comment: twice\n  subsets: [{SUBSET}, {SUBSET}]\n")
    with pytest.raises(ValueError, match=r"toy: subsets: folder: \['o4'\] given more"):
        read_problem_sets(path)
    path.write_text(f"toy:\n  comment: once\n  subsets: [{SUBSET}]\n")
    assert problem_set("toy", path).subsets[0].task == "many"
    with pytest.raises(ValueError, match=r"unknown problem set 'nope'; .*sets.yaml has "
                                         r"\['toy'\]"):
        problem_set("nope", path)


def test_an_unknown_set_is_one_line_naming_the_sets(tmp_path, capsys):
    out = tmp_path / "p"
    assert_bad_input(*run(["problems", "make", "--out", out, "--set", "nope"], capsys),
                     "symplan problems make: error: unknown problem set 'nope'; "
                     "configs/problem_sets.yaml has ['relations30', 'scale', 'scale16', 'towers', 'written']")
    assert not out.exists()


@pytest.mark.parametrize("extra, named", [
    (["--objects", "4"], "--objects"), (["--seed", "0"], "--seed"),
    (["--k", "1", "2", "--count", "3"], "--k, --count"), (["--task", "row"], "--task"),
    (["--backend", "hand"], "--backend"), (["--max-attempts", "3"], "--max-attempts"),
])
def test_set_with_the_options_it_gives_is_a_usage_error(extra, named, tmp_path, capsys):
    out = tmp_path / "p"
    assert_bad_input(*run(["problems", "make", "--out", out, "--set", "written", *extra],
                          capsys), f"error: argument --set: not allowed with {named} ")
    assert not out.exists()


def test_without_set_objects_k_and_count_are_required(tmp_path, capsys):
    assert_bad_input(*run(["problems", "make", "--out", tmp_path / "p", "--k", "2"], capsys),
                     "error: the following arguments are required without --set: "
                     "--objects, --count")
    assert list(tmp_path.iterdir()) == []


def test_set_makes_each_subset_as_the_plain_command(tmp_path, capsys, monkeypatch):
    from drake_symplan.goals import problems

    asked = []

    def make(out_dir, n_objects, k, count, seed, backend, max_attempts, **kw):
        asked.append((Path(out_dir), n_objects, k, count, seed, backend, max_attempts, kw))
        return {"settings": {}, "kept": count - (n_objects == 12), "attempts": 1,
                "rejected": {}}

    monkeypatch.setattr(problems, "make_problems", make)
    code, out, err = run(["problems", "make", "--out", tmp_path, "--set", "towers",
                          "--camera-noise", "realsense", "--json"], capsys)
    assert code == 1 and err == ""  # o12 kept fewer than its count: a negative answer
    result = json.loads(out)
    assert result["set"] == "towers" and list(result["subsets"]) == ["o8", "o12"]
    common = {"reproducible": False, "camera_noise": "realsense", "start_k": 0,
              "task": "towers", "long_fraction": 0.3}
    assert asked == [(tmp_path / "o8", 8, [4, 5, 6], 5, 9008, "arm", 15, common),
                     (tmp_path / "o12", 12, [6, 8, 10], 5, 9012, "arm", 15, common)]
