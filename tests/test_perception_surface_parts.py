"""Surfaces no rectangle explains are cut into one part per block (surface_parts.py)."""

import numpy as np

from drake_symplan.perception.segmentation import Surface
from drake_symplan.perception.surface_parts import split_surface

UP = np.array([0.0, 0.0, 1.0])


def top_face(centre, yaw, long=True, step=0.002):
    """Points on a box's top face (z = 5 cm) on a 2 mm grid."""
    u = np.arange(-0.125 if long else -0.025, (0.125 if long else 0.025) + 1e-9, step)
    v = np.arange(-0.025, 0.025 + 1e-9, step)
    uu, vv = [a.ravel() for a in np.meshgrid(u, v)]
    d = np.array([-np.sin(yaw), np.cos(yaw)])  # the long axis (y at yaw 0)
    e = np.array([np.cos(yaw), np.sin(yaw)])
    xy = np.asarray(centre) + np.outer(uu, d) + np.outer(vv, e)
    return np.column_stack([xy, np.full(len(xy), 0.05)])


def surface(*faces):
    pts = np.vstack(faces)
    return Surface(np.zeros((0, 2), int), pts, UP, pts.mean(axis=0))


def part_sizes(parts):
    return sorted(len(p.points) for p in parts)


def test_two_blocks_at_right_angles_are_two_parts():
    a = top_face((0.70, -0.10), 0.0)
    b = top_face((0.70, 0.0502), np.pi / 2)  # its side against a's end
    parts = split_surface(surface(a, b))
    assert len(parts) == 2
    # each part is one block's face and at most the row of cells where the other touches
    for p in parts:
        on_a = np.mean(np.abs(p.points[:, 0] - 0.70) < 0.026)
        on_b = np.mean(np.abs(p.points[:, 1] - 0.0502) < 0.026)
        assert max(on_a, on_b) > 0.97


def test_a_block_and_a_turned_cube_are_two_parts():
    a = top_face((0.70, 0.0), 0.0)
    cube = top_face((0.7604, 0.0), np.pi / 4, long=False)  # a corner against a's side
    parts = split_surface(surface(a, cube))
    assert len(parts) == 2
    assert min(len(p.points) for p in parts) < len(cube) * 1.2


def test_rectangles_are_left_whole():
    """Blocks side by side and end to end fill their rectangle: one part, as before."""
    side_by_side = surface(top_face((0.70, 0.0), 0.0), top_face((0.75, 0.0), 0.0))
    end_to_end = surface(top_face((0.70, -0.125), 0.0), top_face((0.70, 0.125), 0.0))
    for s in (side_by_side, end_to_end):
        assert split_surface(s) == [s]
    # a cube against a block's side fills 60 % of it: the block, then the cube
    block, cube = top_face((0.70, 0.0), 0.0), top_face((0.75, 0.0), 0.0, long=False)
    parts = split_surface(surface(block, cube))
    assert len(parts) == 2 and abs(min(len(p.points) for p in parts) - len(cube)) < 60


def _face(x0: float, x1: float) -> np.ndarray:
    """Points of a box's side face along x (y = 0) from x0 to x1, 5 cm tall, every 4 mm."""
    x, z = np.meshgrid(np.arange(x0, x1 + 1e-9, 0.004), np.arange(0.0, 0.05, 0.004))
    return np.stack([x.ravel(), np.zeros(x.size), z.ravel()], axis=1)


def test_a_side_cluster_of_two_cubes_a_gap_apart_is_cut_in_two_and_a_block_is_not():
    from drake_symplan.perception.box_fitting import _split_at_gaps

    strays = np.array([[0.062, 0.0, 0.02], [0.064, 0.0, 0.03]])  # flying pixels in the gap
    two = np.concatenate([_face(0.0, 0.05), strays, _face(0.075, 0.125)])
    left, right = sorted(_split_at_gaps(two), key=lambda p: p[:, 0].min())
    assert left[:, 0].max() < 0.07 and right[:, 0].min() > 0.05  # a cube's face each
    assert len(left) + len(right) == len(two)
    block = _face(0.0, 0.25)
    assert len(_split_at_gaps(block)) == 1
