"""`collect`: parallel, resumable collection of exploration transitions into shards.

The N transitions are cut into chunks of `chunk_size` (the last one shorter, so the total
is exactly N). Chunk c is one shard, `shard-{c:06d}.npz`, produced by whole episodes drawn
from its own seed stream `default_rng([seed, c])` (episode ids c * EPISODE_STRIDE + k), so
what a chunk holds depends on (config, seed, c) only, never on the number of workers or on
which worker ran it. Shards are written atomically (storage.write_shard), so after a
`kill -9` the same command finds the finished shards, deletes stray temporary files and
produces only the missing chunks: it ends with exactly N transitions, none duplicated.
For the same reason the same command with a larger N extends a finished collection: its
full chunks are the first chunks of the larger one.

Each worker process builds its own station (back-end) once and takes chunks from a pool;
transitions are reported to the parent as they happen for a tqdm bar with rate and ETA.
Workers exit if their parent dies. With `ray_address` the workers are Ray actors instead
(drake_symplan/cluster.py), on this machine or a cluster: each returns its chunk's arrays
and the driver writes the shard, so the data set is the same file for file; Ray restarts a
killed worker and retries its chunk. Each shard also stores its chunk's bookkeeping
(outcome classes, episode ends, skipped transitions) for `stats`.
"""

from __future__ import annotations

import contextlib
import dataclasses as dc
import itertools
import json
import math
import multiprocessing as mp
import os
import queue as queue_lib
import signal
import subprocess
import time
from collections import Counter
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
from tqdm import tqdm

from drake_symplan.boxes import CONTACT_TOLERANCE
from drake_symplan.cluster import RayRun, cluster_cpus, ray_session, run_jobs
from drake_symplan.data import storage
from drake_symplan.data.exploration import EpisodeConfig, random_choice, run_episode
from drake_symplan.data.packing import pack
from drake_symplan.data.stats import dataset_stats
from drake_symplan.robot.backends import BACKENDS, make_backend
from drake_symplan.world.cameras import DepthNoise
from drake_symplan.world.depth_sensor import camera_noise
from drake_symplan.world.scenes import STARTS
from drake_symplan.world.station import BOX_MODULUS, TIME_STEP

EPISODE_STRIDE = 100_000  # episode ids of chunk c are c * EPISODE_STRIDE + k
MAX_EPISODES_PER_CHUNK = 20_000
LEGACY_TIME_STEP = 5e-3  # s: collections whose manifest names no time step ran at 5 ms
LEGACY_BOX_MODULUS = 1e7  # Pa: and those that name no box modulus with boxes of 1e7


@dc.dataclass
class CollectConfig:
    """Everything that determines the data; stored in the manifest, checked on resume.
    Named settings, such as the shipped model's: configs/recipes.yaml (data/recipes.py)."""

    backend: str = "hand"
    transitions: int = 1000
    seed: int = 0
    min_objects: int = 2
    max_objects: int = 4
    episode_length: int = 10
    long_fraction: float = 0.5
    chunk_size: int = 100
    noise_sigma: float = 0.0  # depth noise (m) along camera rays
    noise_dropout: float = 0.0
    time_step: float = TIME_STEP  # s of physics per step (world/station.py)
    box_modulus: float = BOX_MODULUS  # Pa, the boxes' contact (world/station.py)
    camera_noise: str = "none"  # the cameras' sensor model (world/depth_sensor.CAMERA_NOISE)
    # The hand runs on the arm twin what the arm's wrist or fingers would touch otherwise
    # (skills/arm_twin.py); sets made before it (2026-11-27) are the hand's alone.
    hand_twin: bool = True
    # How actions are chosen: "random", or "active" with its settings (explorers/active.py,
    # ActiveConfig as a dict); the data layer records them, the explorers layer acts on them.
    explorer: str = "random"
    active: dict = dc.field(default_factory=dict)
    # Relevance (m): the contact rule (boxes.CONTACT_TOLERANCE) or vicinity (boxes.VICINITY)
    relevance_radius: float = CONTACT_TOLERANCE
    # An episode's first scene: "random" (scattered boxes), "towers" (two towers of two
    # side by side among them, 5 or more objects) or "cubes" (two cubes side by side, 3 or
    # more; world/scenes.STARTS)
    start: str = "random"

    def __post_init__(self):
        if self.backend not in BACKENDS:
            raise ValueError(f"unknown back-end {self.backend!r}; expected one of {tuple(BACKENDS)}")
        if self.transitions < 1 or self.chunk_size < 1 or self.episode_length < 1:
            raise ValueError("transitions, chunk_size and episode_length must be positive")
        for key, unit in (("time_step", " of seconds"), ("box_modulus", " (Pa)")):
            if not 0 < (value := getattr(self, key)) < math.inf:
                raise ValueError(f"{key} must be a positive number{unit}, got {value}")
        if not 0 <= self.seed < 2**32:
            raise ValueError(f"seed must be an integer in [0, 2**32), got {self.seed}")
        for key, low, high, what in (("long_fraction", 0, 1, "a probability"),
                                     ("relevance_radius", CONTACT_TOLERANCE, 0.1, "metres")):
            if not low <= (value := getattr(self, key)) <= high:
                raise ValueError(f"{key} must be {what} in [{low}, {high}], got {value}")
        if not 0 <= self.noise_sigma < math.inf:
            raise ValueError(f"noise_sigma must be a finite number >= 0 (m), got "
                             f"{self.noise_sigma}")
        if not 0 <= self.noise_dropout < 1:  # 1: cameras that see nothing, episodes forever
            raise ValueError(f"noise_dropout must be a fraction in [0, 1), got "
                             f"{self.noise_dropout}")
        camera_noise(self.camera_noise)  # ValueError naming the choices
        self.hand_twin = self.hand_twin and self.backend == "hand"  # the arm has no twin
        if not 2 <= self.min_objects <= self.max_objects <= 8:
            raise ValueError(f"objects must satisfy 2 <= min <= max <= 8, got "
                             f"{self.min_objects}-{self.max_objects}")
        if self.start not in STARTS:
            raise ValueError(f"unknown start {self.start!r}; expected one of {tuple(STARTS)}")
        least = {"towers": 5, "cubes": 3}.get(self.start, 2)
        if self.min_objects < least:
            raise ValueError(f"a start with {self.start} side by side needs min_objects >= "
                             f"{least}, got {self.min_objects}")

    @property
    def num_chunks(self) -> int:
        return math.ceil(self.transitions / self.chunk_size)

    def chunk_count(self, c: int) -> int:
        return min(self.chunk_size, self.transitions - c * self.chunk_size)

    def episode_config(self) -> EpisodeConfig:
        return EpisodeConfig(self.min_objects, self.max_objects, self.episode_length,
                             self.long_fraction, relevance_radius=self.relevance_radius,
                             start=self.start)


def collection_backend(name: str, time_step: float, sensor: str = "none",
                       hand_twin: bool = True, box_modulus: float = BOX_MODULUS):
    """The back-end a collection's workers run: `name` at `time_step` with the boxes'
    `box_modulus`, its cameras' sensor model `sensor` (CollectConfig.camera_noise), the
    hand with or without its arm twin (CollectConfig.hand_twin)."""
    twin = {"arm_twin": hand_twin} if name == "hand" else {}
    return make_backend(name, time_step=time_step, camera_noise=sensor,
                        box_modulus=box_modulus, **twin)


def backend_args(config: CollectConfig) -> tuple:
    """`collection_backend`'s arguments for a collection."""
    return (config.backend, config.time_step, config.camera_noise, config.hand_twin,
            config.box_modulus)


def code_version(packages=("drake_symplan", "drake", "numpy")) -> dict:
    """Installed versions of `packages` (None: not installed) and the git commit."""
    out = {}
    for pkg in packages:
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    try:
        root = Path(__file__).resolve().parents[2]
        out["git_commit"] = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
            timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        out["git_commit"] = None
    return out


# --- one chunk -------------------------------------------------------------------------


def run_chunk(backend, config: CollectConfig, c: int, on_transition=None, choose=None):
    """Produces chunk c: (TransitionArrays, extra arrays, bookkeeping dict); `choose` is
    the explorer (exploration.random_choice when None)."""
    target = config.chunk_count(c)
    rng = np.random.default_rng([config.seed, c])
    backend.rng = np.random.default_rng([config.seed, c, 1])  # perception noise
    backend.noise = (DepthNoise(config.noise_sigma, config.noise_dropout)
                     if config.noise_sigma > 0 or config.noise_dropout > 0 else None)
    transitions, ends, outcomes, skipped = [], Counter(), Counter(), Counter()
    infeasible, episodes, errors = 0, 0, []
    t0, phases0 = time.perf_counter(), backend.seconds()
    while len(transitions) < target:
        if episodes >= MAX_EPISODES_PER_CHUNK:
            raise RuntimeError(f"chunk {c}: {episodes} episodes gave only {len(transitions)} "
                               f"transitions (ends: {dict(ends)})")
        episode = c * EPISODE_STRIDE + episodes
        log = run_episode(backend, rng, config.episode_config(), episode,
                          target - len(transitions), on_transition, choose or random_choice)
        episodes += 1
        transitions.extend(log.transitions)
        ends[log.end] += 1
        outcomes.update(log.outcomes)
        skipped.update(log.skipped)
        infeasible += log.infeasible
        if log.error:
            errors.append(f"episode {episode}: {log.error}")
    arrays, extra = pack(transitions, modes=config.explorer != "random")
    info = {"chunk": c, "transitions": len(transitions), "episodes": episodes,
            "episode_ends": dict(ends), "executed_outcomes": dict(outcomes),
            "skipped_transitions": dict(skipped), "infeasible_actions": infeasible,
            "perception_errors": errors,
            "explore_modes": dict(Counter(t.mode for t in transitions)),
            "seconds": round(time.perf_counter() - t0, 3),
            "phase_seconds": {k: round(v - phases0[k], 3)
                              for k, v in backend.seconds().items()}}
    return arrays, extra, info


# --- workers ---------------------------------------------------------------------------

_worker: dict = {}


def _init_worker(config_dict: dict, progress, parent_pid: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's: it ends the pool
    config = CollectConfig(**config_dict)
    _worker.update(config=config, progress=progress, parent=parent_pid,
                   backend=collection_backend(*backend_args(config)))
    progress.put(0)  # started: its station is built


def _tick() -> None:
    if os.getppid() != _worker["parent"]:  # the parent was killed: stop, write nothing
        os._exit(1)
    if _worker["progress"] is not None:
        _worker["progress"].put(1)


def _run_chunk_task(out_dir: str, c: int, choose) -> None:
    storage.write_shard(out_dir, c, *chunk_shard(_worker["backend"], _worker["config"], c,
                                                 choose, _tick))


def chunk_shard(backend, config: CollectConfig, c: int, choose=None, on_transition=None,
                tick=None):
    """Chunk c as `storage.write_shard(out_dir, c, arrays, extra)` takes it: (arrays, extra
    with the bookkeeping under "info"). `tick(n)`, if given, is told the transitions so far
    (a Ray job's progress, cluster.run_jobs)."""
    if tick is not None:
        count = itertools.count(1)
        on_transition = lambda: tick(next(count))  # noqa: E731
    arrays, extra, info = run_chunk(backend, config, c, on_transition, choose)
    return arrays, {**extra, "info": np.array(json.dumps(info))}


# --- the command -----------------------------------------------------------------------


def collect(out_dir: str | Path, config: CollectConfig, workers: int | None = 1,
            progress: bool = True, ray_address: str | None = None, explorer=None,
            upto: int | None = None) -> dict:
    """Collects (or finishes collecting) `config.transitions` into `out_dir`; the summary.
    `workers` None: one per CPU (of the Ray cluster with `ray_address`). `ray_address`
    None: local worker processes; "" Ray on this machine; else the Ray cluster there.
    `explorer(c)`: the explorer chunk c acts with (None: random); `upto`: collect only
    the chunks before it (one round of active exploration, explorers/rounds.py)."""
    if config.explorer != "random" and explorer is None:
        raise ValueError(f"a {config.explorer!r} collection needs its explorer "
                         f"(explorers/rounds.py collects it)")
    explorer = explorer or (lambda c: None)
    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    with contextlib.ExitStack() as stack:
        ray = None
        if ray_address is not None:  # joined first: a bad address writes nothing
            ray = stack.enter_context(ray_session(ray_address))
            workers = min(workers or cluster_cpus(ray), cluster_cpus(ray))
        workers = max(1, int(workers or os.cpu_count() or 1))
        manifest, todo, already = _prepare(out_dir, config)
        if upto is not None:
            todo = [c for c in todo if c < upto]
        bar = stack.enter_context(tqdm(  # disabled: update and close do nothing
            total=config.transitions, initial=already, unit="tr", desc="collect",
            smoothing=0.05, dynamic_ncols=True, disable=not progress))
        jobs_by_node = None
        if not todo:
            started = time.perf_counter()
        elif ray is not None:
            started, jobs_by_node = _run_ray(ray, out_dir, config, todo,
                                             min(workers, len(todo)), bar, explorer)
        elif workers == 1:
            backend = collection_backend(*backend_args(config))
            started = time.perf_counter()
            for c in todo:
                storage.write_shard(out_dir, c, *chunk_shard(backend, config, c, explorer(c),
                                                             lambda: bar.update(1)))
        else:
            started = _run_pool(out_dir, config, todo, min(workers, len(todo)), bar,
                                explorer)
    wall = time.perf_counter() - t0

    summary = dataset_stats(out_dir)
    new = sum(config.chunk_count(c) for c in todo)
    summary["this_run"] = {"new_transitions": new, "wall_seconds": round(wall, 2),
                           "workers": workers, "engine": "local" if ray is None else "ray",
                           "startup_seconds": round(started - t0, 2),
                           "rate_per_s": round(new / wall, 3) if wall > 0 else None}
    if jobs_by_node is not None:  # Ray: the chunks each node's workers collected
        summary["this_run"]["chunks_by_node"] = jobs_by_node
    if storage.existing_shards(out_dir).keys() >= set(range(config.num_chunks)):
        manifest["status"] = "complete"
    manifest.update(counts={
        k: summary[k] for k in ("transitions", "episodes", "shards", "dropped_episodes")})
    storage.write_manifest(out_dir, manifest)
    storage.write_json(out_dir, "summary.json", summary)
    return summary


def _prepare(out_dir: Path, config: CollectConfig) -> tuple[dict, list[int], int]:
    """Writes or checks the manifest and clears what a kill left; (manifest, the chunks
    still to collect, the transitions already there)."""
    identity = dc.asdict(config)
    if (out_dir / storage.MANIFEST).exists():
        manifest = storage.read_manifest(out_dir)
        stored = manifest.get("config")
        if isinstance(stored, dict):  # settings added since: what such a set was made with
            stored = {"time_step": LEGACY_TIME_STEP, "explorer": "random", "active": {},
                      "camera_noise": "none", "hand_twin": False, "box_modulus":
                      LEGACY_BOX_MODULUS, "relevance_radius": CONTACT_TOLERANCE,
                      "start": "random", **stored}
        if stored != identity:
            if not _extends(stored, identity):
                raise ValueError(
                    f"{out_dir} holds a collection with a different configuration "
                    f"({stored}); use a new --out directory, or the same options (a larger "
                    f"--transitions extends it)")
            manifest.update(config=identity, status="collecting",
                            extended_from=[*manifest.get("extended_from", []),
                                           stored["transitions"]])
            storage.write_manifest(out_dir, manifest)
    else:
        manifest = {"config": identity, "seed": config.seed, "code_version": code_version(),
                    "status": "collecting"}
        storage.write_manifest(out_dir, manifest)
    storage.remove_stale_tmp(out_dir)
    done = storage.existing_shards(out_dir)
    extra_shards = sorted(set(done) - set(range(config.num_chunks)))
    if extra_shards:
        raise ValueError(f"{out_dir} has shards {extra_shards} beyond this collection's "
                         f"{config.num_chunks} chunks")
    for c, path in list(done.items()):
        if storage.shard_length(path) != config.chunk_count(c):
            path.unlink()  # a short last chunk of a collection being extended: redo it
            del done[c]
    todo = [c for c in range(config.num_chunks) if c not in done]
    return manifest, todo, sum(config.chunk_count(c) for c in done)


def _extends(stored: dict | None, identity: dict) -> bool:
    """Whether `identity` is `stored` with more transitions (the chunks already written are
    then exactly chunks of the larger collection; a short last one is regenerated)."""
    if not isinstance(stored, dict) or stored.keys() != identity.keys():
        return False
    same = all(stored[k] == identity[k] for k in identity if k != "transitions")
    return same and identity["transitions"] > stored["transitions"]


def _run_pool(out_dir: Path, config: CollectConfig, todo: list[int], workers: int,
              bar, explorer) -> RayRun:
    """The chunks on local worker processes; returns when they had all started."""
    ctx = mp.get_context("spawn")  # Drake and forked children do not mix
    progress = ctx.Queue()
    started, ready = time.perf_counter(), 0
    with ctx.Pool(workers, initializer=_init_worker,
                  initargs=(dc.asdict(config), progress, os.getpid())) as pool:
        pending = [pool.apply_async(_run_chunk_task, (str(out_dir), c, explorer(c)))
                   for c in todo]
        while pending:
            try:
                while True:
                    n = progress.get(timeout=0.2)
                    bar.update(n)
                    ready += n == 0
                    if n == 0 and ready == workers:
                        started = time.perf_counter()
            except queue_lib.Empty:
                pass
            still = []
            for r in pending:
                if r.ready():
                    r.get()  # re-raises a worker's exception here
                else:
                    still.append(r)
            pending = still
        pool.close()
        pool.join()
    return started


def _run_ray(ray, out_dir: Path, config: CollectConfig, todo: list[int], workers: int,
             bar, explorer) -> RayRun:
    """The chunks on Ray worker actors (cluster.run_jobs); the driver writes each shard as
    it comes. The bar counts, per chunk, the most transitions any attempt reached, so a
    retried chunk is not counted twice. Returns when the workers had all started and the
    chunks each node collected."""
    seen = dict.fromkeys(todo, 0)
    written: set[int] = set()

    def advance(c: int, n: int) -> None:
        if c not in written and n > seen[c]:
            bar.update(n - seen[c])
            seen[c] = n

    def write(c: int, shard: tuple) -> None:
        storage.write_shard(out_dir, c, *shard)
        advance(c, config.chunk_count(c))
        written.add(c)

    return run_jobs(ray, collection_backend, backend_args(config), chunk_shard,
                    [(c, config, c, explorer(c)) for c in todo], workers, write, advance)
