"""Random goals of a kind (`problems make --task`): a tower, a row, two towers, a bridge
on two towers, a tower beside a bridge, sampled on a start scene so that building them
takes a given number of actions (compiler.check counts them)."""

from __future__ import annotations

import numpy as np

from drake_symplan.datasets import ObjectState
from drake_symplan.goals.compiler import check
from drake_symplan.relations import Relation, SpecError

TASKS = ("tower", "row", "towers", "bridge", "mixed")  # `problems make --task`


def sample_structures(rng: np.random.Generator, objects: dict[str, ObjectState], task: str,
                      k: int) -> list[Relation] | str:
    """A random goal of `task` that takes `k` actions to build from `objects`: a tower of
    k + 1 boxes, a row of k + 1 cubes, two towers of k + 2 boxes, a bridge (`_bridge`), or
    a tower beside a bridge (mixed, k >= 3); or why the scene cannot give one (a string)."""
    names = [str(n) for n in rng.permutation(sorted(objects))]
    if task in ("bridge", "mixed"):
        if k < (3 if task == "mixed" else 2):
            return "k_too_small"
        k_bridge = k if task == "bridge" else int(rng.integers(2, k))
        bridge = _bridge(names, objects, k_bridge)
        if isinstance(bridge, str) or task == "bridge":
            return bridge
        used = {n for st in bridge for n in st.objects}
        rest = [n for n in names if n not in used]
        if len(rest) < k - k_bridge + 1:
            return "too_few_objects"
        return [Relation("tower", tuple(rest[:k - k_bridge + 1])), *bridge]
    if task == "row":
        names = [n for n in names if objects[n].type == "cube"]
    if task == "towers" and k < 2:
        return "k_too_small"
    need = k + 2 if task == "towers" else k + 1
    if len(names) < need:
        return "too_few_objects"
    names = names[:need]
    if task == "towers":
        cut = int(rng.integers(2, need - 1))  # each tower of two or more
        return [Relation("tower", tuple(names[:cut])), Relation("tower", tuple(names[cut:]))]
    return [Relation(task, tuple(names))]


def sample_goal(rng: np.random.Generator, objects: dict[str, ObjectState], task: str,
                ks: tuple[int, ...], tries: int = 100) -> list[Relation] | str:
    """A random goal of `task` whose build from `objects` takes one of `ks` actions, the
    boxes set down out of the way counted (a start with stacks needs them), or why none was
    found in `tries` samples of each structure size, sizes in random order (a string)."""
    why = "k_unreachable"
    for size in rng.permutation(np.arange(1, max(ks) + 1)):
        for _ in range(tries):
            structures = sample_structures(rng, objects, task, size)
            if isinstance(structures, str):
                why = structures
                break  # the scene cannot give this size
            try:
                actions = check(structures, objects)
            except SpecError:
                why = "spec_refused"
                continue
            if len(actions) in ks:
                return structures
    return why


def _bridge(names: list[str], objects: dict[str, ObjectState], k: int) -> list[Relation] | str:
    """A bridge k >= 2 actions away: a row of two cubes, a tower of k // 2 cubes standing on
    each (the row's two are their bottoms), a long block across their tops, and for an odd
    k a cube on the block."""
    cubes = [n for n in names if objects[n].type == "cube"]
    longs = [n for n in names if objects[n].type == "long"]
    h, extra = k // 2, k % 2
    if len(cubes) < 2 * h + extra or not longs:
        return "too_few_objects"
    left, right = cubes[:h], cubes[h:2 * h]  # each listed top first, its bottom last
    out = [Relation("row", (left[-1], right[-1]))]
    out += [Relation("tower", tuple(t)) for t in (left, right) if len(t) > 1]
    out.append(Relation("bridge", (longs[0], left[0], right[0])))
    if extra:
        out.append(Relation("on", (cubes[2 * h], longs[0])))
    return out


