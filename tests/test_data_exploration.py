"""Exploration bookkeeping on hand-made perceived scenes (no simulator): relevance, effects
with the carry subtracted, outcome classes, random actions, packing and stats."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest

from drake_symplan.actions import ACTION_DIM, EFFECT_DIM, Action, relevant_objects
from drake_symplan.data import storage
from drake_symplan.data.collect import CollectConfig, pack
from drake_symplan.data.exploration import (
    Transition,
    classify,
    effects,
    random_action,
)
from drake_symplan.data.stats import dataset_stats
from drake_symplan.datasets import OUTCOMES


@dc.dataclass
class Obj:
    name: str
    position: np.ndarray
    tilt: float = 0.0
    features: np.ndarray = None


@dc.dataclass
class Scene:
    objects: list
    contacts: set = dc.field(default_factory=set)

    @property
    def names(self):
        return [o.name for o in self.objects]

    def object(self, name):
        return next(o for o in self.objects if o.name == name)


def scene(positions: dict, contacts=(), tilts=None) -> Scene:
    tilts = tilts or {}
    return Scene([Obj(n, np.array(p, float), tilts.get(n, 0.0), np.zeros(9, np.float32))
                  for n, p in positions.items()], set(contacts))


IDENTITY = {"a": "a", "b": "b", "c": "c", "d": "d"}


def test_relevance_is_arguments_plus_their_contacts_before():
    s = scene({"a": (0.6, 0, 0.025), "b": (0.8, 0, 0.025), "c": (0.6, 0, 0.075),
               "d": (0.9, 0.3, 0.025)}, contacts={("a", "c")})
    assert relevant_objects(s, Action("a", "center", "b", "left")) == ["a", "b", "c"]
    assert relevant_objects(s, Action("b", "center", "d", "left")) == ["b", "d"]


def test_effect_subtracts_the_carry_from_lifted_objects_only():
    before = scene({"a": (0.6, 0.0, 0.025), "b": (0.8, 0.1, 0.025), "c": (0.9, 0.3, 0.025)})
    lift = scene({"a": (0.6, 0.0, 0.200), "b": (0.8, 0.1, 0.025), "c": (0.9, 0.3, 0.025)})
    # a lands on b, 2 mm off where the carry put it; c is nudged by 3 cm.
    after = scene({"a": (0.8, 0.102, 0.075), "b": (0.8, 0.1, 0.025), "c": (0.93, 0.3, 0.025)})
    carry = np.array([0.2, 0.1])
    e = effects(before, lift, after, IDENTITY, IDENTITY, ["a", "b", "c"], carry)
    assert e.shape == (3, EFFECT_DIM)
    np.testing.assert_allclose(e[0], [0, 0, 0.175, 0, 0.002, -0.125], atol=1e-6)
    np.testing.assert_allclose(e[1], 0, atol=1e-6)
    np.testing.assert_allclose(e[2], [0, 0, 0, 0.03, 0, 0], atol=1e-6)


def test_outcome_classes():
    before = scene({"a": (0.6, 0, 0.025), "b": (0.8, 0, 0.025), "c": (0.6, 0.1, 0.075)})
    same = scene({"a": (0.6, 0, 0.025), "b": (0.8, 0, 0.025), "c": (0.6, 0.1, 0.075)})
    up_a = scene({"a": (0.6, 0, 0.2), "b": (0.8, 0, 0.025), "c": (0.6, 0.1, 0.075)})
    up_ac = scene({"a": (0.6, 0, 0.2), "b": (0.8, 0, 0.025), "c": (0.6, 0.1, 0.25)})
    placed = scene({"a": (0.8, 0, 0.075), "b": (0.8, 0, 0.025), "c": (0.6, 0.1, 0.075)})
    tipped = scene({"a": (0.8, 0.08, 0.06), "b": (0.8, 0, 0.025), "c": (0.6, 0.1, 0.075)},
                   tilts={"a": np.radians(20)})
    pushed = scene({"a": (0.63, 0, 0.025), "b": (0.8, 0, 0.025), "c": (0.6, 0.1, 0.075)})
    m = IDENTITY
    assert classify(before, same, same, m, m) == "no_effect"
    assert classify(before, up_a, placed, m, m) == "placed"
    assert classify(before, up_a, tipped, m, m) == "tipped"
    assert classify(before, up_ac, placed, m, m) == "carried_along"
    assert classify(before, same, pushed, m, m) == "other"
    assert classify(before, up_a, placed, m, m, left_table=True) == "fell_off"


def test_random_actions_cover_all_offsets_and_never_target_the_source():
    rng = np.random.default_rng(0)
    names = ["p0", "p1", "p2"]
    actions = [random_action(rng, names) for _ in range(300)]
    assert all(a.source != a.target for a in actions)
    assert {a.grasp for a in actions} == {"left", "center", "right"}
    assert {a.release for a in actions} == {"left", "center", "right"}
    assert {a.source for a in actions} == set(names)


def _transitions(k_list, episode0=0):
    out = []
    for i, k in enumerate(k_list):
        names = [f"p{j}" for j in range(k)]
        action = np.zeros((k, ACTION_DIM), np.float32)
        action[0, 0] = action[1, 4] = 1.0
        out.append(Transition(names, np.full((k, 9), i, np.float32), action,
                              np.zeros((k, EFFECT_DIM), np.float32),
                              np.full((k, 9), i + 1, np.float32),
                              OUTCOMES[i % 3], episode0 + i // 2, i % 2))
    return out


def test_pack_pads_with_mask_and_stats_read_the_shards(tmp_path):
    import json

    config = CollectConfig(transitions=5, chunk_size=3)
    storage.write_manifest(tmp_path, {"config": dc.asdict(config)})
    for c, ks in enumerate(([2, 3, 2], [4, 2])):
        arrays, extra = pack(_transitions(ks, episode0=10 * c))
        info = {"executed_outcomes": {"no_effect": 2, "fell_off": 1}, "episode_ends":
                {"length_unrecovered": 1, "perception_unrecovered": 1},
                "skipped_transitions": {"perception_count_mismatch": 1,
                                        "perception_recovering": 2},
                "infeasible_actions": 0, "seconds": 1.0,
                "phase_seconds": {"physics": 0.5, "perception": 0.25}}
        storage.write_shard(tmp_path, c, arrays, extra={**extra, "info": np.array(json.dumps(
            info))})
    data = storage.load_transitions(tmp_path)
    assert data.state.shape == (5, 4, 9)
    np.testing.assert_array_equal(data.mask.sum(axis=1), [2, 3, 2, 4, 2])
    assert not data.state[0, 2:].any() and data.next_state[1, 2, 0] == 2
    stats = dataset_stats(tmp_path)
    assert stats["transitions"] == 5 and stats["shards"] == 2
    assert stats["objects_histogram"] == {"2": 3, "3": 1, "4": 1}
    # Only the episodes that ended early are dropped; one that ran its length lost is not.
    assert stats["dropped_episodes"] == 2 and stats["episodes"] == 4
    assert stats["dropped_reasons"] == {"perception_unrecovered": 2}
    # Per shard: 3 executed actions stored or classified, 1 misperceived, 2 run while lost.
    assert stats["perception_failures_per_action"] == pytest.approx(2 / 12, abs=1e-4)
    assert stats["perception_unrecorded_per_action"] == pytest.approx(6 / 12, abs=1e-4)
    assert stats["executed_outcome_fractions"]["fell_off"] == pytest.approx(1 / 3, abs=1e-3)
    assert sum(stats["outcome_fractions"].values()) == pytest.approx(1.0)
    assert stats["worker_seconds"] == 2.0
    assert stats["worker_seconds_by_phase"] == {"physics": 1.0, "perception": 0.5,
                                                "other": 0.5}


def test_chunks_sum_to_exactly_n():
    config = CollectConfig(transitions=250, chunk_size=100)
    assert config.num_chunks == 3
    assert [config.chunk_count(c) for c in range(3)] == [100, 100, 50]
    with pytest.raises(ValueError, match="objects"):
        CollectConfig(min_objects=1)


class ScriptedBackend:
    """Returns scripted perceived scenes: `perceive()` pops `seen`, `execute` pops `after`."""

    def __init__(self, seen: list, after: list):
        self.seen, self.after = list(seen), list(after)

    def reset(self, scene):
        pass

    def perceive(self, prior=None):
        return self.seen.pop(0)

    def execute(self, action, before, lift=True):
        from drake_symplan.robot.backends import Execution

        return Execution("ok", before, self.after.pop(0))

    def ground_truth_states(self):
        return {}  # nothing left the table


def cubes(*xs: float):
    from drake_symplan.perception.perceive import PerceivedObject, PerceivedScene

    return PerceivedScene([PerceivedObject(f"p{i}", "cube", np.array([x, 0.0, 0.025]), 0.0,
                                           0.0, np.zeros(9, np.float32), False, np.eye(3))
                           for i, x in enumerate(xs)], set())


def test_a_misperceived_scene_is_skipped_and_the_episode_goes_on_once_all_are_seen():
    from drake_symplan.data.exploration import EpisodeConfig, run_episode

    config = EpisodeConfig(min_objects=2, max_objects=2, length=4)
    two, three = cubes(0.5, 0.7), cubes(0.5, 0.6, 0.7)
    # Action 1 ends in a phantom third box: skipped, track lost. Action 2 is perceived
    # from scratch and sees both boxes again: skipped (its 'before' was wrong), recovered.
    backend = ScriptedBackend(seen=[two, two], after=[three, three, two, two])
    log = run_episode(backend, np.random.default_rng(0), config, episode=0, budget=10)
    assert log.end == "length" and not log.dropped
    assert [t.step for t in log.transitions] == [2, 3]
    assert log.skipped == {"perception_count_mismatch": 1, "perception_recovering": 1}

    backend = ScriptedBackend(seen=[two, three, three, three], after=[three] * 4)
    log = run_episode(backend, np.random.default_rng(0), config, episode=0, budget=10)
    # All four actions ran, none could be recorded: not dropped, four skipped.
    assert log.end == "length_unrecovered" and not log.dropped and not log.transitions
    assert sum(log.skipped.values()) == 4

    # Lost track and seeing a single box: no action to draw, the episode ends dropped.
    backend = ScriptedBackend(seen=[two], after=[cubes(0.5)])
    log = run_episode(backend, np.random.default_rng(0), config, episode=0, budget=10)
    assert log.end == "perception_unrecovered" and log.skipped == {
        "perception_lost_object": 1}


def test_perception_raising_drops_the_episode_and_keeps_what_it_recorded():
    from drake_symplan.data.exploration import EpisodeConfig, run_episode
    from drake_symplan.robot.backends import Backend, PerceptionFailure

    class RaisingPerceiver:
        def perceive(self, *args, **kwargs):
            raise ValueError("Points cannot contain NaN")

    backend = Backend.__new__(Backend)  # no station: only the perceiver is called
    backend.station, backend.perceiver, backend.noise, backend.rng = None, RaisingPerceiver(), \
        None, None
    with pytest.raises(PerceptionFailure, match="ValueError: Points cannot contain NaN"):
        backend.perceive()

    class FailingThird(ScriptedBackend):
        def execute(self, action, before, lift=True):
            if not self.after:
                raise PerceptionFailure("perception failed: ValueError: NaN")
            return super().execute(action, before, lift)

    two = cubes(0.5, 0.7)
    config = EpisodeConfig(min_objects=2, max_objects=2, length=4)
    log = run_episode(FailingThird(seen=[two], after=[two, two]), np.random.default_rng(0),
                      config, episode=0, budget=10)
    assert log.end == "perception_error" and log.dropped and "NaN" in log.error
    assert [t.step for t in log.transitions] == [0, 1]


def test_scene_records_keep_identities_through_the_episode_and_renumber_after_a_loss():
    from drake_symplan.data.exploration import EpisodeConfig, run_episode
    from drake_symplan.perception.perceive import PerceivedObject, PerceivedScene

    def tagged(*xs, contacts=()):
        # Features carry the x position, so a slot's identity can be checked.
        return PerceivedScene([PerceivedObject(f"p{i}", "cube", np.array([x, 0.0, 0.025]),
                                               0.0, 0.0, np.full(9, x, np.float32), False,
                                               np.eye(3)) for i, x in enumerate(xs)],
                              set(contacts))

    config = EpisodeConfig(min_objects=2, max_objects=2, length=3)
    a, b = tagged(0.5, 0.7), tagged(0.5, 0.7, contacts={("p0", "p1")})
    backend = ScriptedBackend(seen=[a], after=[a, b, b])
    log = run_episode(backend, np.random.default_rng(0), config, episode=0, budget=10)
    scenes = [t.scene for t in log.transitions]
    assert [sc.chain for sc in scenes] == [0, 0, 0]
    for prev, nxt in zip(scenes, scenes[1:], strict=False):
        np.testing.assert_array_equal(nxt.state, prev.next_state)
    assert scenes[0].mask.tolist() == [True, True] + [False] * 6
    np.testing.assert_allclose(scenes[0].state[:2, 0], [0.5, 0.7], rtol=1e-6)
    assert not scenes[0].next_contacts.any() and scenes[1].next_contacts[0, 1]
    assert scenes[1].next_contacts[1, 0] and scenes[2].contacts[0, 1]
    for t in log.transitions:  # each relevant object's slot holds its own features
        np.testing.assert_array_equal(t.scene.state[t.scene.slots], t.state)

    # Lost after action 1, recovered at action 2: the two recorded steps start a new chain.
    two, three = tagged(0.5, 0.7), tagged(0.5, 0.6, 0.7)
    backend = ScriptedBackend(seen=[two, two], after=[three, three, two, two])
    config = EpisodeConfig(min_objects=2, max_objects=2, length=4)
    log = run_episode(backend, np.random.default_rng(0), config, episode=0, budget=10)
    assert [(t.step, t.scene.chain) for t in log.transitions] == [(2, 0), (3, 0)]
    arrays, extra = pack(log.transitions)
    assert extra["scene_state"].shape == (2, 8, 9) and extra["chain"].tolist() == [0, 0]
    assert extra["scene_slots"].shape == (2, 2) and (extra["scene_slots"] >= 0).all()
