"""A goal of relations in the discovered symbols: the pairs a person's relations name
(`relation_goal`), the stages they are planned in (`stage_keys`), and the readings of a
pair that count as its relation (`pair_choices`).

The goal scene is an example of the structure (the compiler's, perceived); only the atoms
of the pairs the relations name are the goal (the paper's contact-graph filter on what was
asked for). A bridge on towers also names the pair of its towers' bottoms, planned first:
the spanning operators ask how the supports stand to each other, and no operator predicts
how two towers' tops stand from how their bottoms do (the agent reads it once they stand).
"""

from __future__ import annotations

from dataclasses import replace

from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.boxes import SIDE
from drake_symplan.relations import PAIR_KIND, bottom, named, pair_unmet, rests_on
from drake_symplan.symbolic.relation_patterns import ground as ground_pattern
from drake_symplan.symbolic.structs import Goal

BASES = -1  # the relation index of a bridge's bases' pair: before any relation of layer 0
# The kinds whose readings also count where they share only what the example and every
# pattern of the kind say: a block bears on a support wherever along it the support
# stands, and the bits that say where differ between the example and the data's patterns.
CORE_KINDS = ("bears",)


def base_of(name: str, states: dict) -> str:
    """The box at the bottom of the stack `name` stands on in `states` (itself on the table)."""
    below = [n for n, o in states.items() if n != name and rests_on(states[name], o)]
    return base_of(below[0], states) if below else name


def relation_pairs(relations, states: dict) -> tuple[dict, dict]:
    """({(upper, lower): (layer of the lower box, relation index, place in a row)},
    {pair: kind}) of the pairs the relations name in the example `states`; a bridge whose
    supports stand on others adds its bases' pair (BASES, no kind: its atoms wanted as the
    example has them). A row's pairs are staged one by one from its first box: a learned
    move names its source and target alone, so no operator says that moving a row's
    middle box leaves the next one behind, and planned at once a row was laid from its
    end."""
    pairs, kinds = {}, {}
    for index, r in enumerate(relations):
        for place, (upper, lower) in enumerate(r.pairs()):
            layer = max(0, int(round(bottom(states[lower]) / SIDE))) if lower in states else 0
            pairs[(upper, lower)] = (layer, index, place if r.word == "row" else 0)
            kinds[(upper, lower)] = PAIR_KIND[r.word]
        if r.word == "bridge" and set(r.objects[1:]) <= set(states):
            bases = tuple(base_of(n, states) for n in r.objects[1:])
            if bases != r.objects[1:]:
                pairs.setdefault(bases, (0, BASES, 0))
    return pairs, kinds


def relation_goal(goal, relations):
    """The perceived example `goal` (abstraction.Observation) of `relations` as a goal of
    relations: its boxes only the named ones (the others are free), its reading's goal
    atoms only those of the pairs the relations name (`relation_pairs`, Reading.pairs),
    each pair with the layer of its lower box and its relation's index."""
    names = [n for n in named(relations) if n in goal.boxes.names]
    rows = [goal.boxes.names.index(n) for n in names]
    boxes = Boxes(tuple(names), goal.boxes.features[rows],
                  frozenset(p for p in goal.boxes.contacts if set(p) <= set(names)))
    pairs, kinds = relation_pairs(relations, goal.boxes.object_states())
    reading = None if goal.reading is None else replace(goal.reading, pairs=pairs,
                                                         kinds=kinds)
    return replace(goal, reading=reading, boxes=boxes, relations=tuple(relations))


def pair_of(pairs: dict, atom, both: bool = True) -> tuple | None:
    """The named pair (upper, lower) a relation atom is about, or None; with `both`, in
    either order: under vicinity a pair's relation is its bits both ways (b on a and b
    beside a read the same bits from a to b), under contact the bits from upper to lower
    say it (more are incidental and cost plans: measured on the written goals)."""
    for key in ((atom[1], atom[2]), (atom[2], atom[1]))[:2 if both else 1]:
        if key in pairs:
            return key
    return None


def stage_keys(goal) -> list[tuple]:
    """The stages of a goal of relations (goal_plans.stages), in order: the (layer,
    relation index, place in a row) values of its Reading.pairs."""
    return sorted(set(goal.pairs.values()))


def pair_choices(kinds: dict, atoms: frozenset, patterns: dict) -> Goal:
    """A goal of relations' atoms as a Goal: each named pair whose kind has patterns
    (symbolic/relation_patterns.py) a choice of the example's atoms of it, any of its
    kind's patterns, or for CORE_KINDS what all of those share; the other pairs' atoms
    wanted as they are."""
    wanted, choices = set(atoms), []
    for pair, kind in kinds.items():
        if not patterns.get(kind):
            continue
        own = frozenset(a for a in atoms if pair_of({pair: None}, a))
        wanted -= own
        readings = [own, *(ground_pattern(p, *pair) for p in patterns[kind])]
        core = frozenset.intersection(*readings)
        if kind in CORE_KINDS and core:
            readings.append(core)
        choices.append((pair, list(dict.fromkeys(readings))))
    return Goal(wanted, choices)


def unheld(goal, objects: dict) -> frozenset:
    """The named pairs of the goal of relations `goal` (a Reading with `kinds`) whose
    relation the boxes `objects` (perceived, by name) do not hold."""
    return frozenset(pair for pair, kind in (goal.kinds or {}).items()
                     if set(pair) <= set(objects)
                     and pair_unmet(kind, objects[pair[0]], objects[pair[1]]) is not None)


def unheld_in(start, goal) -> frozenset:
    """`unheld` for a plan from the perceived `start` to `goal` (abstraction.Observation):
    none for a goal without a reading."""
    return frozenset() if goal.reading is None \
        else unheld(goal.reading, start.boxes.object_states())


def unheld_readings(goal: Goal, start: frozenset, pairs: frozenset) -> Goal:
    """`goal` without the readings of a pair of `pairs` (whose relation the start does
    not hold) that the `start` atoms already hold: such a reading does not say the
    relation (the middle cube of a tower of three read as two cubes apart), and planned
    to, it let a tower stand unbuilt. A pair all of whose readings hold keeps them."""
    choices = []
    for key, alternatives in goal.choices:
        kept = [a for a in alternatives if not a <= start] if key in pairs else []
        choices.append((key, kept or alternatives))
    return Goal(goal, choices)
