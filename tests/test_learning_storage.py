"""Sharded transition storage: round trip, padding, fingerprint, clear errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import assert_bad_input, run

from drake_symplan.datasets import TransitionArrays
from drake_symplan.shards import (
    fingerprint,
    load_extra,
    load_transitions,
    write_manifest,
    write_shard,
)


def _arrays(t: int, n: int, d: int = 3, seed: int = 0, episode0: int = 0) -> TransitionArrays:
    rng = np.random.default_rng(seed)
    mask = np.ones((t, n), bool)
    mask[:, -1] = False
    return TransitionArrays(
        state=rng.normal(size=(t, n, d)).astype(np.float32),
        action=np.zeros((t, n, 8), np.float32),
        effect=rng.normal(size=(t, n, 6)).astype(np.float32),
        mask=mask,
        episode=np.arange(t, dtype=np.int64) + episode0,
        next_state=rng.normal(size=(t, n, d)).astype(np.float32),
    )


def test_round_trip_pads_to_largest_n_in_index_order(tmp_path):
    a, b = _arrays(2, 3, seed=1), _arrays(3, 4, seed=2, episode0=10)
    write_manifest(tmp_path, {"note": "test"})
    write_shard(tmp_path, 1, b)
    path = write_shard(tmp_path, 0, a)
    assert path.name == "shard-000000.npz"
    assert not [p for p in tmp_path.iterdir() if "tmp" in p.name]
    out = load_transitions(tmp_path)
    assert out.state.shape == (5, 4, 3) and out.mask.dtype == bool
    np.testing.assert_array_equal(out.state[:2, :3], a.state)
    np.testing.assert_array_equal(out.state[:2, 3], 0.0)
    np.testing.assert_array_equal(out.mask[:2], np.c_[a.mask, np.zeros((2, 1), bool)])
    np.testing.assert_array_equal(out.effect[2:], b.effect)
    np.testing.assert_array_equal(out.next_state[2:], b.next_state)
    np.testing.assert_array_equal(out.episode, [0, 1, 10, 11, 12])


def test_extra_arrays_load_in_transition_order_or_not_at_all(tmp_path):
    write_manifest(tmp_path)
    write_shard(tmp_path, 1, _arrays(3, 2), {"outcome": np.array([2, 0, 1], np.int8)})
    write_shard(tmp_path, 0, _arrays(2, 2), {"outcome": np.array([4, 3], np.int8)})
    assert load_extra(tmp_path, "outcome").tolist() == [4, 3, 2, 0, 1]
    write_shard(tmp_path, 2, _arrays(1, 2))  # a shard without the array
    assert load_extra(tmp_path, "outcome") is None
    write_shard(tmp_path, 2, _arrays(2, 2), {"outcome": np.array([1], np.int8)})
    with pytest.raises(ValueError, match="shard-000002.*1 entries for 2 transitions"):
        load_extra(tmp_path, "outcome")


def test_extra_arrays_of_different_widths_pad_like_the_transitions(tmp_path):
    write_manifest(tmp_path)
    write_shard(tmp_path, 0, _arrays(1, 3), {"slots": np.array([[0, 1, 2]], np.int8)})
    write_shard(tmp_path, 1, _arrays(2, 2), {"slots": np.array([[3, 1], [0, 2]], np.int8)})
    assert load_extra(tmp_path, "slots", pad_value=-1).tolist() == [
        [0, 1, 2], [3, 1, -1], [0, 2, -1]]


def test_fingerprint_tracks_contents(tmp_path):
    write_manifest(tmp_path)
    write_shard(tmp_path, 0, _arrays(2, 3, seed=1))
    first = fingerprint(tmp_path)
    assert first == fingerprint(tmp_path) and len(first) == 64
    write_shard(tmp_path, 0, _arrays(2, 3, seed=2))
    assert fingerprint(tmp_path) != first


def test_errors_name_the_path(tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere"):
        load_transitions(tmp_path / "nowhere")
    with pytest.raises(FileNotFoundError, match="manifest.json"):
        load_transitions(tmp_path)
    write_manifest(tmp_path)
    with pytest.raises(ValueError, match="no shard"):
        load_transitions(tmp_path)
    (tmp_path / "shard-000000.npz").write_bytes(b"not an npz")
    with pytest.raises(ValueError, match="shard-000000.npz"):
        load_transitions(tmp_path)
    np.savez(tmp_path / "shard-000000.npz", state=np.zeros((1, 2, 3)))
    with pytest.raises(ValueError, match="lacks arrays"):
        load_transitions(tmp_path)
    write_shard(tmp_path, 0, _arrays(2, 3, d=3))
    write_shard(tmp_path, 1, _arrays(2, 3, d=4))
    with pytest.raises(ValueError, match="feature width"):
        load_transitions(tmp_path)
    (tmp_path / "manifest.json").write_text("{}")
    with pytest.raises(ValueError, match="schema_version"):
        load_transitions(tmp_path)


def test_a_head_view_is_the_first_shards_of_a_set_and_nothing_else(tmp_path):
    from drake_symplan.data.storage import link_head

    data = tmp_path / "data"
    write_manifest(data, {"config": {"transitions": 7}})
    for c, (t, episode0) in enumerate([(2, 0), (3, 10), (2, 20)]):
        write_shard(data, c, _arrays(t, 3, seed=c, episode0=episode0))
    view = link_head(data, tmp_path / "head", 5)
    np.testing.assert_array_equal(load_transitions(view).episode, [0, 1, 10, 11, 12])
    assert link_head(data, view, 7) == view  # replaced: now the whole set
    assert fingerprint(view) == fingerprint(data)
    with pytest.raises(ValueError, match="do not hold exactly 4 transitions"):
        link_head(data, tmp_path / "other", 4)  # inside a shard


def test_data_head_makes_a_view_of_the_first_shards_and_refuses_a_count_inside_one(
        tmp_path, capsys):
    data = tmp_path / "data"
    write_manifest(data, {"config": {"transitions": 5}, "status": "complete"})
    for c, (t, episode0) in enumerate([(2, 0), (3, 10)]):
        write_shard(data, c, _arrays(t, 3, seed=c, episode0=episode0))
    code, out, _ = run(["data", "head", data, "--transitions", 2, "--out", tmp_path / "v"],
                       capsys)
    assert code == 0 and "the first 2 transitions" in out
    np.testing.assert_array_equal(load_transitions(tmp_path / "v").episode, [0, 1])
    code, out, err = run(["data", "head", data, "--transitions", 3, "--out",
                          tmp_path / "w"], capsys)
    assert_bad_input(code, out, err, "do not hold exactly 3 transitions")
    assert not (tmp_path / "w").exists()


def test_data_join_makes_a_view_of_sets_one_after_the_other_and_refuses_mixed_relevance(
        tmp_path, capsys):
    for name, episodes, radius in (("a", [(2, 0), (1, 5)], 0.035), ("b", [(3, 0)], 0.035),
                                   ("c", [(2, 0)], 0.006)):
        data = tmp_path / name
        write_manifest(data, {"config": {"transitions": sum(t for t, _ in episodes),
                                         "relevance_radius": radius}, "status": "complete"})
        for c, (t, episode0) in enumerate(episodes):
            write_shard(data, c, _arrays(t, 3, seed=c, episode0=episode0 + 100 * len(name)))
    code, out, _ = run(["data", "join", tmp_path / "a", tmp_path / "b", "--out",
                        tmp_path / "ab"], capsys)
    assert code == 0 and "the 6 transitions of" in out
    joined = load_transitions(tmp_path / "ab")
    np.testing.assert_array_equal(joined.episode, [100, 101, 105, 100, 101, 102])
    assert [p.name for p in sorted((tmp_path / "ab").glob("shard-*.npz"))] == [
        "shard-000000.npz", "shard-000001.npz", "shard-000002.npz"]
    code, out, err = run(["data", "join", tmp_path / "a", tmp_path / "c", "--out",
                          tmp_path / "ac"], capsys)
    assert_bad_input(code, out, err, "different relevance ([0.006, 0.035] m)")
    assert not list((tmp_path / "ac").glob("shard-*"))
