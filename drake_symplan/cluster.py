"""Ray engine: worker actors that build their station once and run many jobs for the driver;
`run_jobs_local`, the same on local worker processes where Ray is not installed.

`ray_session(address)` joins the cluster at `address` (`""`: `ray.init()` on this machine)
unless Ray is already initialised, and shuts down what it started. `run_jobs` creates one
`StationWorker` actor per worker (one CPU each); an actor calls `setup(*setup_args)` once
(a collection back-end, an agent) and then runs `job(state, *args, tick=...)` for each job
it is handed by a `ray.util.ActorPool`. A worker process that dies (kill -9, a lost node)
is restarted by Ray (`max_restarts`) and the job it had in flight is retried on it
(`max_task_retries`); a job's exception is not retried and is raised on the driver. Jobs
report progress with `tick(n)` (n done so far in this attempt) to a small actor the driver
polls, so one bar on the driver follows every worker. Results come back through Ray's
object store; the driver writes them, so workers need no shared file system.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import socket
import time
import uuid
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager

POLL_SECONDS = 0.2  # the driver's progress polling period
CONNECT_SECONDS = 5.0  # to reach a head at HOST:PORT
WORKER_TITLE = "ray::StationWorker"  # the process title of a worker actor


def require_ray():
    """The `ray` module; a ValueError (bad input) that says how to install it if missing."""
    try:
        import ray
    except ImportError as e:
        raise ValueError('--ray needs Ray, which is not installed: pip install -e ".[ray]"') \
            from e
    return ray


@contextmanager
def ray_session(address: str = ""):
    """Yields the `ray` module connected to the cluster at `address` (empty: `ray.init()`,
    which starts Ray on this machine or joins the one already running here). A session
    already initialised in this process is used as it is and left running."""
    ray = require_ray()
    if ray.is_initialized():
        yield ray
        return
    _check_reachable(address)
    try:
        ray.init(address=address or None)
    except (ConnectionError, ValueError) as e:
        raise ValueError(f"cannot join the Ray cluster at {address or 'this machine'}: "
                         f"{e}") from e
    try:
        yield ray
    finally:
        ray.shutdown()


def _check_reachable(address: str) -> None:
    """A HOST:PORT no Ray head answers at is bad input now (ray.init would retry for
    minutes); other forms ("auto", "ray://...") are left to Ray."""
    host, _, port = address.rpartition(":")
    if not host or not port.isdigit() or "/" in address:
        return
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_SECONDS).close()
    except OSError as e:
        raise ValueError(f"no Ray head answers at {address} ({e}); start one with "
                         f"`ray start --head` there") from e


def cluster_cpus(ray) -> int:
    """CPUs of the connected cluster: one worker actor each."""
    return max(1, int(ray.cluster_resources().get("CPU", 1)))


class StationWorker:
    """One Ray worker: its state (a back-end with its station, an agent) is built once and
    every job it runs reuses it."""

    def __init__(self, setup: Callable, setup_args: tuple, progress: str):
        import ray

        # By name: an actor handle among the arguments would keep them in the object store,
        # from where a restart may not get them back (ray-project/ray#53727).
        self.progress = ray.get_actor(progress)
        self.state = setup(*setup_args)

    def ready(self) -> bool:
        return True

    def run(self, key, job: Callable, *args):
        def tick(n: int) -> None:
            self.progress.report.remote(key, n)  # fire and forget

        return key, job(self.state, *args, tick=tick)


class Progress:
    """The latest `tick` of each job since the driver last asked."""

    def __init__(self):
        self.latest: dict = {}

    def report(self, key, n: int) -> None:
        self.latest[key] = n

    def take(self) -> dict:
        out, self.latest = self.latest, {}
        return out


def run_jobs(ray, setup: Callable, setup_args: tuple, job: Callable,
             jobs: Iterable[tuple], workers: int, on_done: Callable,
             on_progress: Callable | None = None) -> float:
    """Runs `job(state, *args, tick=tick)` for each `(key, *args)` of `jobs` on `workers`
    StationWorker actors; calls `on_done(key, result)` on the driver as each finishes (in
    any order) and `on_progress(key, n)` with the jobs' ticks. Returns the perf_counter time
    at which every worker had its state built (its start-up done)."""
    from ray.util import ActorPool

    remote = ray.remote(num_cpus=1, max_restarts=-1, max_task_retries=-1)(StationWorker)
    name = f"symplan-progress-{uuid.uuid4().hex}"
    progress = ray.remote(num_cpus=0, max_restarts=-1, max_task_retries=-1)(Progress).options(
        name=name).remote()
    actors = [remote.remote(setup, setup_args, name) for _ in range(workers)]
    ready = [a.ready.remote() for a in actors]  # an actor runs its calls in order
    ready_at = None
    pool = ActorPool(actors)
    try:
        for key, *args in jobs:
            pool.submit(lambda actor, value: actor.run.remote(*value), (key, job, *args))
        while pool.has_next():
            try:
                on_done(*pool.get_next_unordered(timeout=POLL_SECONDS))
            except TimeoutError:
                pass
            if on_progress is not None:
                for key, n in ray.get(progress.take.remote()).items():
                    on_progress(key, n)
            if ready_at is None and not ray.wait(ready, num_returns=len(ready), timeout=0)[1]:
                ready_at = time.perf_counter()
    finally:
        for actor in [*actors, progress]:
            ray.kill(actor)
    return ready_at if ready_at is not None else time.perf_counter()


# --- local worker processes -------------------------------------------------------------

_local: dict = {}


def _init_local(setup: Callable, setup_args: tuple, parent_pid: int) -> None:
    _local.update(state=setup(*setup_args), parent=parent_pid)


def _run_local(task: tuple):
    if os.getppid() != _local["parent"]:  # the driver was killed: stop, return nothing
        os._exit(1)
    key, job, *args = task
    return key, job(_local["state"], *args)


def run_jobs_local(setup: Callable, setup_args: tuple, job: Callable,
                   jobs: Iterable[tuple], workers: int, on_done: Callable) -> None:
    """`run_jobs` on `workers` local processes (spawned: Drake and forked children do not
    mix), each with its state built once; `on_done(key, result)` runs in this process as
    each job finishes, in any order. A job's exception is raised here; a worker that dies
    raises BrokenProcessPool (the jobs not done are lost: a resumable caller runs again).
    On an exception the jobs not started are cancelled."""
    pool = ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"),
                               initializer=_init_local,
                               initargs=(setup, setup_args, os.getpid()))
    try:
        futures = [pool.submit(_run_local, (key, job, *args)) for key, *args in jobs]
        for future in as_completed(futures):
            on_done(*future.result())
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
