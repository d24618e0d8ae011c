"""Atomic file writes (standard library only): a reader sees the old file or the whole new
one, never a part, and an interrupted writer leaves no half-written file under the name.

Every writer of shards, manifests, checkpoints, run files and command outputs goes
through `write_atomic`. Its temporary files are named `.NAME.tmp-PID` beside the target;
`remove_stale_tmp` deletes those a killed writer left behind.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

TMP_GLOB = ".*.tmp-*"


def write_atomic(path: str | Path, data: bytes | str | Callable[[BinaryIO], object]) -> Path:
    """Write `data` to `path` atomically; returns the path.

    `data` is bytes, text (written as UTF-8) or a function that writes into the open
    binary file (e.g. `lambda f: np.savez(f, **arrays)`). It goes to a temporary file in
    the same directory, is flushed to disk, then replaces `path` (os.replace); if writing
    fails the temporary file is removed and `path` is left as it was. The directory must
    exist.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            if callable(data):
                data(f)
            else:
                f.write(data.encode() if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def remove_stale_tmp(directory: str | Path) -> list[Path]:
    """Deletes the temporary files of `write_atomic` calls killed mid-write in `directory`."""
    stale = [p for p in Path(directory).glob(TMP_GLOB) if p.is_file()]
    for p in stale:
        p.unlink(missing_ok=True)
    return stale


def save_figure(fig, path: str | Path, dpi: int = 120) -> Path:
    """Writes a matplotlib figure (format from the file's extension) atomically and
    closes it; returns the path."""
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fmt = path.suffix.lstrip(".") or "png"
    try:
        return write_atomic(path, lambda f: fig.savefig(f, format=fmt, dpi=dpi))
    finally:
        plt.close(fig)
