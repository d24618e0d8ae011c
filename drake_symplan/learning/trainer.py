"""Training loop: seeded Adam with gradient clipping, early stopping, resumable runs.

`train(TrainConfig(...))` loads the whole data set into memory, splits it by
episode (80/10/10, seeded), fits normalisation statistics on the training split,
and runs epochs of shuffled mini-batches. After every epoch it evaluates the
validation loss in eval mode (deterministic bits), appends a row to `log.csv`, saves
`last.pt` and, on improvement, `best.pt`. Training stops after `epochs` epochs or
`patience` epochs without improvement; the test metrics of the best checkpoint go to
`metrics.json`. A run interrupted at any point resumes from `last.pt` with
`resume=True` (same data and settings; `epochs` may be raised), continuing the same
random streams.
"""

from __future__ import annotations

import csv
import dataclasses
import inspect
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch
from tqdm import tqdm

from drake_symplan.learning import checkpoint as ckpt_io
from drake_symplan.learning.dataset import TensorSet, normalization_stats, split_by_episode
from drake_symplan.learning.device import (
    DEFAULT_DEVICE,
    DEVICES,
    describe,
    model_device,
    resolve_device,
)
from drake_symplan.learning.effect_error import effect_metrics, evaluate_loss
from drake_symplan.learning.gumbel import DEFAULT_HARD, DEFAULT_TEMPERATURE
from drake_symplan.learning.models import MODELS, build_model
from drake_symplan.shards import fingerprint, load_transitions

LOG_FIELDS = ("epoch", "train_loss", "val_loss", "val_error_cm", "best_val_loss", "seconds")
# Settings that may differ when a run is resumed.
RESUMABLE_CHANGES = ("epochs", "patience", "threads", "progress", "device")


@dataclass
class TrainConfig:
    """A training run's settings. The defaults are Table I's (README, configs/table1.yaml),
    except `threads`, which Table I set to 1 to run two trainings side by side."""

    model: str
    data: str
    out: str
    epochs: int = 300
    batch_size: int = 128
    lr: float = 1e-3
    seed: int = 0
    patience: int = 30
    grad_clip: float = 10.0
    threads: int | None = None  # torch.set_num_threads; None leaves torch's default
    temperature: float = DEFAULT_TEMPERATURE  # Gumbel-sigmoid; see gumbel.py
    hard: bool = DEFAULT_HARD
    model_kwargs: dict = field(default_factory=dict)
    progress: bool = True
    init: str | None = None  # a checkpoint whose weights training starts from (warm start)
    device: str = DEFAULT_DEVICE  # auto (a GPU when torch sees one), cpu or cuda; device.py

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"unknown model {self.model!r}; expected one of {sorted(MODELS)}")
        for name in ("epochs", "batch_size", "patience"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        if self.lr <= 0:
            raise ValueError(f"lr must be positive, got {self.lr}")
        check_model_kwargs(self.model, self.model_kwargs)
        if self.device not in DEVICES:
            raise ValueError(f"unknown device {self.device!r}; expected one of "
                             f"{', '.join(DEVICES)}")


# Constructor arguments that TrainConfig sets itself (from the data or its own fields).
_SET_BY_TRAINER = ("state_dim", "temperature", "hard")


def check_model_kwargs(model: str, kwargs: dict) -> None:
    """Raise ValueError naming any of `kwargs` that model `model` does not take."""
    params = inspect.signature(MODELS[model].__init__).parameters
    unknown = sorted(k for k in kwargs if k not in params or k == "self")
    if unknown:
        options = sorted(k for k in params if k not in ("self", *_SET_BY_TRAINER))
        raise ValueError(f"model {model!r} has no option {unknown}; it takes {options}")
    fixed = sorted(k for k in kwargs if k in _SET_BY_TRAINER)
    if fixed:
        raise ValueError(f"{fixed} are set by the trainer, not as model options")


def make_model(cfg: TrainConfig, state_dim: int, max_objects: int):
    kwargs = {"state_dim": state_dim, "temperature": cfg.temperature, "hard": cfg.hard,
              **cfg.model_kwargs}
    if cfg.model == "deepsym":
        kwargs.setdefault("max_objects", max_objects)
    return build_model(cfg.model, **kwargs)


def make_optimizer(model: torch.nn.Module, lr: float) -> torch.optim.Adam:
    # The fused CPU kernel is the fastest Adam here; it needs float parameters.
    return torch.optim.Adam(model.parameters(), lr=lr, fused=True)


def train_step(model, optimizer, batch, grad_clip: float) -> torch.Tensor:
    """One Adam step on `batch` = (state, action, effect, mask[, next_state]); returns the
    loss (the model's `training_loss`: the effect loss, and the symbolic transition loss
    where the model has one)."""
    optimizer.zero_grad(set_to_none=True)
    loss = model.training_loss(*batch)
    loss.backward()
    torch.nn.utils.clip_grad_norm_(model.parameters(), grad_clip, foreach=True)
    optimizer.step()
    return loss.detach()


def _check_resumable(saved: dict, cfg: TrainConfig, data_fp: str, out: Path) -> None:
    if saved["data_fingerprint"] != data_fp:
        raise ValueError(f"cannot resume {out}: the data in {cfg.data} changed since it started")
    now, then = dataclasses.asdict(cfg), saved["train_config"]
    # A setting the saved run lacks (added since it started) counts as changed.
    diff = [k for k in sorted(now.keys() | then.keys())
            if k not in RESUMABLE_CHANGES and k not in ("data", "out")
            and now.get(k, None) != then.get(k, None)]
    if diff:
        raise ValueError(f"cannot resume {out}: settings {diff} differ from the saved run")


def _trim_log(path: Path, epoch: int) -> None:
    """Drop log rows past `epoch` (written by a run stopped before it saved last.pt)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    kept = [rows[0]] + [row for row in rows[1:] if row and int(row[0]) <= epoch]
    if len(kept) != len(rows):
        with open(path, "w", newline="") as f:
            csv.writer(f).writerows(kept)


@dataclass
class _Run:
    """A run in progress: what its checkpoints save, and resuming restores."""

    cfg: TrainConfig
    out: Path
    data_fp: str
    model: torch.nn.Module
    optimizer: torch.optim.Optimizer
    shuffle: torch.Generator  # orders the training mini-batches (on the CPU)
    progress: dict
    device: torch.device = torch.device("cpu")

    def restore_last(self) -> None:
        """Continue from last.pt: its model, optimizer, progress and random streams."""
        saved = ckpt_io.read_checkpoint(self.out / ckpt_io.LAST)
        _check_resumable(saved, self.cfg, self.data_fp, self.out)
        self.model.load_state_dict(saved["model_state"])
        self.optimizer.load_state_dict(saved["optimizer_state"])
        self.progress = saved["progress"]
        torch.set_rng_state(saved["rng"]["torch"])
        if self.device.type == "cuda" and "cuda" in saved["rng"]:  # saved on this GPU
            torch.cuda.set_rng_state(saved["rng"]["cuda"], self.device)
        self.shuffle.set_state(saved["rng"]["shuffle"])
        _trim_log(self.out / ckpt_io.LOG, self.progress["epoch"])

    def payload(self, metrics: dict) -> dict:
        """What a checkpoint saves now."""
        return {
            "model": self.cfg.model, "model_config": self.model.config(),
            "model_state": self.model.state_dict(), "optimizer_state": self.optimizer.state_dict(),
            "epoch": self.progress["epoch"], "train_config": dataclasses.asdict(self.cfg),
            "data_fingerprint": self.data_fp, "metrics": metrics, "progress": dict(self.progress),
            "rng": {"torch": torch.get_rng_state(), "shuffle": self.shuffle.get_state(),
                    **({"cuda": torch.cuda.get_rng_state(self.device)}
                       if self.device.type == "cuda" else {})},
        }


def _load_init(model: torch.nn.Module, path: str) -> None:
    """The weights of checkpoint `path`; a symbolic transition head the earlier run lacked
    starts fresh (an effect-only run fine-tuned with the transition objective)."""
    missing, unexpected = model.load_state_dict(ckpt_io.read_checkpoint(path)["model_state"],
                                                strict=False)
    missing = [k for k in missing if not k.startswith("transition.")]
    if missing or unexpected:
        raise ValueError(f"--init {path}: its model differs from this one (missing "
                         f"{missing[:3]}, unexpected {unexpected[:3]})")


def _validation_loss(model, data: TensorSet, effect_loss_value: float) -> float:
    """What early stopping watches: the effect loss, or with a symbolic transition head
    the objective trained (effect + weighted transition loss, eval-mode bits)."""
    if getattr(model, "transition_weight", 0.0) <= 0:
        return effect_loss_value
    device = model_device(model)
    model.eval()
    total = 0.0
    with torch.no_grad():
        for batch in data.batches(4096, with_next=True):
            total += float(model.training_loss(*(t.to(device) for t in batch))) * len(batch[0])
    return total / len(data)


def _check_run_dir(out: Path, resume: bool) -> None:
    last_path = out / ckpt_io.LAST
    if last_path.exists() and not resume:
        raise ValueError(f"{out} already holds a run; resume it or choose another output")
    if resume and not last_path.exists():
        raise FileNotFoundError(f"nothing to resume: {last_path} does not exist")


def _load_data(data_path: Path, seed: int):
    """The transitions in `data_path`, their fingerprint, episode split and split TensorSets."""
    arrays = load_transitions(data_path)
    data_fp = fingerprint(data_path)
    splits = split_by_episode(arrays.episode, seed)
    sets = {name: TensorSet.from_arrays(arrays, idx) for name, idx in splits.items()}
    if len(sets["train"]) == 0 or len(sets["val"]) == 0:
        raise ValueError(f"{data_path}: the train or validation split is empty")
    return arrays, data_fp, splits, sets


def _trial_step(model, cfg: TrainConfig, train_set: TensorSet) -> None:
    """The model's loss on two training transitions, before anything is written: model
    options it cannot run with (n_unary=-1) or an objective the data cannot feed are bad
    input now, not after the run directory is made. torch's random state is left as it
    was, so the run is the same as without it."""
    with_next = getattr(model, "transition_weight", 0.0) > 0
    if with_next and train_set.next_state is None:
        raise ValueError(f"{cfg.data}: the symbolic transition objective needs next_state "
                         "in the data set")
    was_training = model.training
    with torch.random.fork_rng(devices=[]), torch.no_grad():
        try:
            model.eval()
            model.training_loss(*train_set.batch(torch.arange(min(2, len(train_set))),
                                                 with_next))
        except (AttributeError, TypeError, ValueError, RuntimeError, IndexError) as e:
            if not cfg.model_kwargs:
                raise
            raise ValueError(f"model {cfg.model!r} cannot run with options "
                             f"{cfg.model_kwargs}: {e}") from e
        finally:
            model.train(was_training)


def _start_log(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    with open(out / ckpt_io.LOG, "w", newline="") as f:
        csv.writer(f).writerow(LOG_FIELDS)


def _train_epoch(run: _Run, train_set: TensorSet) -> float:
    """One pass over the shuffled training set; returns its mean mini-batch loss."""
    run.model.train()
    total, n_batches = torch.zeros((), device=run.device), 0
    with_next = getattr(run.model, "transition_weight", 0.0) > 0
    if with_next and train_set.next_state is None:
        raise ValueError(f"{run.cfg.data}: the symbolic transition objective needs next_state "
                         "in the data set")
    for batch in train_set.batches(run.cfg.batch_size, run.shuffle, with_next):
        total += train_step(run.model, run.optimizer, batch, run.cfg.grad_clip)
        n_batches += 1
    return float(total) / max(1, n_batches)


def _count_epoch(progress: dict, val_loss: float) -> bool:
    """Records a finished epoch in `progress`; returns whether the validation loss improved."""
    progress["epoch"] += 1
    improved = val_loss < progress["best_val_loss"]
    if improved:
        progress.update(best_val_loss=val_loss, best_epoch=progress["epoch"], bad_epochs=0)
    else:
        progress["bad_epochs"] += 1
    return improved


def _append_log_row(path: Path, progress: dict, train_loss: float, val: dict,
                    seconds: float) -> None:
    with open(path, "a", newline="") as f:  # before last.pt: see _trim_log
        csv.writer(f).writerow([progress["epoch"], f"{train_loss:.6g}", f"{val['loss']:.6g}",
                                f"{val['error_cm']:.4f}", f"{progress['best_val_loss']:.6g}",
                                f"{seconds:.3f}"])


def _fit(run: _Run, sets: dict) -> bool:
    """Runs epochs until `epochs` are done or `patience` runs out; returns whether it did."""
    cfg, last_path = run.cfg, run.out / ckpt_io.LAST
    stopped_early = run.progress["bad_epochs"] >= cfg.patience
    bar = tqdm(total=cfg.epochs, initial=min(run.progress["epoch"], cfg.epochs), unit="epoch",
               desc=f"train {cfg.model}", disable=not cfg.progress)
    while run.progress["epoch"] < cfg.epochs and not stopped_early:
        start = time.perf_counter()
        train_loss = _train_epoch(run, sets["train"])
        if not math.isfinite(train_loss):
            raise ValueError(f"training diverged in epoch {run.progress['epoch'] + 1} "
                             f"(loss {train_loss}); {last_path} holds the previous epoch")
        val = effect_metrics(run.model, sets["val"])
        val["loss"] = _validation_loss(run.model, sets["val"], val["loss"])
        improved = _count_epoch(run.progress, val["loss"])
        metrics = {"train_loss": train_loss, "val_loss": val["loss"],
                   "val_error_cm": val["error_cm"]}
        _append_log_row(run.out / ckpt_io.LOG, run.progress, train_loss, val,
                        time.perf_counter() - start)
        if improved:
            ckpt_io.save_checkpoint(run.out / ckpt_io.BEST, run.payload(metrics))
        ckpt_io.save_checkpoint(last_path, run.payload(metrics))
        bar.update(1)
        bar.set_postfix(train=f"{train_loss:.3g}", val=f"{val['loss']:.3g}",
                        val_cm=f"{val['error_cm']:.2f}")
        stopped_early = run.progress["bad_epochs"] >= cfg.patience
    bar.close()
    return stopped_early


def _final_metrics(run: _Run, sets: dict, stopped_early: bool) -> dict:
    """Evaluates best.pt on every split into metrics.json; returns what it wrote."""
    best_model = ckpt_io.model_from_checkpoint(ckpt_io.read_checkpoint(run.out / ckpt_io.BEST),
                                               run.device)
    progress = run.progress
    result = {
        "run": str(run.out), "model": run.cfg.model, "epochs": progress["epoch"],
        "best_epoch": progress["best_epoch"], "best_val_loss": progress["best_val_loss"],
        "stopped_early": stopped_early, "data_fingerprint": run.data_fp,
        "val": effect_metrics(best_model, sets["val"]),
        "test": effect_metrics(best_model, sets["test"]) if len(sets["test"]) else None,
        "train_loss_eval": evaluate_loss(best_model, sets["train"]),
        "parameters": int(sum(p.numel() for p in best_model.parameters())),
    }
    ckpt_io.write_json(run.out / ckpt_io.METRICS, result)
    return result


def train(cfg: TrainConfig, resume: bool = False) -> dict:
    """Train `cfg.model` on `cfg.data` into run directory `cfg.out`; returns the metrics.
    On `cfg.device` (resolved: device.py): the model and the training set move there once;
    the mini-batch order and the validation and test metrics stay on the CPU."""
    device = resolve_device(cfg.device)
    if cfg.threads is not None:
        torch.set_num_threads(cfg.threads)
    out = Path(cfg.out)
    _check_run_dir(out, resume)
    data_path = Path(cfg.data).resolve()
    arrays, data_fp, splits, sets = _load_data(data_path, cfg.seed)

    torch.manual_seed(cfg.seed)
    try:
        model = make_model(cfg, arrays.state.shape[2], int(arrays.mask.sum(axis=1).max()))
    except (TypeError, AttributeError, RuntimeError) as e:
        if not cfg.model_kwargs:
            raise
        raise ValueError(f"model {cfg.model!r} cannot be made with options "
                         f"{cfg.model_kwargs}: {e}") from e
    if cfg.init is not None:  # the weights of an earlier run; normalised for this data
        _load_init(model, cfg.init)
    model.set_normalization(**normalization_stats(arrays.subset(splits["train"])))
    _trial_step(model, cfg, sets["train"])  # before the run directory is made
    model.to(device)
    sets["train"] = sets["train"].to(device)
    run = _Run(cfg, out, data_fp, model, make_optimizer(model, cfg.lr),
               shuffle=torch.Generator().manual_seed(cfg.seed),
               progress={"epoch": 0, "best_val_loss": math.inf, "best_epoch": 0, "bad_epochs": 0},
               device=device)
    if resume:
        run.restore_last()
    else:
        _start_log(out)
    ckpt_io.write_json(out / ckpt_io.CONFIG, {
        "train_config": dataclasses.asdict(cfg), "model": cfg.model,
        "model_config": model.config(), "data": str(data_path), "data_fingerprint": data_fp,
        "split_sizes": {k: int(len(v)) for k, v in splits.items()},
        "versions": ckpt_io.versions(), **describe(device),
    })
    stopped_early = _fit(run, sets)
    return _final_metrics(run, sets, stopped_early)
