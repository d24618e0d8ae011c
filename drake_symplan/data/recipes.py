"""Data recipes: named collection settings, configs/recipes.yaml, as `symplan collect
--recipe NAME` takes them.

A recipe is a mapping of CollectConfig fields (data/collect.py) other than the per-run
`transitions` and `seed`, read through typed_yaml (unknown keys and wrong types are refused
by name); `recipe_config(name, **settings)` is the CollectConfig it makes, with `settings`
(a run's transitions and seed, options given on the command line) on top and
CollectConfig's defaults for what neither names.
"""

from __future__ import annotations

from pathlib import Path

from drake_symplan.data.collect import CollectConfig
from drake_symplan.typed_yaml import check_fields, read_config

RECIPES = "recipes.yaml"
PER_RUN = ("transitions", "seed")  # a recipe leaves these to each run


def read_recipes(path: str | Path | None = None) -> dict[str, dict]:
    """Every recipe in `path` (configs/recipes.yaml when None), name -> checked settings."""
    path, data = read_config(path, RECIPES, "recipe names to settings")
    recipes = {}
    for name, settings in data.items():
        settings = check_fields(CollectConfig, settings, f"{path}: {name}")
        if per_run := sorted(set(settings) & set(PER_RUN)):
            raise ValueError(f"{path}: {name}: {per_run} are given per run, not by a recipe")
        recipes[str(name)] = settings
    return recipes


def recipe(name: str, path: str | Path | None = None) -> dict:
    """The settings of recipe `name`; a ValueError of one line naming the recipes there
    when there is none of that name."""
    recipes = read_recipes(path)
    if name not in recipes:
        raise ValueError(f"unknown data recipe {name!r}; configs/{RECIPES} has "
                         f"{sorted(recipes)}")
    return recipes[name]


def recipe_config(name: str, **settings) -> CollectConfig:
    """The collection recipe `name` makes, `settings` on top (see the module doc)."""
    return CollectConfig(**{**recipe(name), **settings})
