"""The device a model trains on: `--device auto|cpu|cuda` of `symplan train`, `collect
--explorer active`, `reproduce` and `curve`. `auto` is a CUDA GPU when torch sees one, else
the CPU; `cuda` without one is bad input (a ValueError: one line, exit status 2)."""

from __future__ import annotations

import torch

DEVICES = ("auto", "cpu", "cuda")
DEFAULT_DEVICE = "auto"


def resolve_device(name: str = DEFAULT_DEVICE) -> torch.device:
    """The torch device `name` (one of DEVICES) means on this machine."""
    if name not in DEVICES:
        raise ValueError(f"unknown device {name!r}; expected one of {', '.join(DEVICES)}")
    if name == "cuda" and not torch.cuda.is_available():
        build = "built without CUDA" if torch.version.cuda is None else \
            f"CUDA {torch.version.cuda}, but no GPU is visible"
        raise ValueError(f"--device cuda: torch {torch.__version__} ({build}) has no GPU "
                         f"here; use --device cpu or auto")
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    return torch.device(name)


def describe(device: torch.device) -> dict:
    """What a run's config.json records of the device it trained on."""
    out = {"device": str(device)}
    if device.type == "cuda":
        out["gpu"] = torch.cuda.get_device_name(device)
    return out


def model_device(model: torch.nn.Module) -> torch.device:
    """The device of a model's parameters (or buffers); the CPU for an empty one."""
    for tensor in (*model.parameters(), *model.buffers()):
        return tensor.device
    return torch.device("cpu")
