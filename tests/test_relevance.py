"""Relevance by vicinity: the graph of pairs a transition records and the planner reads,
on scenes with known answers (boxes.neighbour_pairs and its users)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.actions import Action, relevant_objects
from drake_symplan.boxes import CONTACT_TOLERANCE, VICINITY, contact_graph, neighbour_pairs
from drake_symplan.cli.options import relevance_radius
from drake_symplan.data.collect import CollectConfig
from drake_symplan.data.recipes import recipe
from drake_symplan.data.storage import relevance_radius as data_relevance
from drake_symplan.features import object_features

SIDE = 0.05


def scene(boxes: dict[str, tuple[str, list[float]]]):
    """A perceived scene of upright boxes at their centres, contacts from the geometry."""
    objects = [SimpleNamespace(name=n, type=k, position=np.array(p), R=np.eye(3))
               for n, (k, p) in boxes.items()]
    half = {"cube": (0.025, 0.025, 0.025), "long": (0.025, 0.125, 0.025)}
    contacts = contact_graph({o.name: (o.position, o.R, np.array(half[o.type]))
                              for o in objects})
    features = np.stack([object_features(o.type, o.position, o.R) for o in objects])
    return SimpleNamespace(objects=objects, names=[o.name for o in objects],
                           contacts=contacts, features=lambda: features)


# a row's neighbours 2.5 cm apart (a cube released beside another), a tower of three
ROW_AND_TOWER = scene({"a": ("cube", [0.6, 0.0, 0.025]), "b": ("cube", [0.6, 0.075, 0.025]),
                       "far": ("cube", [0.6, 0.3, 0.025]),
                       "t0": ("cube", [0.9, 0.0, 0.025]), "t1": ("cube", [0.9, 0.0, 0.075]),
                       "t2": ("cube", [0.9, 0.0, 0.125])})


def test_contact_relevance_is_the_contact_graph():
    assert neighbour_pairs(ROW_AND_TOWER, CONTACT_TOLERANCE) == {("t0", "t1"), ("t1", "t2")}


def test_vicinity_relates_a_rows_neighbours_not_a_towers_next_but_one():
    assert neighbour_pairs(ROW_AND_TOWER, VICINITY) == {("a", "b"), ("t0", "t1"),
                                                        ("t1", "t2")}


def test_a_gap_just_past_the_radius_is_not_related():
    apart = scene({"a": ("cube", [0.6, 0.0, 0.025]),
                   "b": ("cube", [0.6, SIDE + VICINITY + 0.002, 0.025])})
    assert neighbour_pairs(apart, VICINITY) == set()


def test_relevant_objects_follow_the_graph_given():
    move = Action("far", "center", "a", "right")
    assert relevant_objects(ROW_AND_TOWER, move) == ["far", "a"]
    assert relevant_objects(ROW_AND_TOWER, move, neighbour_pairs(ROW_AND_TOWER, VICINITY)) \
        == ["far", "a", "b"]


def test_the_continuous_model_involves_the_same_objects_as_the_data():
    boxes = Boxes.of(ROW_AND_TOWER)
    move = Action("far", "center", "a", "right")
    names = list(boxes.names)
    assert [names[i] for i in boxes.involved(move)] == ["a", "far"]
    assert [names[i] for i in boxes.involved(move, VICINITY)] == ["a", "b", "far"]
    # a predicted scene (contacts from the geometry) relates the same pairs
    moved = boxes.moved(boxes.positions.copy())
    assert moved.neighbours(VICINITY) == frozenset(neighbour_pairs(ROW_AND_TOWER, VICINITY))


def test_the_vicinity_recipe_and_option_name_the_same_radius():
    assert recipe("vicinity")["relevance_radius"] == VICINITY
    assert relevance_radius("vicinity") == VICINITY
    assert relevance_radius("contact") == CONTACT_TOLERANCE
    assert relevance_radius("0.02") == 0.02
    assert CollectConfig().relevance_radius == CONTACT_TOLERANCE


@pytest.mark.parametrize("radius", [0.0, 0.2])
def test_a_radius_out_of_range_is_refused(radius):
    with pytest.raises(ValueError, match="relevance_radius must be metres"):
        CollectConfig(relevance_radius=radius)


def test_a_data_set_without_the_setting_was_collected_by_contact(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"schema_version": 1, "config": {"backend": "hand"}}))
    assert data_relevance(tmp_path) == CONTACT_TOLERANCE
    (tmp_path / "manifest.json").write_text(json.dumps({"schema_version": 1,
                                                         "config": {"relevance_radius": 0.035}}))
    assert data_relevance(tmp_path) == 0.035


def test_the_degree_atoms_count_what_touches_while_relations_follow_vicinity():
    from drake_symplan.symbolic.effect_operators import EFFECT

    # a and b side by side (related, not touching), c on b (touching)
    related = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], bool)
    touch = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 0]], bool)
    unary, rel = np.zeros((3, 1), np.uint8), np.zeros((1, 3, 3), np.uint8)
    rel[0, 0, 1] = 1
    atoms, _ = EFFECT.read(unary, None, rel, None, related, degree=touch.sum(-1))
    assert {a for a in atoms if a[0].startswith("touching")} == {
        ("touching0", 0), ("touching1", 1), ("touching1", 2)}
    assert ("r0", 0, 1) in atoms and ("not_r0", 1, 2) in atoms
    assert not any(a[1:] == (0, 2) for a in atoms)  # a and c are not related


def test_the_pairs_in_contact_of_recorded_scenes_come_from_their_geometry():
    from drake_symplan.features import touching

    boxes = ROW_AND_TOWER
    state = np.zeros((1, 8, 9), np.float32)
    state[0, :len(boxes.objects)] = boxes.features()
    mask = np.zeros((1, 8), bool)
    mask[0, :len(boxes.objects)] = True
    got = touching(state, mask)[0]
    names = boxes.names
    pairs = {tuple(sorted((names[i], names[j]))) for i, j in np.argwhere(got)}
    assert pairs == {("t0", "t1"), ("t1", "t2")}  # the row's 2.5 cm gap is no contact
