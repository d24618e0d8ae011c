"""Local worker processes (cluster.run_jobs_local): each worker builds its state once, every
result comes back, a job's exception and a worker's death stop the run instead of hanging."""

from __future__ import annotations

import os
from concurrent.futures.process import BrokenProcessPool

import pytest

from drake_symplan.cluster import run_jobs_local


def make_state(offset: int) -> dict:
    return {"offset": offset, "pid": os.getpid()}


def add(state: dict, x: int) -> tuple[int, int]:
    return x + state["offset"], state["pid"]


def fail(state: dict, x: int) -> int:
    raise ValueError(f"bad job {x}")


def die(state: dict, x: int) -> int:
    os._exit(3)  # as a crash in native code would


def test_every_job_runs_once_on_workers_that_set_up_once():
    done = {}
    run_jobs_local(make_state, (100,), add, [(i, i) for i in range(12)], 2,
                   lambda key, result: done.__setitem__(key, result))
    assert sorted(done) == list(range(12))
    assert all(value == key + 100 for key, (value, _) in done.items())
    assert 1 <= len({pid for _, pid in done.values()}) <= 2 and os.getpid() not in {
        pid for _, pid in done.values()}


def test_a_failing_job_raises_in_the_driver():
    with pytest.raises(ValueError, match="bad job 1"):
        run_jobs_local(make_state, (0,), fail, [(1, 1)], 1, lambda key, result: None)


def test_a_dead_worker_stops_the_run():
    with pytest.raises(BrokenProcessPool):
        run_jobs_local(make_state, (0,), die, [(i, i) for i in range(4)], 2,
                       lambda key, result: None)
