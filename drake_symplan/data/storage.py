"""Data set storage for collection: the shard format of `drake_symplan.shards` (re-exported
here) plus what resuming a collection needs (which shards exist, how long they are; stray
temporary files: `atomic.remove_stale_tmp`, re-exported) and its summary file.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from drake_symplan.atomic import remove_stale_tmp, write_atomic  # noqa: F401 - re-exported
from drake_symplan.shards import (  # noqa: F401 - the format, re-exported for data/*
    MANIFEST,
    REQUIRED_KEYS,
    SCHEMA_VERSION,
    SHARD_GLOB,
    UNREADABLE,
    fingerprint,
    load_extra,
    load_transitions,
    read_manifest,
    read_shard_arrays,
    relevance_radius,
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
    """Number of transitions in a shard; -1 if the file cannot be read (cut short or
    damaged: a collection resumed there collects its chunk again)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return int(z["episode"].shape[0])
    except UNREADABLE:
        return -1


def write_json(out_dir: str | Path, name: str, data: dict) -> Path:
    """Writes `data` as `out_dir/name` atomically."""
    return write_atomic(Path(out_dir) / name, json.dumps(data, indent=2))


def link_head(data_dir: str | Path, view: str | Path, transitions: int) -> Path:
    """A data set `view` of the first `transitions` of `data_dir`: links to its first
    shards (which must hold exactly that many) and a manifest naming where they are from.
    An earlier view there is replaced."""
    data_dir, view = Path(data_dir), Path(view)
    shards, total = [], 0
    for c, path in sorted(existing_shards(data_dir).items()):
        if total >= transitions:
            break
        if c != len(shards):
            break  # a gap: the head ends before it
        shards.append(path)
        total += shard_length(path)
    if total != transitions:
        raise ValueError(f"the first shards of {data_dir} do not hold exactly {transitions} "
                         f"transitions (they hold {total} up to that count)")
    _link_shards(shards, view)
    write_manifest(view, {"head_of": str(data_dir), "transitions": transitions,
                          "config": read_manifest(data_dir).get("config")})
    return view


def link_join(sources: list[str | Path], view: str | Path) -> Path:
    """A data set `view` of every transition of `sources`, one after the other: links to
    their shards, numbered on, and a manifest naming them (its config the first's, each
    source's under "configs"). Sets collected under different relevance are refused: their
    symbols relate different pairs. Episode numbers stay each source's own, so a split by
    episode keeps an episode of one set with the same-numbered one of another. An earlier
    view there is replaced."""
    sources, view = [Path(s) for s in sources], Path(view)
    radii = sorted({relevance_radius(s) for s in sources})
    if len(radii) > 1:
        raise ValueError(f"the sets were collected under different relevance ({radii} m); "
                         f"a joined set must relate the same pairs")
    shards = [path for source in sources for _, path in sorted(existing_shards(source).items())]
    _link_shards(shards, view)
    configs = [read_manifest(s).get("config") for s in sources]
    total = sum(shard_length(path) for path in shards)
    write_manifest(view, {"joined": [str(s) for s in sources], "transitions": total,
                          "config": configs[0], "configs": configs})
    return view


def _link_shards(shards: list[Path], view: Path) -> None:
    """`view`'s shards replaced by links to `shards`, numbered from 0 in their order."""
    view.mkdir(parents=True, exist_ok=True)
    for old in view.glob(SHARD_GLOB):
        old.unlink()
    for index, path in enumerate(shards):
        shard_path(view, index).symlink_to(os.path.relpath(path.resolve(), view.resolve()))
