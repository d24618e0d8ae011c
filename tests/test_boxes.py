"""The boxes' geometry: surface distances and the contact graph, on hand-placed boxes."""

from __future__ import annotations

import numpy as np
import pytest

from drake_symplan.boxes import HALF_EXTENTS, box_distance, contact_graph

CUBE, LONG = np.asarray(HALF_EXTENTS["cube"]), np.asarray(HALF_EXTENTS["long"])
UPRIGHT = np.eye(3)


def yawed(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_box_distance_of_hand_placed_boxes():
    a = np.zeros(3)
    assert box_distance(a, UPRIGHT, CUBE, np.array([0.06, 0, 0]), UPRIGHT, CUBE) == pytest.approx(0.01)
    assert box_distance(a, UPRIGHT, CUBE, np.array([0.03, 0, 0]), UPRIGHT, CUBE) == 0.0  # overlap
    # A cube on a long block's end, turned 90 degrees: its face is 2 mm above the block.
    on_end = np.array([0.10, 0.0, 0.052])
    assert box_distance(a, yawed(np.pi / 2), LONG, on_end, UPRIGHT, CUBE) == pytest.approx(0.002)


def test_contact_graph_pairs_touching_boxes_only():
    boxes = {"base": (np.zeros(3), UPRIGHT, LONG),
             "top": (np.array([0.0, 0.1, 0.051]), UPRIGHT, CUBE),     # 1 mm above the block
             "far": (np.array([0.3, 0.0, 0.0]), UPRIGHT, CUBE)}
    assert contact_graph(boxes) == {("base", "top")}
    assert contact_graph(boxes, tolerance=0.0005) == set()
