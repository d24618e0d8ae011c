"""shards.py: a data set that lies (a shard cut short, missing from a set whose manifest
says it is complete, or not its own) is one line naming the file, exit 2, for every
reader: `data stats`, `train`; a collection resumed there collects the damaged chunk."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import assert_bad_input, run

from drake_symplan.actions import ACTION_DIM, EFFECT_DIM
from drake_symplan.datasets import TransitionArrays
from drake_symplan.shards import shard_path, shard_paths, write_manifest, write_shard

READERS = [["data", "stats"], ["train", "--model", "reference", "--data"]]


@pytest.fixture
def complete_set(tmp_path):
    """A data set of 3 shards of 2 made-up transitions whose manifest says it is complete."""
    t, n, d = 2, 3, 5
    out = tmp_path / "data"
    for c in range(3):
        write_shard(out, c, TransitionArrays(
            np.zeros((t, n, d)), np.zeros((t, n, ACTION_DIM)), np.zeros((t, n, EFFECT_DIM)),
            np.ones((t, n), bool), np.arange(t) + 10 * c))
    write_manifest(out, {"config": {"transitions": 6, "chunk_size": 2}, "status": "complete"})
    return out


def read_by(reader: list[str], data, tmp_path, capsys):
    """(exit status, stdout, stderr) of `reader` on the data set `data`."""
    argv = [*reader, data] + (["--out", tmp_path / "run"] if reader[0] == "train" else [])
    return run(argv, capsys)


def test_an_intact_complete_set_reads(complete_set):
    assert [p.name for p in shard_paths(complete_set)] == [
        "shard-000000.npz", "shard-000001.npz", "shard-000002.npz"]


@pytest.mark.parametrize("reader", READERS)
def test_a_shard_cut_short_is_one_line_naming_it(reader, complete_set, tmp_path, capsys):
    path = shard_path(complete_set, 1)
    path.write_bytes(path.read_bytes()[:300])
    code, out, err = read_by(reader, complete_set, tmp_path, capsys)
    assert_bad_input(code, out, err)
    assert err == (f"symplan {reader[0]}{' stats' if reader[0] == 'data' else ''}: error: "
                   f"cannot read shard {path}: cut short or damaged (File is not a zip file)\n")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("reader", READERS)
def test_a_shard_missing_from_a_complete_set_is_named(reader, complete_set, tmp_path, capsys):
    shard_path(complete_set, 1).unlink()
    code, out, err = read_by(reader, complete_set, tmp_path, capsys)
    assert_bad_input(code, out, err)
    assert err.endswith(
        f": error: {shard_path(complete_set, 1)} is missing; its manifest says the set is "
        "complete: 6 transitions in 3 shards, shard-000000.npz to shard-000002.npz\n")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("reader", READERS)
def test_a_stray_shard_is_named(reader, complete_set, tmp_path, capsys):
    stray = shard_path(complete_set, 7)
    stray.write_bytes(shard_path(complete_set, 0).read_bytes())
    code, out, err = read_by(reader, complete_set, tmp_path, capsys)
    assert_bad_input(code, out, err)
    assert err.endswith(
        f": error: {stray} is not a shard of this set; its manifest says the set is "
        "complete: 6 transitions in 3 shards, shard-000000.npz to shard-000002.npz\n")


def test_a_set_still_being_collected_promises_no_shards(complete_set):
    from drake_symplan.json_files import read_json

    manifest = read_json(complete_set / "manifest.json")
    write_manifest(complete_set, {**manifest, "status": "collecting"})
    shard_path(complete_set, 1).unlink()
    assert len(shard_paths(complete_set)) == 2


def test_a_damaged_shard_counts_as_not_collected(complete_set):
    from drake_symplan.data.storage import shard_length

    path = shard_path(complete_set, 2)
    assert shard_length(path) == 2
    path.write_bytes(path.read_bytes()[:-40])
    assert shard_length(path) == -1  # collect's resume (data/collect.py _prepare) redoes it


def test_verify_names_every_damaged_missing_or_stray_shard(complete_set, tmp_path, capsys):
    import json

    code, out, err = run(["data", "stats", complete_set, "--verify", "--json"], capsys)
    assert code == 0 and json.loads(out)["damaged"] == {}, err
    cut = shard_path(complete_set, 0)
    cut.write_bytes(cut.read_bytes()[:300])
    flipped = shard_path(complete_set, 1)
    data = bytearray(flipped.read_bytes())
    data[80] ^= 0xFF  # a byte inside the first member: its CRC fails
    flipped.write_bytes(bytes(data))
    shard_path(complete_set, 2).unlink()
    shard_path(complete_set, 7).write_bytes(b"")
    code, out, err = run(["data", "stats", complete_set, "--verify", "--json"], capsys)
    damaged = json.loads(out)["damaged"]
    assert code == 1 and err.count("\n") == 1 and "4 shard(s) damaged or missing" in err
    assert sorted(damaged) == ["shard-000000.npz", "shard-000001.npz", "shard-000002.npz",
                               "shard-000007.npz"]
    assert damaged["shard-000002.npz"] == "missing"
    assert damaged["shard-000007.npz"] == "not a shard of this set"
