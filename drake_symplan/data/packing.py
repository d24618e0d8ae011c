"""A chunk's transitions as the arrays of its shard: `pack` pads them to their largest
object count (TransitionArrays) and adds the per-transition extras (outcome, step, how
each action was chosen, the whole scenes around it). Used by collect.py."""

from __future__ import annotations

import numpy as np

from drake_symplan.datasets import OUTCOMES, TransitionArrays

EXPLORE_MODES = ("random", "disagreement", "goal", "uncovered")  # explorers/active.py


def pack(transitions, modes: bool = False) -> tuple[TransitionArrays, dict[str, np.ndarray]]:
    """Transitions padded to their largest object count, plus per-transition extras (with
    `modes`, "explore_mode": the index in EXPLORE_MODES of how each action was chosen)."""
    n = max(len(t.names) for t in transitions)
    d = transitions[0].state.shape[1]
    T = len(transitions)
    state = np.zeros((T, n, d), np.float32)
    next_state = np.zeros((T, n, d), np.float32)
    action = np.zeros((T, n, transitions[0].action.shape[1]), np.float32)
    effect = np.zeros((T, n, transitions[0].effect.shape[1]), np.float32)
    mask = np.zeros((T, n), bool)
    for i, t in enumerate(transitions):
        k = len(t.names)
        state[i, :k], next_state[i, :k] = t.state, t.next_state
        action[i, :k], effect[i, :k], mask[i, :k] = t.action, t.effect, True
    arrays = TransitionArrays(state, action, effect, mask,
                              np.array([t.episode for t in transitions], np.int64), next_state)
    extra = {"outcome": np.array([OUTCOMES.index(t.outcome) for t in transitions], np.int8),
             "step": np.array([t.step for t in transitions], np.int32)}
    if modes:
        extra["explore_mode"] = np.array([EXPLORE_MODES.index(t.mode) for t in transitions],
                                         np.int8)
    if all(t.scene is not None for t in transitions):
        extra.update(scene_extras([t.scene for t in transitions], n))
    return arrays, extra


def scene_extras(scenes, n: int) -> dict[str, np.ndarray]:
    """The per-transition scene arrays stored beside the transitions (exploration.SceneRecord):
    scene_state / scene_next_state [T, 8, d_o], scene_mask [T, 8], scene_contacts /
    scene_next_contacts [T, 8, 8], scene_slots [T, n] (-1 for padding), chain [T]."""
    slots = np.full((len(scenes), n), -1, np.int8)
    for i, sc in enumerate(scenes):
        slots[i, :len(sc.slots)] = sc.slots
    return {
        "scene_state": np.stack([sc.state for sc in scenes]),
        "scene_next_state": np.stack([sc.next_state for sc in scenes]),
        "scene_mask": np.stack([sc.mask for sc in scenes]),
        "scene_contacts": np.stack([sc.contacts for sc in scenes]),
        "scene_next_contacts": np.stack([sc.next_contacts for sc in scenes]),
        "scene_slots": slots,
        "chain": np.array([sc.chain for sc in scenes], np.int16),
    }
