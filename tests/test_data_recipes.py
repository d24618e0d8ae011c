"""Data recipes (configs/recipes.yaml, data/recipes.py): `paper` is the shipped model's kind
of data, options given override it, an unknown name is one line, and a collection made with
it records those settings in its manifest."""

from __future__ import annotations

import json

import pytest
from conftest import assert_bad_input, run

from drake_symplan.data.collect import CollectConfig
from drake_symplan.data.recipes import read_recipes, recipe, recipe_config

# What models/learned/ was trained on (docs/data.md): random actions of the hand alone, boxes
# of modulus 1e7, 2-4 objects; the shipped set itself at the older 5 ms step.
PAPER = {"backend": "hand", "hand_twin": False, "box_modulus": 1e7, "time_step": 0.01,
         "min_objects": 2, "max_objects": 4, "episode_length": 10, "long_fraction": 0.5,
         "chunk_size": 100, "noise_sigma": 0.0, "noise_dropout": 0.0, "camera_noise": "none",
         "explorer": "random", "relevance_radius": 0.006}


def test_a_recipe_loads_into_the_collection_config():
    assert recipe("paper") == PAPER
    assert recipe("shipped") == {**PAPER, "time_step": 0.005}
    config = recipe_config("paper", transitions=200, seed=12)
    assert config == CollectConfig(**PAPER, transitions=200, seed=12)
    assert isinstance(config.box_modulus, float) and config.active == {}
    # current: what no recipe makes, CollectConfig's defaults.
    assert recipe_config("current", transitions=200) == CollectConfig(transitions=200)


def test_the_bridges_recipe_starts_from_towers_side_by_side_and_needs_five_boxes():
    config = recipe_config("bridges", transitions=10)
    episode = config.episode_config()
    assert (episode.start, episode.min_objects, episode.max_objects, episode.length) == \
        ("towers", 5, 6, 3)
    assert episode.relevance_radius == 0.035  # vicinity: the other tower top is relevant
    with pytest.raises(ValueError, match="min_objects >= 5"):
        recipe_config("bridges", transitions=10, min_objects=4)
    with pytest.raises(ValueError, match="unknown start 'stacks'"):
        CollectConfig(start="stacks")
    table = recipe_config("bridges_table", transitions=10).episode_config()
    assert (table.start, table.min_objects, table.max_objects) == ("cubes", 3, 4)
    with pytest.raises(ValueError, match="min_objects >= 3"):
        recipe_config("bridges_table", transitions=10, min_objects=2)


def test_a_recipe_is_checked_against_the_config_fields(tmp_path):
    path = tmp_path / "recipes.yaml"
    path.write_text("fast:\n  backend: hand\n  box_modulus: stiff\n")
    with pytest.raises(ValueError, match="recipes.yaml: fast: box_modulus: expected a finite "
                                         "float, got str 'stiff'"):
        read_recipes(path)
    path.write_text("fast:\n  transitions: 10\n")
    with pytest.raises(ValueError, match=r"fast: \['transitions'\] are given per run"):
        read_recipes(path)


def test_an_unknown_recipe_is_one_line_and_exit_2(tmp_path, capsys):
    out_dir = tmp_path / "data"
    code, out, err = run(["collect", "--recipe", "nope", "--transitions", "10", "--out",
                          out_dir], capsys)
    assert_bad_input(code, out, err, "symplan collect: error: unknown data recipe 'nope'; "
                     "configs/recipes.yaml has ['bridges', 'bridges_table', 'current', 'paper', "
                     "'shipped', 'vicinity']")
    assert not out_dir.exists()


def test_options_given_override_the_recipe(tmp_path, capsys, monkeypatch):
    from drake_symplan.data import collect

    asked = []
    monkeypatch.setattr(collect, "collect", lambda out, config, **kw: asked.append(config)
                        or {"this_run": {}})
    argv = ["collect", "--transitions", "200", "--out", tmp_path / "d", "--json"]
    assert run([*argv, "--recipe", "paper"], capsys)[0] == 0
    assert run([*argv, "--recipe", "paper", "--time-step", "0.005"], capsys)[0] == 0
    assert run([*argv, "--recipe", "paper", "--hand-twin", "on", "--objects", "3"],
               capsys)[0] == 0
    assert run(argv, capsys)[0] == 0  # no recipe: CollectConfig's defaults
    assert asked == [recipe_config("paper", transitions=200),
                     recipe_config("shipped", transitions=200),
                     recipe_config("paper", transitions=200, hand_twin=True, min_objects=3,
                                   max_objects=3),
                     CollectConfig(transitions=200)]


@pytest.mark.slow  # about a minute on 2 cores
def test_collect_with_the_paper_recipe_writes_its_settings(tmp_path, capsys):
    out_dir = tmp_path / "data"
    code, out, _ = run(["collect", "--recipe", "paper", "--transitions", "200", "--out",
                        out_dir, "--workers", "1", "--no-progress", "--json"], capsys)
    assert code == 0 and json.loads(out)["transitions"] == 200
    manifest = json.loads((out_dir / "manifest.json").read_text())
    assert manifest["status"] == "complete"
    assert manifest["config"] == {**PAPER, "transitions": 200, "seed": 0, "active": {},
                                  "start": "random"}
