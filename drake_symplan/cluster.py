"""Ray engine: worker actors that build their station once and run many jobs for the driver;
`run_jobs_local`, the same on local worker processes where Ray is not installed.

`ray_session(address)` joins the cluster at `address` (`""`: `ray.init()` on this machine)
unless Ray is already initialised, and shuts down what it started. A HOST:PORT is checked
first, quietly (no head there, a token the head refuses or that is missing here: one
ValueError naming the fix, not Ray's retries and GCS warnings on stderr); Ray's token
authentication (on by default since Ray 2.5x) needs `RAY_AUTH_MODE=token` and the head's
token on every node and on the driver, see docs/cluster.md. `run_jobs` creates one
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
import signal
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import NamedTuple

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
    if _check_reachable(address):
        _check_token(address)
    try:
        if address:  # joining: Ray's connection warnings only if it fails (then not at all)
            with _stderr_captured() as captured:
                ray.init(address=address)
            sys.stderr.write("".join(captured))
        else:
            ray.init()
    except (ConnectionError, ValueError, RuntimeError, ray.exceptions.RayError) as e:
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise ValueError(f"cannot join the Ray cluster at {address or 'this machine'}: "
                         f"{first}") from e
    try:
        yield ray
    finally:
        ray.shutdown()


def _check_reachable(address: str) -> bool:
    """A HOST:PORT no Ray head answers at is bad input now (ray.init would retry for
    minutes); other forms ("auto", "ray://...") are left to Ray: False."""
    host, _, port = address.rpartition(":")
    if not host or not port.isdigit() or "/" in address:
        return False
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_SECONDS).close()
    except OSError as e:
        raise ValueError(f"no Ray head answers at {address} ({e}); start one with "
                         f"`ray start --head` there") from e
    return True


TOKEN_HELP = ("with the head's token here: copy its ~/.ray/auth_token to this machine or "
              "set RAY_AUTH_TOKEN (docs/cluster.md)")


def auth_token_source() -> str | None:
    """Where Ray would read this machine's token from, in its order: the RAY_AUTH_TOKEN
    variable, the file RAY_AUTH_TOKEN_PATH names, ~/.ray/auth_token; None: no token."""
    if os.environ.get("RAY_AUTH_TOKEN", "").strip():
        return "RAY_AUTH_TOKEN"
    named = os.environ.get("RAY_AUTH_TOKEN_PATH")
    path = os.path.expanduser(named or os.path.join("~", ".ray", "auth_token"))
    try:
        with open(path) as f:
            return path if f.read().strip() else None
    except OSError:
        return None


def _check_token(address: str) -> None:
    """Asks the head at `address` for its cluster id once, as ray.init would, with stderr
    silenced: a head with token authentication that refuses this process is one ValueError
    saying what to set. A token mode without a token is refused before (Ray would abort
    the process). Anything else is left to ray.init."""
    token_mode = os.environ.get("RAY_AUTH_MODE", "").strip().lower() == "token"
    source = auth_token_source()
    if token_mode and source is None:
        raise ValueError(f"RAY_AUTH_MODE=token but no Ray token on this machine: run "
                         f"again {TOKEN_HELP}")
    if token_mode and _answers_without_token(address):  # its workers could not call back
        raise ValueError(f"the Ray cluster at {address} has token authentication off but "
                         f"RAY_AUTH_MODE=token here: start its nodes with RAY_AUTH_MODE=token "
                         f"too, or set RAY_AUTH_MODE=disabled here (docs/cluster.md)")
    try:
        from ray._raylet import GcsClient
        from ray.exceptions import AuthenticationError
    except ImportError:  # another Ray: ray.init says what is wrong
        return
    try:
        with _stderr_captured():
            GcsClient(address=address)
    except AuthenticationError as e:
        if not token_mode:
            raise ValueError(f"the Ray cluster at {address} uses token authentication: "
                             f"export RAY_AUTH_MODE=token and run again {TOKEN_HELP}") from e
        raise ValueError(f"the Ray cluster at {address} refused the token from {source}: "
                         f"run again {TOKEN_HELP}") from e
    except Exception:  # noqa: BLE001 - not the token: ray.init tells
        return


def _answers_without_token(address: str) -> bool:
    """Whether the head at `address` lets a process without token authentication in (a
    child process: the mode is fixed per process)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH_")}
    code = "import sys; from ray._raylet import GcsClient; GcsClient(address=sys.argv[1])"
    try:
        return subprocess.run([sys.executable, "-c", code, address],
                              env={**env, "RAY_AUTH_MODE": "disabled"}, capture_output=True,
                              timeout=60).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


@contextmanager
def _stderr_captured():
    """Everything written to file descriptor 2 (Ray's C++ core logs there, its Python
    loggers through sys.stderr) goes to a temporary file; yields a list that holds its
    text on exit."""
    text: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield text
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            text.append(tmp.read().decode(errors="replace"))


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
        self.node = ray.get_runtime_context().get_node_id()
        self.jobs = 0
        self.state = setup(*setup_args)

    def ready(self) -> bool:
        return True

    def run(self, key, job: Callable, *args):
        def tick(n: int) -> None:
            self.progress.report.remote(key, n)  # fire and forget

        out = key, job(self.state, *args, tick=tick)
        self.jobs += 1
        return out

    def ran(self) -> tuple[str, int]:
        """(its node's id, the jobs it finished since it (re)started)."""
        return self.node, self.jobs


class Progress:
    """The latest `tick` of each job since the driver last asked."""

    def __init__(self):
        self.latest: dict = {}

    def report(self, key, n: int) -> None:
        self.latest[key] = n

    def take(self) -> dict:
        out, self.latest = self.latest, {}
        return out


class RayRun(NamedTuple):
    """What `run_jobs` tells: the perf_counter time at which every worker had its state
    built (its start-up done), and the jobs finished on each node (by node id; a worker
    restarted mid-run counts its jobs since the restart)."""
    ready_at: float
    jobs_by_node: dict[str, int]


def run_jobs(ray, setup: Callable, setup_args: tuple, job: Callable,
             jobs: Iterable[tuple], workers: int, on_done: Callable,
             on_progress: Callable | None = None) -> RayRun:
    """Runs `job(state, *args, tick=tick)` for each `(key, *args)` of `jobs` on `workers`
    StationWorker actors; calls `on_done(key, result)` on the driver as each finishes (in
    any order) and `on_progress(key, n)` with the jobs' ticks."""
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
        jobs_by_node: dict[str, int] = {}
        for node, n in ray.get([actor.ran.remote() for actor in actors]):
            jobs_by_node[node] = jobs_by_node.get(node, 0) + n
    finally:
        for actor in [*actors, progress]:
            ray.kill(actor)
    return RayRun(ready_at if ready_at is not None else time.perf_counter(), jobs_by_node)


# --- local worker processes -------------------------------------------------------------

_local: dict = {}


def _init_local(setup: Callable, setup_args: tuple, parent_pid: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's to handle
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
    except KeyboardInterrupt:  # Ctrl-C: the workers stop now, as after kill -9
        for process in list((pool._processes or {}).values()):
            process.terminate()
        raise
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
