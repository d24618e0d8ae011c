"""Measuring perception against the simulator's ground truth (tests and benchmarks only)."""

from __future__ import annotations

import numpy as np

from drake_symplan.boxes import YAW_PERIOD, fold_yaw
from drake_symplan.perception.matching import match_by_position

MATCH_RADIUS = 0.05  # m: a perceived object farther than this from every true one is invented


def match_to_truth(perceived, truth: dict) -> dict[str, str]:
    """Perceived name -> true name, by optimal assignment on positions within MATCH_RADIUS."""
    return match_by_position({o.name: o.position for o in perceived.objects},
                             {n: s.position for n, s in truth.items()}, MATCH_RADIUS)


def yaw_error_deg(kind: str, yaw_a: float, yaw_b: float) -> float:
    """The yaw difference in degrees, up to the box's symmetry."""
    return float(abs(np.degrees(fold_yaw(yaw_a - yaw_b, YAW_PERIOD[kind]))))


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
