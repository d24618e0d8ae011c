"""Measuring perception against the simulator's ground truth (tests and benchmarks only)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from drake_symplan.perception.features import YAW_SYMMETRY

MATCH_RADIUS = 0.05  # m: a perceived object farther than this from every true one is invented


def match_to_truth(perceived, truth: dict) -> dict[str, str]:
    """Perceived name -> true name, by optimal assignment on positions within MATCH_RADIUS."""
    if not perceived.objects or not truth:
        return {}
    names = list(truth)
    gt = np.stack([truth[n].position for n in names])
    obs = np.stack([o.position for o in perceived.objects])
    cost = np.linalg.norm(obs[:, None] - gt[None], axis=2)
    rows, cols = linear_sum_assignment(cost)
    return {perceived.objects[r].name: names[c] for r, c in zip(rows, cols, strict=True)
            if cost[r, c] < MATCH_RADIUS}


def yaw_error_deg(kind: str, yaw_a: float, yaw_b: float) -> float:
    period = 2 * np.pi / YAW_SYMMETRY[kind]
    d = (yaw_a - yaw_b + period / 2) % period - period / 2
    return float(abs(np.degrees(d)))


def compare(perceived, truth: dict, true_contacts: set) -> dict:
    """Per-object errors, count and contact-graph agreement for one scene."""
    match = match_to_truth(perceived, truth)
    errors = {}
    for o in perceived.objects:
        if o.name not in match:
            continue
        t = truth[match[o.name]]
        errors[t.name] = {
            "position_mm": round(float(np.linalg.norm(o.position - t.position)) * 1000, 2),
            "yaw_deg": round(yaw_error_deg(t.type, o.yaw, t.yaw), 2),
            "type_ok": bool(o.type == t.type),
        }
    renamed = {tuple(sorted((match.get(a, a), match.get(b, b)))) for a, b in perceived.contacts}
    return {
        "match": match,
        "errors": errors,
        "count_ok": bool(len(perceived.objects) == len(truth)),
        "invented": len(perceived.objects) - len(match),
        "missed": len(truth) - len(match),
        "contacts_ok": bool(renamed == set(true_contacts)),
    }
