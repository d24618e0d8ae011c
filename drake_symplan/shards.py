"""The transition data set format: sharded on-disk storage (numpy only: no Drake, no torch).

`learning` reads data sets through this module and `data` writes them through it, so
neither needs the other (data/storage.py adds collection bookkeeping and re-exports it).

A data set is a directory holding

- `shard-000000.npz`, `shard-000001.npz`, ...: one `TransitionArrays` each, stored
  under its field names (`state`, `action`, `effect`, `mask`, `episode`,
  `next_state`); shards may differ in their object count N;
- `manifest.json`: at least `{"schema_version": 1}`; collection adds its own keys.

Shards and the manifest are written atomically (`atomic.write_atomic`), so a reader
never sees half a shard and an interrupted writer leaves no corrupt file behind. A set
damaged afterwards is told, naming the file, by every reader: a shard cut short or
otherwise unreadable, and, where the manifest says a collection is complete (`status`
"complete", its `config` giving `transitions` and `chunk_size`), a shard missing from
it or one that is not its own.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
import zlib
from pathlib import Path

import numpy as np

from drake_symplan.atomic import write_atomic
from drake_symplan.boxes import CONTACT_TOLERANCE
from drake_symplan.datasets import TransitionArrays
from drake_symplan.json_files import read_json

SCHEMA_VERSION = 1
MANIFEST = "manifest.json"
SHARD_GLOB = "shard-*.npz"
REQUIRED_KEYS = ("state", "action", "effect", "mask", "episode")
# What numpy and zipfile raise on a shard file cut short or damaged.
UNREADABLE = (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error)


def shard_path(out_dir: str | Path, index: int) -> Path:
    return Path(out_dir) / f"shard-{index:06d}.npz"


def write_shard(
    out_dir: str | Path, index: int, arrays: TransitionArrays,
    extra: dict[str, np.ndarray] | None = None,
) -> Path:
    """Write `arrays` as shard `index` of `out_dir` atomically; returns its path.

    `extra` arrays (e.g. collection bookkeeping) are stored alongside under their own
    names; `load_transitions` ignores them.
    """
    if index < 0:
        raise ValueError(f"shard index must be non-negative, got {index}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = shard_path(out_dir, index)
    fields = {
        "state": arrays.state.astype(np.float32, copy=False),
        "action": arrays.action.astype(np.float32, copy=False),
        "effect": arrays.effect.astype(np.float32, copy=False),
        "mask": arrays.mask.astype(bool, copy=False),
        "episode": arrays.episode.astype(np.int64, copy=False),
    }
    if arrays.next_state is not None:
        fields["next_state"] = arrays.next_state.astype(np.float32, copy=False)
    for key, value in (extra or {}).items():
        if key in fields or key == "next_state":
            raise ValueError(f"extra array {key!r} would overwrite a transition field")
        fields[key] = np.asarray(value)
    return write_atomic(path, lambda f: np.savez(f, **fields))


def write_manifest(out_dir: str | Path, info: dict | None = None) -> Path:
    """Write `manifest.json` (atomically) with `schema_version` plus `info`."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    manifest = {"schema_version": SCHEMA_VERSION, **(info or {})}
    return write_atomic(out_dir / MANIFEST, json.dumps(manifest, indent=2))


def read_manifest(data_dir: str | Path) -> dict:
    """The manifest of `data_dir`, checked for a known schema version."""
    path = Path(data_dir) / MANIFEST
    if not Path(data_dir).exists():
        raise FileNotFoundError(f"data directory {data_dir} does not exist")
    if not Path(data_dir).is_dir():
        raise NotADirectoryError(f"data directory {data_dir} is not a directory")
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist: {data_dir} is not a data set directory")
    manifest = read_json(path)
    if manifest.get("schema_version") != SCHEMA_VERSION:
        raise ValueError(f"{path} has no schema_version {SCHEMA_VERSION}")
    return manifest


def promised_shards(manifest: dict) -> int | None:
    """How many shards (indices 0 to n - 1) the manifest of a complete collection says the
    set holds; None where it promises none (a set still being collected, a view of one,
    a set made by hand)."""
    config = manifest.get("config")
    if manifest.get("status") != "complete" or not isinstance(config, dict):
        return None
    total, size = config.get("transitions"), config.get("chunk_size")
    if not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in (total, size)):
        return None
    return -(-total // size)


def shard_paths(data_dir: str | Path) -> list[Path]:
    """The shard files of `data_dir` in index order; errors if there are none, or, when
    its manifest says the collection is complete, if one is missing or not its own."""
    data_dir = Path(data_dir)
    manifest = read_manifest(data_dir)
    paths = sorted(data_dir.glob(SHARD_GLOB))
    if not paths:
        raise ValueError(f"data directory {data_dir} holds no {SHARD_GLOB} files")
    n = promised_shards(manifest)
    if n is not None:
        names = {path.name for path in paths}
        wanted = [shard_path(data_dir, c) for c in range(n)]
        missing = [path for path in wanted if path.name not in names]
        promise = (f"its manifest says the set is complete: {manifest['config']['transitions']}"
                   f" transitions in {n} shards, {wanted[0].name} to {wanted[-1].name}")
        if missing:
            more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
            raise ValueError(f"{missing[0]} is missing{more}; {promise}")
        stray = sorted(names - {path.name for path in wanted})
        if stray:
            more = f" (and {len(stray) - 1} more)" if len(stray) > 1 else ""
            raise ValueError(f"{data_dir / stray[0]} is not a shard of this set{more}; "
                             f"{promise}")
    return paths


def damaged_shards(data_dir: str | Path) -> dict[str, str]:
    """Every shard of `data_dir` that is missing, not the set's own, or damaged (a member
    whose zip CRC-32 fails, a file cut short, arrays missing), by file name, with why;
    empty: every shard reads whole. Reads every byte of every shard."""
    data_dir = Path(data_dir)
    paths = sorted(data_dir.glob(SHARD_GLOB))
    found: dict[str, str] = {}
    n = promised_shards(read_manifest(data_dir))
    if n is not None:
        wanted = {shard_path(data_dir, c).name for c in range(n)}
        found |= {name: "missing" for name in sorted(wanted - {p.name for p in paths})}
        found |= {p.name: "not a shard of this set" for p in paths if p.name not in wanted}
    for path in paths:
        if path.name in found:
            continue
        try:
            with zipfile.ZipFile(path) as z:
                bad = z.testzip()
            if bad is not None:
                found[path.name] = f"{bad} fails its CRC"
                continue
            _read_shard(path)
        except (zipfile.BadZipFile, ValueError, *UNREADABLE) as e:
            found[path.name] = str(e).strip() or type(e).__name__
    return found


def _unreadable(path: Path, error: BaseException) -> ValueError:
    """The one-line error of a shard file that cannot be read."""
    detail = str(error).strip() or type(error).__name__
    return ValueError(f"cannot read shard {path}: cut short or damaged ({detail})")


def _read_shard(path: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as z:
            fields = {key: z[key] for key in z.files}
    except UNREADABLE as e:
        raise _unreadable(path, e) from e
    missing = [key for key in REQUIRED_KEYS if key not in fields]
    if missing:
        raise ValueError(f"shard {path} lacks arrays {missing}")
    return fields


def _pad(arr: np.ndarray, n: int) -> np.ndarray:
    if arr.shape[1] == n:
        return arr
    width = [(0, 0), (0, n - arr.shape[1])] + [(0, 0)] * (arr.ndim - 2)
    return np.pad(arr, width)


def load_transitions(data_dir: str | Path) -> TransitionArrays:
    """All shards of `data_dir` concatenated in index order, N padded to the largest."""
    shards = []
    for path in shard_paths(data_dir):
        fields = _read_shard(path)
        try:
            TransitionArrays(**{k: fields.get(k) for k in (*REQUIRED_KEYS, "next_state")})
        except (ValueError, IndexError) as e:
            raise ValueError(f"shard {path} is malformed: {e}") from e
        shards.append((path, fields))
    with_next = [("next_state" in fields) for _, fields in shards]
    if any(with_next) and not all(with_next):
        lacking = [str(p) for (p, _), w in zip(shards, with_next, strict=True) if not w]
        raise ValueError(f"shards {lacking} lack next_state while others have it")
    widths = {path.name: fields["state"].shape[2] for path, fields in shards}
    if len(set(widths.values())) > 1:
        raise ValueError(f"shards of {data_dir} differ in feature width: {widths}")
    n = max(fields["mask"].shape[1] for _, fields in shards)
    keys = [*REQUIRED_KEYS] + (["next_state"] if all(with_next) else [])
    cat = {}
    for key in keys:
        parts = [fields[key] if key == "episode" else _pad(fields[key], n) for _, fields in shards]
        cat[key] = np.concatenate(parts, axis=0)
    return TransitionArrays(
        state=cat["state"].astype(np.float32, copy=False),
        action=cat["action"].astype(np.float32, copy=False),
        effect=cat["effect"].astype(np.float32, copy=False),
        mask=cat["mask"].astype(bool, copy=False),
        episode=cat["episode"].astype(np.int64, copy=False),
        next_state=cat.get("next_state"),
    )


def fingerprint(data_dir: str | Path) -> str:
    """sha256 over the contents of the shard files, taken in name order."""
    h = hashlib.sha256()
    for path in shard_paths(data_dir):
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def read_shard_arrays(path: str | Path, keys: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Only the named arrays of one shard (those it has)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in keys if k in z.files}
    except UNREADABLE as e:
        raise _unreadable(Path(path), e) from e


def load_extra(data_dir: str | Path, key: str, pad_value=None) -> np.ndarray | None:
    """The per-transition extra array `key` (e.g. "outcome") of all shards of `data_dir`,
    in `load_transitions` order; None if any shard lacks it. Shards whose arrays differ in
    width (e.g. per relevant object, padded to the shard's largest count) are padded to the
    widest with `pad_value`, as `load_transitions` pads the transitions."""
    parts = []
    for path in shard_paths(data_dir):
        z = read_shard_arrays(path, (key, "episode"))
        if key not in z:
            return None
        if len(z[key]) != len(z["episode"]):
            raise ValueError(f"shard {path}: {key} has {len(z[key])} entries for "
                             f"{len(z['episode'])} transitions")
        parts.append(z[key])
    if pad_value is not None and parts:
        width = np.max([p.shape[1:] for p in parts], axis=0)
        parts = [np.pad(p, [(0, 0)] + [(0, int(w - d)) for w, d in zip(width, p.shape[1:],
                                                                      strict=True)],
                        constant_values=pad_value) for p in parts]
    return np.concatenate(parts)


def relevance_radius(data_dir: str | Path) -> float:
    """The relevance a data set was collected with (CollectConfig.relevance_radius, m): the
    contact rule for a set whose manifest names none."""
    config = read_manifest(data_dir).get("config") if (Path(data_dir) / MANIFEST).is_file() \
        else None
    return float((config or {}).get("relevance_radius", CONTACT_TOLERANCE))
