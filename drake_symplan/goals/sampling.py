"""Random goals of a kind (`problems make --task`), sampled on a start scene: a tower, a
row, two towers, a bridge on two towers, a tower beside a bridge, each so that building it
takes a given number of actions (compiler.check counts them); or a goal as a person writes
it (WRITTEN), whatever its build takes."""

from __future__ import annotations

import numpy as np

from drake_symplan.datasets import ObjectState
from drake_symplan.goals.compiler import check
from drake_symplan.relations import Relation, SpecError


def _written(task: str, cubes: list[str], longs: list[str], names: list[str]
             ) -> list[Relation] | str:
    """The goals a person writes (module docstring), on randomly ordered names."""
    if task == "tower4":
        return [Relation("tower", tuple(names[:4]))] if len(names) >= 4 else "too_few_objects"
    if task == "towers3":
        return [Relation("tower", tuple(names[:3])), Relation("tower", tuple(names[3:6]))] \
            if len(names) >= 6 else "too_few_objects"
    if task == "row4":
        return [Relation("row", tuple(cubes[:4]))] if len(cubes) >= 4 else "too_few_objects"
    if not longs or len(cubes) < (2 if task == "bridge2" else 4):
        return "too_few_objects"
    if task == "bridge2":
        return [Relation("bridge", (longs[0], *cubes[:2]))]
    return [Relation("tower", tuple(cubes[:2])), Relation("tower", tuple(cubes[2:4])),
            Relation("bridge", (longs[0], cubes[0], cubes[2]))]


def _many(rng: np.random.Generator, objects: dict[str, ObjectState], names: list[str],
          k: int) -> list[Relation] | str:
    """Several structures that take about `k` actions together, each on boxes of its own:
    towers of 2-4 boxes, bridges on two towers of two cubes, rows of 2-3 cubes."""
    free, out, left = list(names), [], k
    while left >= 1:
        cubes = [n for n in free if objects[n].type == "cube"]
        longs = [n for n in free if objects[n].type == "long"]
        kinds = ["tower"] + (["bridge"] if len(cubes) >= 4 and longs and left >= 3 else []) \
            + (["row"] if len(cubes) >= 2 else [])
        kind = kinds[int(rng.integers(len(kinds)))]
        if kind == "bridge":
            c = cubes[:4]
            made = [Relation("tower", (c[0], c[1])), Relation("tower", (c[2], c[3])),
                    Relation("bridge", (longs[0], c[0], c[2]))]
        else:
            pool = cubes if kind == "row" else free
            m = min(int(rng.integers(2, 4 if kind == "row" else 5)), left + 1, len(pool))
            if m < 2:
                break
            made = [Relation(kind, tuple(pool[:m]))]
        out += made
        used = {n for r in made for n in r.objects}
        free = [n for n in free if n not in used]
        left -= len(used) - 1 - (kind == "bridge")
    return out or "too_few_objects"


# Goals as a person writes them, whatever the number of actions their build takes: a tower
# of 4, two towers of 3, a bridge over two cubes, a row of 4 cubes, a bridge on two towers
# of 2 (the cubes' bottoms brought together: compiler.with_supports)
WRITTEN = ("tower4", "towers3", "bridge2", "row4", "bridge_towers")
TASKS = ("tower", "row", "towers", "bridge", "mixed", "many", *WRITTEN)  # `problems make --task`


def sample_structures(rng: np.random.Generator, objects: dict[str, ObjectState], task: str,
                      k: int) -> list[Relation] | str:
    """A random goal of `task` that takes `k` actions to build from `objects`: a tower of
    k + 1 boxes, a row of k + 1 cubes, two towers of k + 2 boxes, a bridge (`_bridge`), or
    a tower beside a bridge (mixed, k >= 3); or why the scene cannot give one (a string)."""
    names = [str(n) for n in rng.permutation(sorted(objects))]
    if task in WRITTEN:
        return _written(task, [n for n in names if objects[n].type == "cube"],
                        [n for n in names if objects[n].type == "long"], names)
    if task == "many":
        return _many(rng, objects, names, k)
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


