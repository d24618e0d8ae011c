"""Active collection in rounds: collect, learn from everything so far, collect with it.

Round 0 is `warmup` random transitions; round r >= 1 collects `round_size` transitions with
the explorer learned from the transitions of rounds 0..r-1. That explorer lives in
`OUT/active/round-RRR/`: `data/` (links to the shards it learned from), `runs/m*` (the
ensemble's members, each trained from its predecessor of the round before: warm start),
`bundle/` (the first member's symbols, their effect-first operators, every member as the
continuous model) and `explorer.json`, written last: a round without it is learned again
from scratch. Training is seeded and single-threaded, so a round learned again after a
kill is the same round, and chunks (data/collect.py) depend only on (config, seed,
chunk, the round's explorer): a collection resumed after a kill, or extended to more
transitions, holds the same data as one run straight through. The manifest's
`active_rounds` records each round's explorer (data fingerprint, models, operators).
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

from drake_symplan.atomic import write_atomic
from drake_symplan.data import storage
from drake_symplan.data.collect import CollectConfig, collect
from drake_symplan.explorers.active import ActiveConfig, ActiveExplorer
from drake_symplan.json_files import read_json
from drake_symplan.learning.checkpoint import BEST, LAST, load_run
from drake_symplan.learning.readout import readout_scenes
from drake_symplan.learning.trainer import TrainConfig, train
from drake_symplan.shards import fingerprint
from drake_symplan.symbolic.bundle import ModelBundle, learn_bundle_operators, write_bundle
from drake_symplan.symbolic.effect_operators import EFFECT, changes, lift_transitions

SYMBOL_MODEL = {"model": "relational", "model_kwargs": {"invariant": True}}
ROUNDS = "active"


def round_dir(out_dir: Path, r: int) -> Path:
    return Path(out_dir) / ROUNDS / f"round-{r:03d}"


def check_rounds(config: CollectConfig, active: ActiveConfig) -> None:
    """Rounds must end on chunk boundaries (a chunk is collected by one explorer)."""
    if active.warmup % config.chunk_size or active.round_size % config.chunk_size:
        raise ValueError(f"--warmup ({active.warmup}) and --round-size "
                         f"({active.round_size}) must be multiples of --chunk-size "
                         f"({config.chunk_size})")


def collect_active(out_dir: str | Path, config: CollectConfig, workers: int | None = 1,
                   progress: bool = True, ray_address: str | None = None,
                   say=lambda text: None, device: str = "auto") -> dict:
    """Collects (or resumes, or extends) an active collection; the summary of the data.
    `device`: where each round's ensemble trains (learning/device.py; not part of the
    data's settings: a resume may train elsewhere)."""
    if config.explorer != "active":
        raise ValueError(f"collect_active collects with the active explorer, not "
                         f"{config.explorer!r}")
    out_dir, active = Path(out_dir), ActiveConfig(**config.active)
    check_rounds(config, active)
    r, new, t0 = 0, 0, time.perf_counter()
    while True:
        end = min(active.round_end(r), config.transitions)
        explorer = None if r == 0 else load_explorer(out_dir, r, config, active, say,
                                                     device)
        say(f"round {r}: transitions {0 if r == 0 else active.round_end(r - 1)}-{end}")
        summary = collect(out_dir, config, workers, progress, ray_address,
                          explorer=lambda c, e=explorer: e, upto=end // config.chunk_size)
        new += summary["this_run"]["new_transitions"]
        if end >= config.transitions:
            break
        r += 1
    wall = time.perf_counter() - t0  # the rounds' collection and learning
    summary["this_run"].update(new_transitions=new, wall_seconds=round(wall, 2),
                               rate_per_s=round(new / wall, 3) if wall > 0 else None)
    manifest = storage.read_manifest(out_dir)
    manifest["active_rounds"] = [
        read_json(round_dir(out_dir, k) / "explorer.json")
        for k in range(1, r + 1)]
    storage.write_manifest(out_dir, manifest)
    summary["active_rounds"] = manifest["active_rounds"]
    return summary


def load_explorer(out_dir: Path, r: int, config: CollectConfig, active: ActiveConfig,
                  say=lambda text: None, device: str = "auto") -> ActiveExplorer:
    """Round r's explorer, learned first if it is not there yet."""
    where = round_dir(out_dir, r)
    if not (where / "explorer.json").is_file():
        learn_round(out_dir, r, config, active, say, device)
    record = read_json(where / "explorer.json")
    return ActiveExplorer(ModelBundle.load(where / "bundle", allow_empty=True), active, record["predicates"])


def learn_round(out_dir: Path, r: int, config: CollectConfig, active: ActiveConfig,
                say=lambda text: None, device: str = "auto") -> dict:
    """Learns round r's explorer from the transitions of rounds 0..r-1 (module docstring)."""
    t0 = time.perf_counter()
    where = round_dir(out_dir, r)
    if where.exists():  # a round a kill interrupted: learned again, the same way
        shutil.rmtree(where)
    n = active.round_end(r - 1)
    data = storage.link_head(out_dir, where / "data", n)
    runs = [where / "runs" / f"m{m}" for m in range(active.members)]
    metrics = []
    for m, run in enumerate(runs):
        before = round_dir(out_dir, r - 1) / "runs" / f"m{m}" / BEST
        say(f"round {r}: training member {m} on {n} transitions")
        metrics.append(train(TrainConfig(
            **SYMBOL_MODEL, data=str(data), out=str(run), seed=m, epochs=active.epochs_for(n),
            patience=active.patience, threads=1, progress=False, device=device,
            init=str(before) if r > 1 else None)))
    model, _ = load_run(runs[0])
    symbols, _ = readout_scenes(model, data)
    operators, semantics, info = learn_bundle_operators(symbols, "effect", active.min_count)
    info["relevance_radius"] = storage.relevance_radius(data)
    record = {"round": r, "transitions": n, "data_fingerprint": fingerprint(data),
              "members": [{"val_error_cm": round(x["val"]["error_cm"], 4),
                           "epochs": x["epochs"]} for x in metrics],
              "operators": len(operators), "predicates": changeable_predicates(symbols)}
    write_bundle(where / "bundle", runs[0], operators, semantics, info,
                 {"active_round": r, "data_fingerprint": record["data_fingerprint"]},
                 continuous_run=runs)
    record["seconds"] = round(time.perf_counter() - t0, 2)
    write_atomic(where / "explorer.json", json.dumps(record, indent=1))
    for run in runs:  # the next round starts from best.pt; a resumed round trains anew
        (run / LAST).unlink()
    return record


def changeable_predicates(symbols) -> list[list]:
    """(predicate, arity) of every atom some transition added: what a goal may ask for."""
    seen = set()
    for tr in lift_transitions(symbols, EFFECT):
        add, _ = changes(tr.before, tr.after, tr.unknown_before, tr.unknown_after)
        seen |= {(a[0], len(a) - 1) for a in add}
    return [list(p) for p in sorted(seen)]
