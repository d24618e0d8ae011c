"""The goal relations read in the discovered symbols: for each kind of pair a goal names (on,
bears, beside: relations.PAIR_KINDS), the patterns of relation bits its pairs read in the
robot's own perceived data, each pattern one way the symbols say it.

One example of a goal (the compiled goal scene, perceived) reads one pattern per named
pair, and the learned bits also say things no relation is about (how far off centre a cube
sits, what stands above): a plan to the example's pattern can only reach it by chance, and
the planner shuffles a box on its support to get there. So a goal pair holds in the
symbols when its bits read the example's pattern or any of its kind's (a disjunctive goal,
compiled for the planner in planning/grounding.py; Abstraction.plan runs the plan with
the patterns only where it is shorter than the example's). A pattern is kept when it is
frequent among the kind's pairs (at least MIN_SHARE of them) and mostly theirs: of all
related pairs of the data whose bits hold it (a pattern with a bit read uncertain holds
whatever that bit reads), at least PURITY are of the kind, so the symbols tell the kinds
apart where they can. Only certain bits count, both directions of the pair's relations,
the pair (upper, lower) or (first, next) as slots 0 and 1.
"""

from __future__ import annotations

import itertools
from collections import Counter
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from drake_symplan.atomic import write_atomic
from drake_symplan.json_files import read_json
from drake_symplan.relations import PAIR_KINDS, pair_unmet

FILE = "patterns.json"
MIN_SHARE = 0.02  # of a kind's pairs that must read a pattern for it to be kept
PURITY = 0.8  # of the related pairs reading a pattern that must be of the kind
SCENES = 6000  # perceived scenes of the data read (before and after of the first half)

Pattern = frozenset  # of slot atoms: ("r0", 0, 1), ("not_r2", 1, 0), ...


def pair_pattern(rel: np.ndarray, uncertain: np.ndarray, i: int, j: int) -> Pattern:
    """The certain relation bits between slots i and j of one scene ([K, n, n]), both
    ways, as slot atoms with i as 0 and j as 1."""
    out = []
    for k in range(rel.shape[0]):
        for a, b, slots in ((i, j, (0, 1)), (j, i, (1, 0))):
            if not uncertain[k, a, b]:
                out.append((f"r{k}" if rel[k, a, b] else f"not_r{k}", *slots))
    return frozenset(out)


def pair_kinds(first, second) -> list[str]:
    """The kinds of pair (relations.PAIR_KINDS) the ObjectStates (first, second) are."""
    return [k for k in PAIR_KINDS if pair_unmet(k, first, second) is None]


def count_patterns(scenes: Iterable[tuple[dict, set, np.ndarray, np.ndarray]]
                   ) -> tuple[dict[str, Counter], Counter]:
    """({kind: Counter of patterns}, Counter of patterns over every related pair) of
    scenes given as (ObjectStates by slot, related pairs {(i, j)}, relations [K, n, n],
    their uncertainty)."""
    by_kind: dict[str, Counter] = {k: Counter() for k in PAIR_KINDS}
    every: Counter = Counter()
    for objects, related, rel, uncertain in scenes:
        for i, j in itertools.permutations(sorted(objects), 2):
            if (min(i, j), max(i, j)) not in related:
                continue
            pattern = pair_pattern(rel, uncertain, i, j)
            every[pattern] += 1
            for kind in pair_kinds(objects[i], objects[j]):
                by_kind[kind][pattern] += 1
    return by_kind, every


def select(by_kind: dict[str, Counter], every: Counter, min_share: float = MIN_SHARE,
           purity: float = PURITY) -> dict[str, list[Pattern]]:
    """Each kind's patterns kept (module docstring), most frequent first."""
    def reading(pattern: Pattern, counts: Counter) -> int:  # pairs whose bits hold it
        return sum(c for q, c in counts.items() if pattern <= q)

    out = {}
    for kind, counts in by_kind.items():
        total = sum(counts.values())
        out[kind] = [p for p, c in counts.most_common() if total and c >= min_share * total
                     and reading(p, counts) >= purity * reading(p, every)]
    return out


def ground(pattern: Pattern, first: str, second: str):
    """The pattern's atoms for the pair (first, second)."""
    from drake_symplan.symbolic.structs import Atom

    names = (first, second)
    return frozenset(Atom(p, *(names[s] for s in slots)) for p, *slots in pattern)


def save(patterns: dict[str, list[Pattern]], folder: str | Path, info: dict) -> Path:
    """`patterns` as FILE in a bundle's `folder`, with what they were read from."""
    import json

    data = {**info, "patterns": {k: [sorted([list(a) for a in p]) for p in ps]
                                 for k, ps in patterns.items()}}
    return write_atomic(Path(folder) / FILE, json.dumps(data, indent=1) + "\n")


def load(folder: str | Path) -> dict[str, list[Pattern]]:
    """A bundle's patterns (FILE), or {} where it has none."""
    path = Path(folder) / FILE
    if not path.is_file():
        return {}
    data = read_json(path, expect=dict)["patterns"]
    return {k: [frozenset((a[0], *a[1:]) for a in p) for p in ps] for k, ps in data.items()}


def read_patterns(bundle, data_dir: str | Path, scenes: int = SCENES
                  ) -> tuple[dict[str, list[Pattern]], dict]:
    """The patterns of the goal relations in `bundle`'s symbols (module docstring), read
    from the perceived scenes of a data set (the first transitions' before and after,
    `scenes` in all), with counts to report beside them."""
    from drake_symplan.boxes import CONTACT_TOLERANCE
    from drake_symplan.features import box_of, feature_graph, shape_state
    from drake_symplan.learning.readout import read_symbols_batched
    from drake_symplan.shards import load_transitions

    arrays = load_transitions(data_dir)
    after = arrays.next_state is not None
    half = max(1, scenes // 2 if after else scenes)
    states = np.concatenate([arrays.state[:half]]
                            + ([arrays.next_state[:half]] if after else []))
    masks = np.concatenate([arrays.mask[:half]] * (2 if after else 1)).astype(bool)
    _, _, rel, uncertain = read_symbols_batched(bundle.model, states, masks, bundle.margin)

    radius = max(bundle.relevance_radius, CONTACT_TOLERANCE)

    def scene(t: int):
        slots = np.flatnonzero(masks[t])
        objects = {int(i): shape_state(str(i), *box_of(states[t, i])) for i in slots}
        related = {tuple(sorted(p)) for p in feature_graph(states[t], slots, radius)}
        return objects, related, rel[t], uncertain[t].astype(bool)

    by_kind, every = count_patterns(scene(t) for t in range(len(states)))
    kept = select(by_kind, every)
    counts = {k: {"pairs": sum(c.values()), "read": sum(c[p] for p in kept[k])}
              for k, c in by_kind.items()}
    return kept, {"scenes": int(len(states)), "related_pairs": int(sum(every.values())),
                  "kinds": counts}
