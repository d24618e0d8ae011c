"""The action's geometry (actions.py): where the fingers close for a grasp offset, where the
grasp point and the source's centre are released, and which grasps stay on a box. Offsets
run along world y; every layer that moves a box reads these."""

from __future__ import annotations

import numpy as np

from drake_symplan.actions import (
    OFFSET_METRES,
    Action,
    along_y,
    grasp_on_box,
    grasp_point,
    release_centre,
    release_point,
    release_shift,
)
from drake_symplan.boxes import HALF_EXTENTS

ACTION = Action("a", "left", "b", "right")  # grasped 7.5 cm left, released 7.5 cm right


def test_offsets_are_vectors_along_world_y():
    assert along_y(0.075).tolist() == [0.0, 0.075, 0.0]
    assert along_y(-0.075, 2).tolist() == [0.0, -0.075]
    assert along_y(0.0).dtype == np.float64


def test_grasp_and_release_points_shift_the_centres_along_y():
    src, tgt = np.array([0.5, 0.2, 0.025]), np.array([0.7, -0.1, 0.075])
    np.testing.assert_allclose(grasp_point(src, ACTION), [0.5, 0.125, 0.025])
    np.testing.assert_allclose(release_point(tgt, ACTION), [0.7, -0.025, 0.075])
    # xy or xyz alike, and the same floating-point sums the callers wrote before.
    np.testing.assert_allclose(grasp_point(src[:2], ACTION), [0.5, 0.125])
    assert grasp_point(src, ACTION).tolist() == (src + [0, OFFSET_METRES["left"], 0]).tolist()
    # A float32 centre gives float64 points, as adding a list of offsets did.
    assert grasp_point(src.astype(np.float32), ACTION).dtype == np.float64
    assert grasp_point(src, Action("a", "center", "b", "center")).tolist() == src.tolist()


def test_the_offsets_compose_into_the_release_shift():
    assert release_shift(ACTION) == 0.15
    assert release_shift(Action("a", "right", "b", "center")) == -0.075
    assert release_shift(Action("a", "left", "b", "left")) == 0.0
    tgt = np.array([0.7, -0.1])
    np.testing.assert_allclose(release_centre(tgt, ACTION), [0.7, 0.05])
    assert release_centre(tgt, ACTION).tolist() == (tgt + [0.0, 0.15]).tolist()
    # The grasp point lands on the release point: centre = release point - grasp offset.
    src = np.array([0.4, 0.3])
    moved = src + (release_point(tgt, ACTION) - grasp_point(src, ACTION))
    np.testing.assert_allclose(moved, release_centre(tgt, ACTION))


def test_a_grasp_stays_on_the_box_when_its_offset_is_inside_the_half_length():
    cube, long = HALF_EXTENTS["cube"][1], HALF_EXTENTS["long"][1]
    assert grasp_on_box("center", cube)
    assert not grasp_on_box("left", cube) and not grasp_on_box("right", cube)
    assert grasp_on_box("left", long) and grasp_on_box("right", long)
    assert not grasp_on_box("right", 0.075)  # exactly at the edge is off
