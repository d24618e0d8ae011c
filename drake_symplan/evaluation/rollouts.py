"""`symplan eval rollout`: the continuous model's position error after k actions rolled
forward on held-out episodes, the number bilevel planning depends on.

From each identity chain of a held-out data set (whole scenes, a seed the model never
saw), the perceived scene at step t is rolled forward through the recorded actions of
steps t..t+k-1 with the model alone (continuous.py) and compared with the scene perceived
after step t+k-1: each object's distance (cm). Beside it the error of predicting that
nothing moves, and of the moved objects only (those that went more than 1 cm). An ensemble
also reports its spread, and how often the rollouts it is sure of (every box's spread
within 1 cm) end with every box within 5 cm: what a plan accepted on its prediction needs.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import asdict, dataclass

import numpy as np

from drake_symplan.abstraction.continuous import Boxes, ContinuousModel
from drake_symplan.actions import IS_SOURCE, IS_TARGET, OFFSETS, Action
from drake_symplan.shards import fingerprint, load_extra, load_transitions

SCENE = ("scene_state", "scene_next_state", "scene_mask", "scene_contacts", "scene_slots",
         "step", "chain")
MOVED = 0.01  # m: an object that went farther than this moved
SURE = 1.0  # cm: a rollout whose every box's spread is within this is one the model is sure of


@dataclass(frozen=True)
class RolloutConfig:
    ks: tuple[int, ...] = (1, 2, 3, 4, 5)
    max_starts: int = 200  # rollouts per k, sampled with `seed`
    seed: int = 0


def scene_action(action_rows: np.ndarray, slots: np.ndarray) -> Action:
    """The recorded action of one transition ([N, 8] encoding of its relevant objects,
    their scene slots) over scene-slot names s<slot>."""
    src = int(np.argmax(action_rows[:, IS_SOURCE]))
    tgt = int(np.argmax(action_rows[:, IS_TARGET]))
    grasp = OFFSETS[int(np.argmax(action_rows[src, IS_SOURCE + 1:IS_SOURCE + 4]))]
    release = OFFSETS[int(np.argmax(action_rows[tgt, IS_TARGET + 1:IS_TARGET + 4]))]
    return Action(f"s{slots[src]}", grasp, f"s{slots[tgt]}", release)


def scene_boxes(state: np.ndarray, mask: np.ndarray, contacts: np.ndarray) -> Boxes:
    """A whole scene row of a data set as Boxes over scene-slot names."""
    slots = np.flatnonzero(mask)
    names = tuple(f"s{s}" for s in slots)
    pairs = frozenset((f"s{a}", f"s{b}") for a in slots for b in slots
                      if a < b and contacts[a, b])
    return Boxes(names, state[slots].astype(np.float32), pairs)


def evaluate_rollouts(model, data_dir, config: RolloutConfig = RolloutConfig()) -> dict:
    """Position errors by k (module docstring); JSON-able."""
    arrays = load_transitions(data_dir)
    extra = {k: load_extra(data_dir, k, pad_value=-1 if k == "scene_slots" else None)
             for k in SCENE}
    if any(v is None for v in extra.values()):
        raise ValueError(f"data set {data_dir} stores no whole scenes; collect it with the "
                         "current code")
    index = {(int(e), int(c), int(s)): i for i, (e, c, s) in enumerate(zip(
        arrays.episode, extra["chain"], extra["step"], strict=True))}
    continuous = ContinuousModel(model)
    rng = np.random.default_rng(config.seed)
    by_k = {}
    for k in config.ks:
        starts = [rows for (e, c, s) in index
                  for rows in [[index.get((e, c, s + d)) for d in range(k)]]
                  if None not in rows]
        chosen = rng.permutation(len(starts))[:config.max_starts]
        cells = defaultdict(list)
        for j in sorted(chosen):
            for key, values in _one(continuous, arrays, extra, starts[j]).items():
                cells[key] += values
        by_k[str(k)] = _summary(cells, len(chosen))
    return {"data": str(data_dir), "data_fingerprint": fingerprint(data_dir),
            "config": asdict(config), "by_k": by_k}


def _one(continuous: ContinuousModel, arrays, extra: dict, rows: list[int]) -> dict:
    """Per-object errors (cm) of one rollout through transitions `rows`."""
    first, last = rows[0], rows[-1]
    boxes = scene_boxes(extra["scene_state"][first], extra["scene_mask"][first],
                        extra["scene_contacts"][first])
    actions = [scene_action(arrays.action[r][arrays.mask[r]],
                            extra["scene_slots"][r][arrays.mask[r]]) for r in rows]
    end = continuous.rollout(boxes, actions)[-1]
    predicted = end.where()
    seen = {n: extra["scene_next_state"][last][int(n[1:]), :3] for n in boxes.names}
    start = boxes.where()
    out = defaultdict(list)
    for n in boxes.names:
        error = 100 * float(np.linalg.norm(predicted[n] - seen[n]))
        still = 100 * float(np.linalg.norm(start[n] - seen[n]))
        out["error"].append(error)
        out["static"].append(still)
        if still > 100 * MOVED:
            out["moved"].append(error)
    out["scene_max"].append(max(out["error"][-len(boxes.names):]))
    out["spread"] += [100 * float(v) for v in end.uncertainty()]
    out["scene_spread"].append(100 * float(end.uncertainty().max()))
    return out


def _summary(cells: dict, n: int) -> dict:
    def stats(values):
        v = np.asarray(values, float)
        return {"mean": round(float(v.mean()), 2), "median": round(float(np.median(v)), 2),
                "p90": round(float(np.percentile(v, 90)), 2)} if v.size else None

    within = np.asarray(cells["scene_max"]) <= 5.0
    sure = np.asarray(cells["scene_spread"]) <= SURE
    return {"rollouts": n, "error_cm": stats(cells["error"]),
            "moved_error_cm": stats(cells["moved"]), "no_motion_cm": stats(cells["static"]),
            "scenes_within_5cm": round(float(within.mean()), 3) if within.size else None,
            "spread_cm": stats(cells["spread"]),
            "sure_share": round(float(sure.mean()), 3) if sure.size else None,
            "sure_within_5cm": round(float(within[sure].mean()), 3) if sure.any() else None,
            "unsure_within_5cm": round(float(within[~sure].mean()), 3)
            if (~sure).any() else None}
