"""Child processes under limits: a process group killed at a wall-clock deadline, an
RLIMIT_CPU budget set in the child, and the CPU seconds children used (planners.py, budget.py)."""

from __future__ import annotations

import math
import os
import resource
import signal
import subprocess
import time
from pathlib import Path


def children_cpu() -> float:
    """CPU seconds used so far by this process's finished children."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def cpu_used() -> float:
    """CPU seconds used so far by this process and its finished children."""
    return time.process_time() + children_cpu()


def limit_cpu(seconds: float | None) -> None:
    """In a child: SIGXCPU after `seconds` of CPU (rounded up: the limit has whole
    seconds), then SIGKILL a second later."""
    if seconds is not None:
        soft = max(1, math.ceil(seconds))
        resource.setrlimit(resource.RLIMIT_CPU, (soft, soft + 1))


def run_group(cmd, cwd, env, stdin: Path | None, deadline: float,
               cpu_seconds: float | None = None):
    """Runs `cmd` in its own process group until `deadline` (perf_counter) or its CPU
    budget: (exit code, stdout, stderr), or (None, "", "") when killed at the deadline.
    A command that cannot start is exit code 35, Fast Downward's driver critical error."""
    try:
        with open(stdin) if stdin is not None else open(os.devnull) as feed:
            proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=feed,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    text=True, start_new_session=True,
                                    # preexec_fn is unsafe beside threads: only when asked.
                                    preexec_fn=None if cpu_seconds is None
                                    else (lambda: limit_cpu(cpu_seconds)))
    except OSError as e:
        return 35, "", f"could not start Fast Downward: {e}"
    try:
        out, err = proc.communicate(timeout=max(deadline - time.perf_counter(), 0.001))
    except subprocess.TimeoutExpired:
        kill_group(proc)
        proc.communicate()
        return None, "", ""
    return proc.returncode, out, err


def kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        proc.kill()
