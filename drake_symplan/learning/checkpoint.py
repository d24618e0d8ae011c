"""Run directories: checkpoints that rebuild their model, and `load_run`.

A run directory holds

- `best.pt`, `last.pt`: {"model", "model_config", "model_state", "optimizer_state",
  "epoch", "train_config", "data_fingerprint", "metrics", "progress", "rng"};
  best is the lowest validation loss, last the end of the latest epoch;
- `config.json`: the training config, model config, data fingerprint and package
  versions, readable without torch;
- `log.csv`: one row per epoch; `metrics.json`: the final result of training.
"""

from __future__ import annotations

import json
import platform
from pathlib import Path

import numpy as np
import torch

import drake_symplan
from drake_symplan.atomic import write_atomic
from drake_symplan.learning.handmade import HANDMADE, HandmadeSymbols
from drake_symplan.learning.models import EffectModel, build_model

BEST = "best.pt"
BUNDLE_MODEL = "model.pt"  # a model bundle's copy of its run's best checkpoint
LAST = "last.pt"
CONFIG = "config.json"
LOG = "log.csv"
METRICS = "metrics.json"


def versions() -> dict:
    return {
        "python": platform.python_version(),
        "torch": torch.__version__,
        "numpy": np.__version__,
        "drake_symplan": getattr(drake_symplan, "__version__", "unknown"),
    }


def save_checkpoint(path: str | Path, payload: dict) -> Path:
    """torch.save `payload` to `path` atomically (`atomic.write_atomic`)."""
    return write_atomic(path, lambda f: torch.save(payload, f))


def write_json(path: str | Path, obj: dict) -> Path:
    """`obj` as indented JSON at `path`, written atomically."""
    return write_atomic(path, json.dumps(obj, indent=2))


def read_checkpoint(path: str | Path, device: torch.device | str = "cpu") -> dict:
    """A checkpoint's payload, its tensors on `device` whichever device saved them."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {path} does not exist")
    try:
        return torch.load(path, map_location=device, weights_only=True)
    except Exception as e:  # a truncated or foreign file: say which one
        raise ValueError(f"cannot read checkpoint {path}: {e}") from e


def model_from_checkpoint(ckpt: dict, device: torch.device | str = "cpu") -> EffectModel:
    """The model a checkpoint names, with its weights: one of models.MODELS, or the
    hand-made symbols (handmade.py: nothing to train, so no `--model` of training)."""
    config = dict(ckpt["model_config"])
    if ckpt["model"] == "relational":
        config.setdefault("own_message", False)  # checkpoints from before the option
    model = (HandmadeSymbols(**config) if ckpt["model"] == HANDMADE
             else build_model(ckpt["model"], **config))
    model.load_state_dict(ckpt["model_state"])
    return model.to(device)


def models_from_file(path: str | Path) -> list[EffectModel]:
    """The models of a checkpoint file, in eval mode: one, or an ensemble's members (a file
    of {"members": [checkpoint, ...]})."""
    ckpt = read_checkpoint(path)
    return [model_from_checkpoint(c).eval() for c in ckpt.get("members", [ckpt])]


def best_checkpoint(run_dir: str | Path) -> Path:
    """A run's `best.pt`; of a model bundle (symbolic/bundle.py), its `model.pt`, the best
    checkpoint of the run it was made from."""
    run_dir = Path(run_dir)
    if not (run_dir / BEST).is_file() and (run_dir / BUNDLE_MODEL).is_file():
        return run_dir / BUNDLE_MODEL
    return run_dir / BEST


def load_run(run_dir: str | Path, which: str = BEST) -> tuple[EffectModel, dict]:
    """(model in eval mode, config) from the `best.pt` checkpoint of `run_dir` (or a
    model bundle's model, `best_checkpoint`).

    config has "model", "model_config", "train_config", "data_fingerprint",
    "metrics" and "epoch" of the checkpoint.
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        what = "is not a directory" if run_dir.exists() else "does not exist"
        raise FileNotFoundError(f"run directory {run_dir} {what}")
    ckpt = read_checkpoint(best_checkpoint(run_dir) if which == BEST else run_dir / which)
    model = model_from_checkpoint(ckpt)
    model.eval()
    config = {key: ckpt.get(key) for key in
              ("model", "model_config", "train_config", "data_fingerprint", "metrics", "epoch")}
    return model, config
