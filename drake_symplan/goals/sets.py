"""Evaluation problem sets as data: configs/problem_sets.yaml, as `symplan problems make
--set NAME --out DIR` makes them.

A set is a name, a comment saying what it asks, and a list of subsets; a subset is one
plain `problems make` (goals/problems.py make_problems) under DIR/FOLDER: its task, object
count, k list, count, seed, share of long blocks, attempts and back-end. The file is read
through typed_yaml: unknown keys, missing ones and values out of range are ValueErrors of
one line naming the file, the set, the subset and the key. Reading it imports no Drake;
`make_set` makes a set's subsets in turn, each resuming as the plain command does.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable, Collection
from pathlib import Path, PurePosixPath

from drake_symplan.goals.sampling import TASKS
from drake_symplan.typed_yaml import check_fields, read_config
from drake_symplan.world.scene_model import MAX_OBJECTS

PROBLEM_SETS = "problem_sets.yaml"


@dc.dataclass(frozen=True)
class Subset:
    """One plain `problems make` of a set, under the set's folder / `folder`."""

    folder: str  # relative path: tower4/o6
    objects: int
    k: tuple[int, ...]  # actions per problem, taken in turn
    count: int  # problems to keep
    seed: int
    task: str | None = None  # a kind of structure goal (goals/sampling.py); None: random
    long_fraction: float = 0.5  # the share of long blocks among the start's boxes
    max_attempts: int | None = None  # None: 20 x count
    backend: str = "arm"

    def arguments(self, out_dir: str | Path) -> dict:
        """The keyword arguments of goals.problems.make_problems that make this subset
        under `out_dir` (the set's folder)."""
        return {"out_dir": Path(out_dir) / self.folder, "n_objects": self.objects,
                "k": list(self.k), "count": self.count, "seed": self.seed,
                "backend": self.backend, "max_attempts": self.max_attempts,
                "task": self.task, "long_fraction": self.long_fraction}


@dc.dataclass(frozen=True)
class ProblemSet:
    """A named evaluation set: what it asks, and its subsets."""

    name: str
    comment: str
    subsets: tuple[Subset, ...]


@dc.dataclass(frozen=True)
class _SetFields:  # a set's mapping in the file, checked by typed_yaml
    comment: str
    subsets: list


_REQUIRED = ("folder", "objects", "k", "count", "seed")


def _subset_problem(s: Subset) -> tuple[str, str] | None:
    """(key, what is wrong) for the first value of `s` out of range, else None."""
    path = PurePosixPath(s.folder)
    checks = (
        ("folder", not s.folder or path.is_absolute() or ".." in path.parts
         or "\\" in s.folder, f"a relative path inside the set's folder, got {s.folder!r}"),
        ("objects", not 2 <= s.objects <= MAX_OBJECTS,
         f"in [2, {MAX_OBJECTS}], got {s.objects}"),
        ("k", not s.k or min(s.k) < 1, f"a non-empty list of integers >= 1, got {list(s.k)}"),
        ("k", s.task is not None and s.k and max(s.k) > 2 * s.objects,
         f"at most {2 * s.objects} (a structure of {s.objects} boxes), got {max(s.k or [0])}"),
        ("count", s.count < 1, f">= 1, got {s.count}"),
        ("seed", s.seed < 0, f">= 0, got {s.seed}"),
        ("task", s.task is not None and s.task not in TASKS,
         f"one of {list(TASKS)} or null, got {s.task!r}"),
        ("long_fraction", not 0 <= s.long_fraction <= 1,
         f"a probability in [0, 1], got {s.long_fraction}"),
        ("max_attempts", s.max_attempts is not None and s.max_attempts < 1,
         f">= 1 or null, got {s.max_attempts}"),
    )
    return next(((key, what) for key, bad, what in checks if bad), None)


def _read_subset(data: object, source: str, backends: Collection[str] | None) -> Subset:
    fields = check_fields(Subset, data, source)
    if missing := [key for key in _REQUIRED if key not in fields]:
        raise ValueError(f"{source}: missing keys {missing}")
    subset = Subset(**fields)
    if problem := _subset_problem(subset):
        raise ValueError(f"{source}: {problem[0]}: expected {problem[1]}")
    if backends is not None and subset.backend not in backends:
        raise ValueError(f"{source}: backend: expected one of {sorted(backends)}, got "
                         f"{subset.backend!r}")
    return subset


def read_problem_sets(path: str | Path | None = None,
                      backends: Collection[str] | None = None) -> dict[str, ProblemSet]:
    """Every set in `path` (configs/problem_sets.yaml when None), by name; with `backends`,
    each subset's back-end must be one of them (the robots' registry imports Drake)."""
    path, data = read_config(path, PROBLEM_SETS, "set names to a comment and subsets")
    sets = {}
    for name, settings in data.items():
        source = f"{path}: {name}"
        fields = check_fields(_SetFields, settings, source)
        if missing := [key for key in ("comment", "subsets") if key not in fields]:
            raise ValueError(f"{source}: missing keys {missing}")
        if not fields["subsets"]:
            raise ValueError(f"{source}: subsets: expected a non-empty list")
        subsets = tuple(_read_subset(s, f"{source}: subsets[{i}]", backends)
                        for i, s in enumerate(fields["subsets"]))
        folders = [s.folder for s in subsets]
        if twice := sorted({f for f in folders if folders.count(f) > 1}):
            raise ValueError(f"{source}: subsets: folder: {twice} given more than once")
        sets[str(name)] = ProblemSet(str(name), fields["comment"].strip(), subsets)
    return sets


def problem_set(name: str, path: str | Path | None = None,
                backends: Collection[str] | None = None) -> ProblemSet:
    """The set `name`; a ValueError of one line naming the sets there when there is none
    of that name."""
    sets = read_problem_sets(path, backends)
    if name not in sets:
        where = path if path is not None else f"configs/{PROBLEM_SETS}"
        raise ValueError(f"unknown problem set {name!r}; {where} has {sorted(sets)}")
    return sets[name]


def make_set(chosen: ProblemSet, out_dir: str | Path, make: Callable[..., dict] | None = None,
             progress: Callable[[Subset, dict], None] | None = None,
             **options) -> dict[str, dict]:
    """Makes every subset of `chosen` under `out_dir`/FOLDER with `make` (default
    goals.problems.make_problems), `options` (reproducible, camera_noise, start_k) on
    each, in the file's order; a subset that keeps fewer than its count does not stop the
    others. Returns each subset's summary by folder; `progress(subset, summary)` after
    each."""
    if make is None:
        from drake_symplan.goals.problems import make_problems as make
    summaries = {}
    for subset in chosen.subsets:
        summaries[subset.folder] = make(**subset.arguments(out_dir), **options)
        if progress:
            progress(subset, summaries[subset.folder])
    return summaries
