"""Data set storage for collection: the shard format of `drake_symplan.shards` (re-exported
here) plus what resuming a collection needs (which shards exist, how long they are; stray
temporary files: `atomic.remove_stale_tmp`, re-exported) and its summary file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drake_symplan.atomic import remove_stale_tmp, write_atomic  # noqa: F401 - re-exported
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


def write_json(out_dir: str | Path, name: str, data: dict) -> Path:
    """Writes `data` as `out_dir/name` atomically."""
    return write_atomic(Path(out_dir) / name, json.dumps(data, indent=2))
