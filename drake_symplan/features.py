"""The object feature vector x_i: the contract between perception, which computes it from a
perceived box only, and everything that learns from it or predicts it (docs/perception.md).


x = [x, y, z, cos(tilt), long_axis_up, cos(k*yaw), sin(k*yaw), is_cube, is_long]
- position in metres, world frame (box centre);
- cos(tilt): tilt between world z and the box axis nearest to it (1 = resting on a face);
- long_axis_up: |z component| of a long block's long axis (0 lying, 1 standing; 0 for cubes);
- yaw folded by the box's symmetry: k = 2 pi / boxes.YAW_PERIOD, 4 for a cube (90 deg),
  2 for a long block (180 deg), so every symmetric-equivalent pose gives the same vector;
- the perceived type, one-hot.
"""

from __future__ import annotations

import numpy as np

from drake_symplan.boxes import CONTACT_TOLERANCE, HALF_EXTENTS, YAW_PERIOD, contact_graph
from drake_symplan.datasets import ObjectState

FEATURE_NAMES = ("x", "y", "z", "cos_tilt", "long_axis_up", "cos_k_yaw", "sin_k_yaw",
                 "is_cube", "is_long")
FEATURE_DIM = len(FEATURE_NAMES)
YAW_SYMMETRY = {kind: round(2 * np.pi / period) for kind, period in YAW_PERIOD.items()}


def box_of(features: np.ndarray) -> tuple[str, np.ndarray, np.ndarray]:
    """(type, centre, axes R) of a box from its features, as if resting on a face (the
    features keep a tilt's size, not its direction): the geometry the continuous model's
    predicted scenes are checked for contact with."""
    kind = "cube" if features[7] >= features[8] else "long"
    yaw = float(np.arctan2(features[6], features[5])) / YAW_SYMMETRY[kind]
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return kind, np.asarray(features[:3], float), R


def shape_state(name: str, kind: str, centre: np.ndarray, R: np.ndarray) -> ObjectState:
    """The box as the skills and relations.py read one, from what box_of reads of its
    features (type, centre, axes R): upright, the yaw the features keep."""
    return ObjectState(name, kind, centre, float(np.arctan2(R[1, 0], R[0, 0])))


def object_features(kind: str, position: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Features of a box of type `kind` at `position` with axes R (columns x, y=long, z)."""
    if kind not in YAW_SYMMETRY:
        raise ValueError(f"unknown object type {kind!r}; expected one of {tuple(YAW_SYMMETRY)}")
    cos_tilt = float(np.abs(R[2, :]).max())
    long_up = float(abs(R[2, 1])) if kind == "long" else 0.0
    y = R[:, 1]
    yaw = np.arctan2(-y[0], y[1])
    k = YAW_SYMMETRY[kind]
    return np.array([*position, cos_tilt, long_up, np.cos(k * yaw), np.sin(k * yaw),
                     kind == "cube", kind == "long"], dtype=np.float32)


def feature_graph(state: np.ndarray, slots, tolerance: float = CONTACT_TOLERANCE
                  ) -> set[tuple[int, int]]:
    """The pairs of a scene's boxes (features [M, D], the `slots` present) whose surfaces
    are within `tolerance` by their geometry (boxes.contact_graph)."""
    shapes = {int(i): box_of(state[i]) for i in slots}
    return contact_graph({i: (c, R, np.asarray(HALF_EXTENTS[k]))
                          for i, (k, c, R) in shapes.items()}, tolerance)


def touching(state: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """[T, M, M] bool: the pairs of each scene's boxes (features [T, M, D]) in contact by
    their geometry (boxes.contact_graph), as perception finds them."""
    out = np.zeros(mask.shape + mask.shape[-1:], bool)
    for t in range(len(state)):
        for i, j in feature_graph(state[t], np.flatnonzero(mask[t])):
            out[t, i, j] = out[t, j, i] = True
    return out
