"""write_atomic: whole file or the old one, never a part; no temporary file left behind."""

import numpy as np
import pytest

from drake_symplan.atomic import remove_stale_tmp, write_atomic


def test_writes_bytes_text_and_writer_functions(tmp_path):
    assert write_atomic(tmp_path / "a.bin", b"\x00\x01") == tmp_path / "a.bin"
    assert (tmp_path / "a.bin").read_bytes() == b"\x00\x01"
    write_atomic(tmp_path / "a.txt", "é\n")
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "é\n"
    write_atomic(tmp_path / "a.npz", lambda f: np.savez(f, x=np.arange(3)))
    with np.load(tmp_path / "a.npz") as z:
        assert z["x"].tolist() == [0, 1, 2]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin", "a.npz", "a.txt"]


def test_a_failing_writer_leaves_the_old_file_and_no_temporary(tmp_path):
    write_atomic(tmp_path / "f", "old")

    def fail(f):
        f.write(b"half")
        raise RuntimeError("killed")

    with pytest.raises(RuntimeError, match="killed"):
        write_atomic(tmp_path / "f", fail)
    assert (tmp_path / "f").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["f"]


def test_remove_stale_tmp_deletes_only_temporaries(tmp_path):
    (tmp_path / ".shard-000001.npz.tmp-123").write_bytes(b"half")
    (tmp_path / "shard-000000.npz").write_bytes(b"whole")
    assert [p.name for p in remove_stale_tmp(tmp_path)] == [".shard-000001.npz.tmp-123"]
    assert [p.name for p in tmp_path.iterdir()] == ["shard-000000.npz"]
