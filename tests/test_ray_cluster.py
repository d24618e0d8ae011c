"""A real two-node Ray cluster on this machine, as docs/cluster.md starts one: a head
(`ray start --head`) and one more node (`ray start --address`), 1 CPU each so both must
run workers, with token authentication (RAY_AUTH_MODE=token and a token of its own in
RAY_AUTH_TOKEN on every node and the driver). `symplan collect --ray` and `symplan eval
planning --ray` run as commands on it: both nodes run jobs, and the data and records are
the local run's. A driver without the token: one line on stderr, exit 2.

The cluster has its own temp dir and ports, so it cannot meet another Ray on the host, and
is stopped at the end, failed or not, by killing its own processes only (its `ray start`
process groups and whatever runs under its temp dir): `ray stop` would stop every Ray on
the machine."""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import collect_args, shard_arrays

pytest.importorskip("ray")

from drake_symplan.cluster import auth_token_source  # noqa: E402
from drake_symplan.data.collect import CollectConfig, collect  # noqa: E402
from drake_symplan.data.storage import existing_shards  # noqa: E402

SEED, CHUNK, N = 3, 4, 16  # 4 chunks over 2 workers
START_SECONDS = 120


_GIVEN: set[int] = set()


def free_port() -> int:
    """A free port not given before in this run: the OS can hand the same free port out
    twice in a row, and two Ray components on one port refuse to start."""
    while True:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port not in _GIVEN:
            _GIVEN.add(port)
            return port


def node_ports() -> list[str]:
    """The ports a node listens on, free ones, so no default (52365...) meets another Ray
    on the host (the Ray client server, 10001, is not started: core Ray has no client)."""
    names = ["--node-manager-port", "--object-manager-port", "--dashboard-agent-listen-port",
             "--dashboard-agent-grpc-port", "--runtime-env-agent-port", "--metrics-export-port"]
    return [f"{name}={free_port()}" for name in names]


def _ours(temp: str, roots: set[int]) -> set[int]:
    """Our processes: `roots`, those whose command line names `temp`, and all their
    descendants."""
    parent, found = {}, set(roots)
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cmd = (proc / "cmdline").read_bytes()
            ppid = int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        parent[int(proc.name)] = ppid
        if temp.encode() in cmd:
            found.add(int(proc.name))
    grew = True
    while grew:
        children = {p for p, pp in parent.items() if pp in found} - found
        found |= children
        grew = bool(children)
    return found - {os.getpid()}


def _stop(starts: list[subprocess.Popen], temp: str) -> None:
    for p in starts:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    deadline = time.time() + 10
    for p in starts:
        try:
            p.wait(timeout=max(0.1, deadline - time.time()))
        except subprocess.TimeoutExpired:
            pass
    for _ in range(3):  # what is left: by process group, then by pid
        for p in starts:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except OSError:
                pass
        for pid in _ours(temp, {p.pid for p in starts}):
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        time.sleep(0.5)


def _start(args: list[str], env: dict, log: Path) -> subprocess.Popen:
    ray = Path(sys.executable).with_name("ray")
    cmd = [str(ray) if ray.exists() else "ray", "start", "--block", *args]
    return subprocess.Popen(cmd, env=env, stdout=log.open("w"), stderr=subprocess.STDOUT,
                            start_new_session=True)


def _wait_started(p: subprocess.Popen, log: Path) -> None:
    deadline = time.time() + START_SECONDS
    while time.time() < deadline:
        if "Ray runtime started" in log.read_text(errors="replace"):
            return
        if p.poll() is not None:
            break
        time.sleep(0.2)
    raise RuntimeError(f"a Ray node did not start:\n{log.read_text(errors='replace')[-3000:]}")


@pytest.fixture(scope="module")
def cluster():
    """(address, env): a head and one more node on 127.0.0.1, 1 CPU each, token
    authentication with a token of their own; `env` is what a driver needs."""
    with two_nodes() as started:
        yield started


@contextlib.contextmanager
def two_nodes(cpus: int = 1, nodes: int = 2, auth: bool = True):
    """The cluster of `cluster`, `cpus` CPUs per node, stopped on leaving; `nodes` 1: the
    head alone; `auth` False: token authentication off (RAY_AUTH_MODE=disabled)."""
    temp = tempfile.mkdtemp(prefix="symplan-ray-", dir="/tmp")  # short: Ray's socket paths
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32),
           "RAY_USAGE_STATS_ENABLED": "0"}
    if not auth:
        env.update(RAY_AUTH_MODE="disabled", RAY_AUTH_TOKEN="")
    env.pop("RAY_ADDRESS", None)
    env.pop("RAY_AUTH_TOKEN_PATH", None)
    port = free_port()
    address = f"127.0.0.1:{port}"
    common = [f"--num-cpus={cpus}", "--num-gpus=0", "--node-ip-address=127.0.0.1",
              "--object-store-memory=100000000", "--disable-usage-stats"]
    starts: list[subprocess.Popen] = []
    try:
        log = Path(temp) / "head.log"
        starts.append(_start(["--head", f"--port={port}", "--include-dashboard=false",
                              f"--temp-dir={temp}/head", *common, *node_ports()],
                             env, log))
        _wait_started(starts[-1], log)
        if nodes > 1:
            log = Path(temp) / "node.log"
            starts.append(_start([f"--address={address}", f"--temp-dir={temp}/node",
                                  *common, *node_ports()], env, log))
            _wait_started(starts[-1], log)
        yield address, env
    finally:
        _stop(starts, temp)
        shutil.rmtree(temp, ignore_errors=True)


def symplan(args: list[str], env: dict) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "drake_symplan.cli.main", *args], env=env,
                          capture_output=True, text=True, timeout=300)




@pytest.mark.slow
def test_collect_on_two_nodes_gives_the_local_data(cluster, tmp_path):
    address, env = cluster
    reference = tmp_path / "local"
    collect(reference, CollectConfig(backend="hand", transitions=N, seed=SEED, min_objects=2,
                                     max_objects=3, chunk_size=CHUNK),
            workers=1, progress=False)
    out = tmp_path / "ray"
    done = symplan([*collect_args(SEED, CHUNK, out, N), "--ray", address], env)
    assert done.returncode == 0, done.stderr[-3000:]
    this_run = json.loads(done.stdout)["this_run"]
    assert this_run["engine"] == "ray" and this_run["workers"] == 2
    chunks = this_run["chunks_by_node"]
    assert len(chunks) == 2 and all(n >= 1 for n in chunks.values()), chunks
    assert sum(chunks.values()) == N // CHUNK
    ours, theirs = existing_shards(out), existing_shards(reference)
    assert sorted(ours) == sorted(theirs) == list(range(N // CHUNK))
    for c in ours:
        x, y = shard_arrays(ours[c]), shard_arrays(theirs[c])
        assert x.keys() == y.keys()
        for k in x:
            assert np.array_equal(x[k], y[k]), (c, k)


@pytest.mark.slow
def test_eval_planning_on_two_nodes_gives_the_local_records(cluster, tmp_path):
    from drake_symplan.evaluation.planning import evaluate_planning
    from drake_symplan.goals.problems import make_problems
    from drake_symplan.world.station import models_dir

    address, env = cluster
    problems = tmp_path / "problems"
    make_problems(problems, 2, [1], 2, 5, "hand")
    run = models_dir() / "learned"
    local = evaluate_planning([run], problems, robot="hand", monitor=(True,))
    records = tmp_path / "records.jsonl"
    done = symplan(["eval", "planning", "--runs", str(run), "--problems", str(problems),
                    "--backend", "hand", "--monitor", "on", "--records", str(records),
                    "--json", "--ray", address], env)
    assert done.returncode == 0, done.stderr[-3000:]
    solves = json.loads(done.stdout)["solves_by_node"]
    assert len(solves) == 2 and all(n == 1 for n in solves.values()), solves

    def without_times(rs):
        return [{k: v for k, v in r.items() if k != "seconds"} for r in rs]

    on_ray = [json.loads(line) for line in records.read_text().splitlines()]
    key = lambda r: r["problem"]  # noqa: E731 - the records come in finishing order
    assert without_times(sorted(on_ray, key=key)) == without_times(
        sorted(local["records"], key=key))
    assert len(on_ray) == 2


@pytest.mark.parametrize("auth, message", [
    ({"RAY_AUTH_MODE": None}, "uses token authentication: export RAY_AUTH_MODE=token"),
    ({"RAY_AUTH_TOKEN": "0" * 64}, "refused the token from RAY_AUTH_TOKEN"),
])
@pytest.mark.slow
def test_a_driver_without_the_token_is_one_line(cluster, tmp_path, auth, message):
    address, env = cluster
    env = dict(env)
    for k, v in auth.items():
        env.pop(k) if v is None else env.update({k: v})
    out = tmp_path / "data"
    done = symplan([*collect_args(SEED, CHUNK, out, 4), "--ray", address], env)
    err = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(err) == 1, done.stderr
    assert message in err[0] and "docs/cluster.md" in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_a_token_driver_at_a_head_without_tokens_is_one_line(tmp_path):
    """Its workers could not call back to a driver that wants a token (Ray 2.60: the actors
    die unstarted), so the driver says so before joining."""
    with two_nodes(nodes=1, auth=False) as (address, env):
        out = tmp_path / "data"
        done = symplan([*collect_args(SEED, CHUNK, out, 4), "--ray", address],
                       {**env, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": "0" * 64})
    err = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(err) == 1, done.stderr
    assert "has token authentication off but RAY_AUTH_MODE=token here" in err[0]
    assert not out.exists()


def test_the_token_is_looked_up_where_ray_reads_it(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.delenv("RAY_AUTH_TOKEN", raising=False)
    monkeypatch.delenv("RAY_AUTH_TOKEN_PATH", raising=False)
    assert auth_token_source() is None
    (tmp_path / ".ray").mkdir()
    (tmp_path / ".ray" / "auth_token").write_text("abc\n")
    assert auth_token_source() == str(tmp_path / ".ray" / "auth_token")
    monkeypatch.setenv("RAY_AUTH_TOKEN_PATH", str(tmp_path / "missing"))
    assert auth_token_source() is None
    monkeypatch.setenv("RAY_AUTH_TOKEN", "abc")
    assert auth_token_source() == "RAY_AUTH_TOKEN"
