"""A long block set on a cube lines up with the second support of equal height it would
otherwise come down askew over (skills/geometry.span_turn), and only then."""

import numpy as np
import pytest

from drake_symplan.actions import Action
from drake_symplan.datasets import ObjectState
from drake_symplan.skills.geometry import nominal_points

ASKEW = np.radians(144.0)  # two cubes knocked askew, as traced on a bridge on towers


def _scene(support_xy):
    """A block lying at 108 degrees, its target cube at (0.6, 0.077) and a cube as high at
    `support_xy`, both cubes at 144 degrees."""
    return {"b": ObjectState("b", "long", np.array([0.45, -0.2, 0.025]), np.radians(108.0)),
            "t": ObjectState("t", "cube", np.array([0.6, 0.077, 0.025]), ASKEW),
            "s": ObjectState("s", "cube", np.array([*support_xy, 0.025]), ASKEW)}


def _laid(objects) -> float:
    """The block's yaw once set centred on the target cube, in degrees modulo 180."""
    _, _, turn = nominal_points(Action("b", "center", "t", "center"), objects)
    return float(np.degrees(objects["b"].yaw + turn) % 180.0)


def test_a_block_that_would_miss_the_second_support_lines_up_with_it():
    # turned to its target's faces the block would lie at 144 degrees, its axis 4.5 cm
    # beside the support 7.7 cm along y: lined up, it lies along y (0 degrees)
    laid = _laid(_scene((0.6, 0.0)))
    assert min(laid, 180.0 - laid) == pytest.approx(0.0, abs=1e-6)


def test_a_block_turns_to_its_targets_faces_where_no_support_is_beside_it():
    # the cube beside stands across the block's lie (6.2 cm off its axis): not a support
    assert _laid(_scene((0.677, 0.077))) == pytest.approx(144.0, abs=1e-6)
    # nor where no box is as high within the block's half length
    assert _laid(_scene((0.6, -0.2))) == pytest.approx(144.0, abs=1e-6)
