"""Contact graph of perceived boxes: pairs whose surfaces are within a tolerance."""

from __future__ import annotations

import numpy as np

CONTACT_TOLERANCE = 0.006  # m; perceived boxes are a few mm off, sampled objects >= 2 cm apart


def _surface_samples(center, R, half, n=7) -> np.ndarray:
    g = np.linspace(-1.0, 1.0, n)
    pts = []
    for axis in range(3):
        a, b = [i for i in range(3) if i != axis]
        for sign in (-1.0, 1.0):
            uu, vv = np.meshgrid(g, g)
            local = np.zeros((uu.size, 3))
            local[:, axis] = sign
            local[:, a], local[:, b] = uu.ravel(), vv.ravel()
            pts.append(local * half)
    return center + np.vstack(pts) @ R.T


def box_distance(c1, R1, h1, c2, R2, h2) -> float:
    """Approximate surface distance between two boxes (0 when they overlap)."""
    best = np.inf
    for (ca, Ra, ha), (cb, Rb, hb) in (((c1, R1, h1), (c2, R2, h2)),
                                         ((c2, R2, h2), (c1, R1, h1))):
        local = (_surface_samples(ca, Ra, ha) - cb) @ Rb
        outside = np.maximum(np.abs(local) - hb, 0.0)
        best = min(best, float(np.sqrt((outside ** 2).sum(axis=1)).min()))
    return best


def contact_graph(boxes: dict, tolerance: float = CONTACT_TOLERANCE) -> set[tuple[str, str]]:
    """`boxes`: name -> (center, R, half_extents). Returns sorted name pairs in contact."""
    names = sorted(boxes)
    pairs = set()
    for i, a in enumerate(names):
        ca, Ra, ha = boxes[a]
        for b in names[i + 1:]:
            cb, Rb, hb = boxes[b]
            if np.linalg.norm(ca - cb) > np.linalg.norm(ha) + np.linalg.norm(hb) + tolerance:
                continue
            if box_distance(ca, Ra, ha, cb, Rb, hb) <= tolerance:
                pairs.add((a, b))
    return pairs
