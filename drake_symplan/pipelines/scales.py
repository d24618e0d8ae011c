"""Scales: how big each stage of `symplan reproduce` and `symplan curve` is, configs/scales.yaml.

One dataclass for both pipelines; the file holds a mapping per pipeline (`reproduce`,
`curve`) of scale names to settings, read through typed_yaml. A scale names every setting
its pipeline reads (FIELDS) and no other, so a missing or misplaced key is refused by name
rather than filled in; the defaults below serve scales made in code (tests).
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

from drake_symplan.typed_yaml import check_fields, read_yaml, shipped_config

SCALES = "scales.yaml"


@dc.dataclass(frozen=True)
class Scale:
    """How big each stage is: the data, training, operators, evaluation."""

    # Both pipelines.
    recipe: str = "paper"  # the data recipe every collection uses (configs/recipes.yaml)
    heldout: int = 2000  # transitions in the held-out data set (another seed)
    objects: str = "2-4"  # objects per scene in every data set
    epochs: int = 300
    patience: int = 30
    min_count: int = 10  # effect-first operators: transitions an effect needs
    operator_problems: int = 30  # `eval operators --max-problems` (per k and object count)
    seeds: tuple[int, ...] = (0, 1, 2)  # training seeds
    train_seed: int = 12
    heldout_seed: int = 97
    problem_seed: int = 1000  # arm problems of n objects: seed problem_seed + n
    # reproduce: Table I's models on one training set, then the arm.
    train: int = 0  # transitions in the training data set
    paper_min_count: int = 50  # the paper's learner
    planning_objects: tuple[int, ...] = ()
    planning_k: tuple[int, ...] = ()
    planning_problems: int = 0  # per object count
    planning_seeds: tuple[int, ...] = ()  # training seeds whose bundles solve the arm problems
    # curve: random against active exploration by data size.
    sizes: tuple[int, ...] = ()  # both explorers
    random_only: tuple[int, ...] = ()  # random alone goes on to these (data alone buys)
    multi_seed: tuple[int, ...] = ()  # sizes trained with every seed (else the first)
    chunk_size: int = 100
    active: tuple[str, ...] = ()  # extra `collect --explorer active` options
    arm: tuple[int, int] | None = None  # (active size, random size) solved in the arm
    arm_problems: int = 30  # per object count 2, 3, 4 (k = 1-3)

    def settings(self, pipeline: str) -> dict:
        """The settings `pipeline` reads (a run's record)."""
        return {k: getattr(self, k) for k in FIELDS[pipeline]}


_BOTH = ("recipe", "heldout", "objects", "epochs", "patience", "min_count",
         "operator_problems", "seeds", "train_seed", "heldout_seed", "problem_seed")
FIELDS = {  # what each pipeline reads: every scale of it names exactly these
    "reproduce": (*_BOTH, "train", "paper_min_count", "planning_objects", "planning_k",
                  "planning_problems", "planning_seeds"),
    "curve": (*_BOTH, "sizes", "random_only", "multi_seed", "chunk_size", "active", "arm",
              "arm_problems"),
}


def read_scales(pipeline: str, path: str | Path | None = None) -> dict[str, Scale]:
    """The scales of `pipeline` in `path` (configs/scales.yaml when None), by name."""
    path = Path(path) if path is not None else shipped_config(SCALES)
    data = read_yaml(path)
    if not isinstance(data, dict) or not isinstance(data.get(pipeline), dict):
        raise ValueError(f"{path}: expected a mapping {pipeline}: {{NAME: settings}}")
    scales = {}
    for name, settings in data[pipeline].items():
        source = f"{path}: {pipeline}: {name}"
        fields = check_fields(Scale, settings, source)
        missing = [k for k in FIELDS[pipeline] if k not in fields]
        others = [k for k in fields if k not in FIELDS[pipeline]]
        if missing or others:
            raise ValueError(f"{source}: " + "; ".join(
                [f"missing {missing}"] * bool(missing) + [f"not read by {pipeline}: {others}"]
                * bool(others)))
        scales[str(name)] = Scale(**fields)
    return scales


def load_scale(pipeline: str, scale: str | Scale) -> tuple[str, Scale]:
    """(name, Scale) of `scale`: a name in configs/scales.yaml, or a Scale as it is ("custom");
    an unknown name is a ValueError of one line naming the scales there."""
    if isinstance(scale, Scale):
        return "custom", scale
    scales = read_scales(pipeline)
    if scale not in scales:
        raise ValueError(f"unknown scale {scale!r}; expected one of {sorted(scales)}")
    return scale, scales[scale]
