"""Data set storage for collection: the shard format of `drake_symplan.shards` (re-exported
here) plus what resuming a collection needs (which shards exist, how long they are,
stray temporary files) and its summary file.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from drake_symplan.shards import (  # noqa: F401 - the format, re-exported for data/*
    MANIFEST,
    REQUIRED_KEYS,
    SCHEMA_VERSION,
    SHARD_GLOB,
    fingerprint,
    load_extra,
    load_transitions,
    read_manifest,
    read_shard_arrays,
    shard_path,
    shard_paths,
    write_manifest,
    write_shard,
)


def existing_shards(data_dir: str | Path) -> dict[int, Path]:
    """Shard index -> path for the shards present (no manifest needed, may be empty)."""
    out = {}
    for path in Path(data_dir).glob(SHARD_GLOB):
        stem = path.name[len("shard-"):-len(".npz")]
        if stem.isdigit():
            out[int(stem)] = path
    return out


def shard_length(path: str | Path) -> int:
    """Number of transitions in a shard; -1 if the file cannot be read."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return int(z["episode"].shape[0])
    except (OSError, ValueError, KeyError):
        return -1


def remove_stale_tmp(data_dir: str | Path) -> list[Path]:
    """Deletes temporary files left by writers that were killed mid-write."""
    stale = [p for p in Path(data_dir).glob(".*.tmp-*") if p.is_file()]
    for p in stale:
        p.unlink(missing_ok=True)
    return stale


def write_json(out_dir: str | Path, name: str, data: dict) -> Path:
    """Writes `data` as `out_dir/name` atomically."""
    path = Path(out_dir) / name
    tmp = Path(out_dir) / f".{name}.tmp-{os.getpid()}"
    tmp.write_text(json.dumps(data, indent=2))
    os.replace(tmp, path)
    return path
