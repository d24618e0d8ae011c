"""Collection and the planning evaluation on a local Ray instance (loopback, 2 CPUs): the same
data and records as the local workers, a worker killed mid-run, bad input."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import collect_args, shard_arrays

ray = pytest.importorskip("ray")

from drake_symplan.cli.main import main  # noqa: E402
from drake_symplan.cluster import WORKER_TITLE  # noqa: E402
from drake_symplan.data.collect import CollectConfig, collect  # noqa: E402
from drake_symplan.data.storage import existing_shards, load_transitions  # noqa: E402

SEED, CHUNK = 3, 4


def config(n: int) -> CollectConfig:
    return CollectConfig(backend="hand", transitions=n, seed=SEED, min_objects=2,
                         max_objects=3, chunk_size=CHUNK)




def assert_same_shards(a: dict, b: dict) -> None:
    x, y = shard_arrays(a), shard_arrays(b)
    assert x.keys() == y.keys()
    for k in x:
        assert np.array_equal(x[k], y[k]), k


def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, monkeypatch):
    out = tmp_path / "data"
    assert main([*collect_args(SEED, CHUNK, out, 4), "--ray", "127.0.0.1:1"]) == 2  # nothing listens
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no Ray head answers at 127.0.0.1:1" in err[0]
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    assert main([*collect_args(SEED, CHUNK, out, 4), "--ray"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'pip install -e ".[ray]"' in err[0]
    assert not out.exists()


@pytest.fixture(scope="module")
def local_ray():
    ray.init(address="local", num_cpus=2, include_dashboard=False,
             _node_ip_address="127.0.0.1", log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """16 transitions (4 chunks) collected by the local engine, in this process."""
    out = tmp_path_factory.mktemp("local") / "data"
    collect(out, config(16), workers=1, progress=False)
    return out


@pytest.mark.slow
def test_the_same_command_on_ray_gives_the_same_data(local_ray, reference, tmp_path, capsys):
    out = tmp_path / "data"
    assert main([*collect_args(SEED, CHUNK, out, 16), "--ray", "--workers", "2"]) == 0
    capsys.readouterr()
    ours, theirs = existing_shards(out), existing_shards(reference)
    assert sorted(ours) == sorted(theirs) == [0, 1, 2, 3]
    for c in ours:
        assert_same_shards(ours[c], theirs[c])
    assert main(["data", "stats", str(out), "--json"]) == 0
    assert '"transitions": 16' in capsys.readouterr().out
    summary = collect(out, config(16), progress=False, ray_address="")  # resumes: nothing to do
    assert summary["this_run"]["new_transitions"] == 0 and summary["this_run"]["engine"] == "ray"


def _worker_pids() -> list[int]:
    pids = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and (proc / "cmdline").read_bytes().startswith(
                    WORKER_TITLE.encode()):
                pids.append(int(proc.name))
        except OSError:
            pass
    return pids


@pytest.mark.slow
def test_a_worker_killed_mid_run_loses_only_its_chunk(local_ray, reference, tmp_path):
    out, n = tmp_path / "data", 28  # 7 chunks; the first 4 are the reference's
    killed: list[tuple[int, int]] = []

    def kill_one_worker():
        deadline = time.time() + 120
        while time.time() < deadline and not existing_shards(out):
            time.sleep(0.05)
        pids = _worker_pids()
        if pids:
            killed.append((pids[0], len(existing_shards(out))))
            os.kill(pids[0], signal.SIGKILL)

    killer = threading.Thread(target=kill_one_worker)
    killer.start()
    summary = collect(out, config(n), workers=2, progress=False, ray_address="")
    killer.join()
    assert killed, "no Ray worker process was found to kill"
    assert 1 <= killed[0][1] < 7, "the kill landed after the last chunk"
    assert summary["transitions"] == n == len(load_transitions(out))
    keys = set()
    for path in existing_shards(out).values():
        with np.load(path) as z:
            keys.update(zip(z["episode"].tolist(), z["step"].tolist(), strict=True))
    assert len(keys) == n  # no (episode, step) twice
    theirs = existing_shards(reference)
    for c in range(4):
        assert_same_shards(existing_shards(out)[c], theirs[c])
    assert not list(out.glob(".*tmp*"))


@pytest.mark.slow
def test_eval_planning_on_ray_gives_the_local_records(local_ray, tmp_path):
    from drake_symplan.evaluation.planning import evaluate_planning
    from drake_symplan.goals.problems import make_problems
    from drake_symplan.world.station import models_dir

    problems = tmp_path / "problems"
    make_problems(problems, 2, [1], 2, 5, "hand")
    runs = [models_dir() / "learned"]
    local = evaluate_planning(runs, problems, robot="hand", monitor=(True,))
    records = tmp_path / "records.jsonl"
    on_ray = evaluate_planning(runs, problems, robot="hand", monitor=(True,),
                               records_path=records, ray_address="")

    def without_times(result):
        return [{k: v for k, v in r.items() if k != "seconds"} for r in result["records"]]

    assert len(without_times(on_ray)) == 2
    assert without_times(on_ray) == without_times(local)
    assert len(records.read_text().splitlines()) == 2
    again = evaluate_planning(runs, problems, robot="hand", monitor=(True,),
                              records_path=records, ray_address="")  # resumes: no solve
    assert again["records"] == on_ray["records"]


@pytest.mark.slow
def test_an_active_collection_on_ray_gives_the_local_data(local_ray, tmp_path):
    import dataclasses as dc

    from drake_symplan.explorers.active import ActiveConfig
    from drake_symplan.explorers.rounds import collect_active

    active = CollectConfig(backend="hand", transitions=20, seed=SEED, min_objects=2,
                           max_objects=3, chunk_size=CHUNK, episode_length=2,
                           explorer="active", active=dc.asdict(ActiveConfig(
                               warmup=12, round_size=8, members=2, epochs=3)))
    local, on_ray = tmp_path / "local", tmp_path / "ray"
    collect_active(local, active, workers=1, progress=False)
    collect_active(on_ray, active, workers=2, progress=False, ray_address="")
    ours, theirs = existing_shards(on_ray), existing_shards(local)
    assert sorted(ours) == sorted(theirs) == list(range(5))
    for c in ours:
        assert_same_shards(ours[c], theirs[c])
    with np.load(ours[4]) as z:  # round 1 chose with its explorer
        assert set(np.unique(z["explore_mode"])) - {0}
