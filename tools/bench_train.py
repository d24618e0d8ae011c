"""Benchmark of the learning layer: Adam step time per model and symbol read-out rate.

    python tools/bench_train.py --json [--out FILE] [--device auto|cpu|cuda]

An Adam step (forward, summed-over-objects MSE, backward, clip at 10, fused Adam) at
batch 128 with 4 objects on `--device` (default cpu; `symplan train --device`), with
`--threads` CPU threads (default 2), for each model; on a GPU each step is timed to its
end (torch.cuda.synchronize), and `steps_per_s` is 1000 / step_ms:
`--steps` timed steps after a warm-up, repeated `--repeats` times; the reported
figure is the median over repeats of the per-repeat median. Read-out: deterministic
unary and relational symbols before and after `--readout-transitions` transitions of
RelationalDeepSym (`readout_dataset`), in transitions per second.
Acceptance: RelationalDeepSym step <= 10 ms (the peer implementation: 139 ms) and
read-out >= 10,000 transitions/s.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

from drake_symplan.actions import ACTION_DIM, EFFECT_DIM
from drake_symplan.datasets import TransitionArrays
from drake_symplan.learning.device import DEVICES, describe, resolve_device
from drake_symplan.learning.models import build_model
from drake_symplan.learning.readout import readout_dataset
from drake_symplan.learning.trainer import make_optimizer, train_step

STEP_LIMIT_MS = 10.0
READOUT_MIN_RATE = 10_000.0
PEER_STEP_MS = 139.0


def random_arrays(t: int, n: int, state_dim: int, seed: int) -> TransitionArrays:
    """Random transitions with 2..n real objects, a source in slot 0, a target in slot 1."""
    rng = np.random.default_rng(seed)
    mask = np.arange(n)[None, :] < rng.integers(2, n + 1, size=(t, 1))
    action = np.zeros((t, n, ACTION_DIM), np.float32)
    action[:, 0, 0] = action[:, 0, 2] = action[:, 1, 4] = action[:, 1, 6] = 1.0
    return TransitionArrays(
        state=rng.normal(size=(t, n, state_dim)).astype(np.float32),
        action=action,
        effect=(0.02 * rng.normal(size=(t, n, EFFECT_DIM))).astype(np.float32) * mask[..., None],
        mask=mask,
        episode=np.arange(t, dtype=np.int64),
        next_state=rng.normal(size=(t, n, state_dim)).astype(np.float32),
    )


def bench_step(name: str, state_dim: int, batch: int, n: int, steps: int, repeats: int,
               warmup: int, device: torch.device | str = "cpu") -> dict:
    device = torch.device(device)
    torch.manual_seed(0)
    kwargs = {"max_objects": n} if name == "deepsym" else {}
    model = build_model(name, state_dim=state_dim, **kwargs).train().to(device)
    optimizer = make_optimizer(model, lr=1e-4)
    arrays = random_arrays(batch, n, state_dim, seed=0)
    data = tuple(torch.as_tensor(x).to(device) for x in
                 (arrays.state, arrays.action, arrays.effect, arrays.mask))
    sync = (lambda: torch.cuda.synchronize(device)) if device.type == "cuda" else (lambda: None)
    for _ in range(warmup):
        train_step(model, optimizer, data, 10.0)
    medians = []
    for _ in range(repeats):
        times = []
        for _ in range(steps):
            sync()
            start = time.perf_counter()
            train_step(model, optimizer, data, 10.0)
            sync()
            times.append(time.perf_counter() - start)
        medians.append(1000.0 * statistics.median(times))
    return {
        "step_ms": statistics.median(medians),
        "steps_per_s": round(1000.0 / statistics.median(medians), 1),
        "repeat_medians_ms": [round(m, 3) for m in medians],
        "parameters": int(sum(p.numel() for p in model.parameters())),
    }


def bench_readout(state_dim: int, n: int, transitions: int, repeats: int) -> dict:
    torch.manual_seed(0)
    model = build_model("relational", state_dim=state_dim).eval()
    arrays = random_arrays(transitions, n, state_dim, seed=1)
    readout_dataset(model, arrays.subset(np.arange(min(1000, transitions))))  # warm-up
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        readout_dataset(model, arrays)
        seconds.append(time.perf_counter() - start)
    best = statistics.median(seconds)
    return {"transitions": transitions, "seconds": best, "rate_per_s": transitions / best}


def cpu_facts() -> dict:
    """CPU model and widest vector extension. A step time means little without them: the
    same Relational step has measured 6.5 ms on one day's host and 15 ms on another's."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return {}
    model = next((line.split(":", 1)[1].strip() for line in info.splitlines()
                  if line.startswith("model name")), "")
    flags = set(next((line.split(":", 1)[1].split() for line in info.splitlines()
                      if line.startswith("flags")), []))
    simd = next((f for f in ("avx512f", "avx2", "avx") if f in flags), "none")
    return {"cpu_model": model, "simd": simd, "cpus": len(os.sched_getaffinity(0))}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--out", default=None, help="also write the JSON to this file")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--device", choices=DEVICES, default="cpu",
                        help="where the Adam steps run (auto: a GPU when torch sees one)")
    parser.add_argument("--state-dim", type=int, default=9,
                        help="object feature size d_o (perception.features.FEATURE_DIM = 9)")
    parser.add_argument("--batch-size", type=int, default=128)
    parser.add_argument("--objects", type=int, default=4)
    parser.add_argument("--steps", type=int, default=60, help="timed steps per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--warmup", type=int, default=20)
    parser.add_argument("--readout-transitions", type=int, default=50_000)
    args = parser.parse_args(argv)

    try:
        device = resolve_device(args.device)
    except ValueError as e:
        print(f"bench_train: error: {e}", file=sys.stderr)
        return 2
    torch.set_num_threads(args.threads)
    models = {}
    for name in ("relational", "attentive", "deepsym"):
        models[name] = bench_step(name, args.state_dim, args.batch_size, args.objects,
                                  args.steps, args.repeats, args.warmup, device)
        if not args.json:
            print(f"{name}: {models[name]['step_ms']:.2f} ms per Adam step", file=sys.stderr)
    readout = bench_readout(args.state_dim, args.objects, args.readout_transitions, 3)
    result = {
        "settings": {**{k: getattr(args, k) for k in
                        ("threads", "state_dim", "batch_size", "objects", "steps", "repeats",
                         "warmup")}, **describe(device)},
        "adam_step": models,
        "readout": readout,
        "acceptance": {
            "relational_step_ms_max": STEP_LIMIT_MS,
            "relational_step_ok": models["relational"]["step_ms"] <= STEP_LIMIT_MS,
            "readout_rate_min": READOUT_MIN_RATE,
            "readout_ok": readout["rate_per_s"] >= READOUT_MIN_RATE,
            "peer_step_ms": PEER_STEP_MS,
        },
        "machine": {"python": platform.python_version(), "torch": torch.__version__,
                    "processor": platform.processor() or platform.machine(), **cpu_facts()},
    }
    text = json.dumps(result, indent=2)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)  # --out may name a new folder
        Path(args.out).write_text(text + "\n")
    if args.json:
        print(text)
    else:
        print(f"read-out: {readout['rate_per_s']:.0f} transitions/s", file=sys.stderr)
    ok = result["acceptance"]["relational_step_ok"] and result["acceptance"]["readout_ok"]
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
