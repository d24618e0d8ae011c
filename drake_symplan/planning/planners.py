"""Planner back-ends behind one interface: Fast Downward (subprocess) and pyperplan.

`plan(domain_path, problem_path, planner="fd" | "pyperplan", wall_seconds=10.0)` returns a
`PlanResult` whose status is one of solved / unsolvable / timeout / error, with the
plan as PDDL step strings `"(action arg ...)"` and the planner's own message when
something went wrong. Nothing here raises for a planner failure: a malformed PDDL
file, an unsolvable task, a timeout or a missing planner all come back as results.

* Fast Downward is the prebuilt build in the `up-fast-downward` wheel, run as subprocesses
  (FD is GPL-3.0; it stays a separate program): its translator, then its search binary,
  as its driver would run them (the driver itself where there is no such build). Every
  call gets its own temporary directory (`output.sas`, `sas_plan`), its own process
  groups, and a wall-clock limit after which the running group is killed. Exit codes
  follow FD's documented table. `fast_downward_sas` runs the search alone on a task
  translated already (planning/grounding.py).
* pyperplan is imported and run in a forked child process, since it has no time limit
  of its own and a Python thread cannot be stopped: at the deadline the child is
  killed, so a timeout really stops the work.

With `cpu_seconds`, both also stop when their processes have used that much CPU (an
RLIMIT_CPU on each child, what is left of the budget), `wall_seconds` then being the wall-clock
cap: a busy host gives the planner the same work as a quiet one (planning/processes.py runs
the children under those limits).

Both default to optimal A* with LM-cut, so on unit-cost tasks their plans have equal
length. Fast Downward's search binary (not the driver alone) gives the optimal search
OPTIMAL_SHARE of the budget and, when it runs out there, a weighted A* with the FF
heuristic (FD_FALLBACK) the rest: on a long goal (two towers of three from six boxes)
A* with LM-cut takes more than 10 s where the weighted search plans in under one,
and on the short goals it finishes first anyway.
"""

from __future__ import annotations

import importlib.util
import multiprocessing
import os
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from drake_symplan.planning.nodes import EXPANDED, fd_expanded
from drake_symplan.planning.processes import children_cpu, limit_cpu, run_group

STATUSES = ("solved", "unsolvable", "timeout", "error")
WALL_FACTOR = 3.0  # the wall-clock cap of a CPU-second budget, as a multiple of it
DEFAULT_TIMEOUT = 10.0
FD_SEARCH = "astar(lmcut())"
FD_FALLBACK = "eager_wastar([ff()], w=2)"  # cost-aware, satisficing: when A* runs out
OPTIMAL_SHARE = 0.4  # of a call's budget, for FD_SEARCH when FD_FALLBACK follows it
FD_ENV = "SYMPLAN_FAST_DOWNWARD"  # overrides the driver path

# Fast Downward exit codes (driver/returncodes.py in the wheel).
_FD_SOLVED = {0: "", 1: "plan found, then out of memory", 2: "plan found, then out of time",
              3: "plan found, then out of memory and time"}
_FD_UNSOLVABLE = {10: "unsolvable (proved by the translator)",
                  11: "unsolvable (search space exhausted)",
                  12: "no plan found by an incomplete search (not a proof of unsolvability)",
                  13: "unsolvable within the bound"}
_FD_TIMEOUT = {21: "translator out of time", 23: "search out of time",
               24: "search out of memory and time"}
_FD_ERROR = {20: "translator out of memory", 22: "search out of memory",
             30: "translator critical error", 31: "translator input error (malformed PDDL?)",
             32: "search critical error", 33: "search input error",
             34: "search configuration not supported", 35: "driver critical error",
             36: "driver input error", 37: "driver: unsupported"}


@dataclass
class PlanResult:
    status: str  # one of STATUSES
    plan: list[str] = field(default_factory=list)
    seconds: float = 0.0
    message: str = ""
    planner: str = ""

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"unknown status {self.status!r}")

    @property
    def solved(self) -> bool:
        return self.status == "solved"

    def to_dict(self) -> dict:
        return asdict(self)


def _check_files(domain, problem) -> tuple[Path, Path]:
    domain, problem = Path(domain), Path(problem)
    for p in (domain, problem):
        if not p.is_file():
            raise FileNotFoundError(f"no PDDL file {p}")
    return domain.resolve(), problem.resolve()


def _read_plan(text: str) -> list[str]:
    steps = []
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith(";"):
            steps.append(line if line.startswith("(") else f"({line})")
    return steps


# ---------------------------------------------------------------- Fast Downward


def find_fast_downward() -> Path | None:
    """The FD driver script: $SYMPLAN_FAST_DOWNWARD, else the one in the
    up-fast-downward wheel (located without importing the wheel's package)."""
    if os.environ.get(FD_ENV):
        path = Path(os.environ[FD_ENV])
        return path if path.is_file() else None
    spec = importlib.util.find_spec("up_fast_downward")
    if spec is None or not spec.submodule_search_locations:
        return None
    for root in spec.submodule_search_locations:
        driver = Path(root) / "downward" / "fast-downward.py"
        if driver.is_file():
            return driver
    return None


def _fd_message(out: str, err: str) -> str:
    """The planner's own explanation: its output minus progress and driver chatter."""
    lines = [ln.strip() for ln in (out + "\n" + err).splitlines() if ln.strip()]
    noise = ("INFO", "->", "Parsing", "Driver aborting", "translate exit code",
             "search exit code", "[t=", "Remove intermediate")
    picked = [ln for ln in lines if not ln.startswith(noise)]
    return "; ".join((picked or lines)[-4:])


def fast_downward(domain, problem, wall_seconds: float = DEFAULT_TIMEOUT, search: str = FD_SEARCH,
                  driver: str | Path | None = None, cpu_seconds: float | None = None,
                  fallback: str | None = FD_FALLBACK) -> PlanResult:
    """Fast Downward on PDDL files, in a temporary directory, under a time limit (and a
    CPU budget, see the module docstring). `fallback`: the search that takes over when
    `search` runs out of its OPTIMAL_SHARE of the budget (None: `search` has it all)."""
    start = time.perf_counter()
    domain, problem = _check_files(domain, problem)

    def result(status, plan=(), message=""):
        return PlanResult(status, list(plan), time.perf_counter() - start, message, "fd")

    driver = Path(driver) if driver is not None else find_fast_downward()
    if driver is None or not driver.is_file():
        return result("error", message=(
            f"Fast Downward not found (driver {driver}); install the up-fast-downward "
            f"wheel or set {FD_ENV} to a fast-downward.py"))
    with tempfile.TemporaryDirectory(prefix="symplan-fd-") as tmp:
        plan_file = Path(tmp) / "sas_plan"
        components = _fd_components(driver)
        then = None
        if components is None:
            # The wall-clock limit below is the time limit: the driver's own limits are
            # CPU-time rlimits, which kill the translator early when little is left.
            runs = [([sys.executable, str(driver), "--plan-file", str(plan_file),
                      str(domain), str(problem), "--search", search], None, None)]
        else:
            # The driver's steps without the driver: it costs two interpreter starts and
            # a version query per call, a fifth of a 3-object plan.
            bin_dir, search_exe = components
            env = dict(os.environ, PYTHONPATH=str(bin_dir))
            runs = [([sys.executable, "-S", "-m", "fast_downward.translate", str(domain),
                      str(problem), "--sas-file", "output.sas"], env, None),
                    _search_run(search_exe, search, plan_file, Path(tmp) / "output.sas")]
            then = None if fallback is None else _search_run(search_exe, fallback, plan_file,
                                                             Path(tmp) / "output.sas")
        return _fd_runs(runs, tmp, start, wall_seconds, cpu_seconds, then)


def fast_downward_sas(sas: str, wall_seconds: float = DEFAULT_TIMEOUT, search: str = FD_SEARCH,
                      cpu_seconds: float | None = None, fallback: str | None = FD_FALLBACK
                      ) -> PlanResult:
    """Fast Downward's search on a task already translated to SAS+ text
    (planning/grounding.py), under the same limits and `fallback` as `fast_downward`."""
    start = time.perf_counter()
    search_exe = search_binary()
    if search_exe is None:
        return PlanResult("error", [], time.perf_counter() - start, (
            "Fast Downward's search binary not found; install the up-fast-downward wheel"),
            "fd")
    with tempfile.TemporaryDirectory(prefix="symplan-fd-") as tmp:
        (Path(tmp) / "output.sas").write_text(sas)
        files = Path(tmp) / "sas_plan", Path(tmp) / "output.sas"
        then = None if fallback is None else _search_run(search_exe, fallback, *files)
        return _fd_runs([_search_run(search_exe, search, *files)], tmp, start, wall_seconds,
                        cpu_seconds, then)


def _search_run(search_exe: Path, search: str, plan_file: Path, sas_file: Path):
    """The search binary's command line, environment and input, as `_fd_runs` takes them."""
    return ([str(search_exe), "--search", search, "--internal-plan-file", str(plan_file)],
            None, sas_file)


def _fd_runs(runs, tmp: str, start: float, wall_seconds: float, cpu_seconds: float | None,
             fallback=None) -> PlanResult:
    """Runs FD's phases one after the other in `tmp` (a phase's failure stops them) and
    reads the outcome by FD's exit codes and its plan files. With a `fallback` search run,
    the last phase (the search) has OPTIMAL_SHARE of what is left, and the fallback the
    rest when it runs out."""
    def result(status, plan=(), message=""):
        return PlanResult(status, list(plan), time.perf_counter() - start, message, "fd")

    deadline = start + wall_seconds
    used = children_cpu()

    def left() -> float | None:
        return None if cpu_seconds is None else cpu_seconds - (children_cpu() - used)

    for phase, (cmd, env, stdin) in enumerate(runs):
        if fallback is not None and phase == len(runs) - 1:
            now, cpu = time.perf_counter(), left()
            code, out, err = run_group(cmd, tmp, env, stdin,
                                        now + OPTIMAL_SHARE * (deadline - now),
                                        None if cpu is None else OPTIMAL_SHARE * cpu)
            if _out_of_time(code):
                EXPANDED.add(fd_expanded(out))
                code, out, err = run_group(fallback[0], tmp, fallback[1], fallback[2],
                                            deadline, left())
        else:
            code, out, err = run_group(cmd, tmp, env, stdin, deadline, left())
        EXPANDED.add(fd_expanded(out))
        if code is None:
            return result("timeout", message=f"Fast Downward killed after {wall_seconds:g} s")
        if code != 0:
            if phase == 0 and len(runs) == 2 and code not in (20, 21, 31):
                code = 30  # the translator crashed, as the driver reports it
            break
    plan_files = sorted(Path(tmp).glob("sas_plan*"))
    plan = _read_plan(plan_files[-1].read_text()) if plan_files else []
    if code in _FD_SOLVED and plan_files:
        return result("solved", plan, _FD_SOLVED[code])
    if code in _FD_UNSOLVABLE:
        return result("unsolvable", message=_FD_UNSOLVABLE[code])
    if code in _FD_TIMEOUT or code in (-signal.SIGXCPU, 256 - signal.SIGXCPU):
        return result("timeout", message=_FD_TIMEOUT.get(code, "CPU time limit"))
    what = _FD_ERROR.get(code, f"exit code {code}")
    if code == 0:
        what = "exit code 0 but no plan file"
    return result("error", message=f"Fast Downward: {what}: {_fd_message(out, err)}")


def _out_of_time(code: int | None) -> bool:
    """Did a phase stop at its wall-clock deadline or its time limits?"""
    return code is None or code in _FD_TIMEOUT or code in (-signal.SIGXCPU,
                                                             256 - signal.SIGXCPU)


def search_binary() -> Path | None:
    """FD's search binary of the installed build, or None."""
    driver = find_fast_downward()
    components = None if driver is None else _fd_components(driver)
    return None if components is None else components[1]


def _fd_components(driver: Path) -> tuple[Path, Path] | None:
    """(the translator's package folder, the search binary) of the driver's release build,
    or None where the driver is all there is (run it then)."""
    bin_dir = driver.parent / "builds" / "release" / "bin"
    search = bin_dir / "downward"
    if (bin_dir / "fast_downward" / "translate").is_dir() and os.access(search, os.X_OK):
        return bin_dir, search
    return None


# ---------------------------------------------------------------- pyperplan


def _pyperplan_child(conn, domain: str, problem: str, search: str, heuristic: str | None,
                     cpu_seconds: float | None = None):
    """Runs in the child: parse, ground, search; sends (status, payload)."""
    limit_cpu(cpu_seconds)
    try:
        import logging

        logging.disable(logging.CRITICAL)
        from pyperplan import planner as pp

        if search not in pp.SEARCHES:
            raise ValueError(f"unknown pyperplan search {search!r}; one of {sorted(pp.SEARCHES)}")
        if heuristic is not None and heuristic not in pp.HEURISTICS:
            raise ValueError(
                f"unknown pyperplan heuristic {heuristic!r}; one of {sorted(pp.HEURISTICS)}")
        heuristic_class = None if heuristic is None else pp.HEURISTICS[heuristic]
        solution = pp.search_plan(domain, problem, pp.SEARCHES[search], heuristic_class)
        if solution is None:
            conn.send(("unsolvable", "pyperplan: search space exhausted, no plan"))
        else:
            conn.send(("solved", [op.name for op in solution]))
    except BaseException as e:  # noqa: BLE001 - everything goes back as a message
        conn.send(("error", f"pyperplan: {type(e).__name__}: {e}"))
    finally:
        conn.close()


def pyperplan_plan(domain, problem, wall_seconds: float = DEFAULT_TIMEOUT, search: str = "astar",
                   heuristic: str | None = "lmcut", cpu_seconds: float | None = None
                   ) -> PlanResult:
    """pyperplan on PDDL files in a child process that is killed at the deadline (or
    stops at its CPU budget, see the module docstring)."""
    start = time.perf_counter()
    domain, problem = _check_files(domain, problem)

    def result(status, plan=(), message=""):
        return PlanResult(status, list(plan), time.perf_counter() - start, message, "pyperplan")

    if importlib.util.find_spec("pyperplan") is None:
        return result("error", message="pyperplan is not installed (pip install pyperplan)")
    methods = multiprocessing.get_all_start_methods()
    ctx = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_pyperplan_child,
                       args=(send, str(domain), str(problem), search, heuristic,
                             cpu_seconds), daemon=True)
    try:
        proc.start()
    except OSError as e:
        return result("error", message=f"could not start pyperplan: {e}")
    send.close()
    ready = False
    try:
        ready = recv.poll(max(wall_seconds - (time.perf_counter() - start), 0.0))
        message = recv.recv() if ready else None
    except (EOFError, OSError):
        proc.join(5.0)
        if proc.exitcode in (-signal.SIGXCPU, -signal.SIGKILL) and cpu_seconds is not None:
            message = None  # its CPU budget ran out
        else:
            message = ("error", f"pyperplan child died (exit code {proc.exitcode})")
    finally:
        if proc.is_alive() and not ready:
            proc.kill()
        proc.join(5.0)
        recv.close()
    if message is None:
        return result("timeout", message=f"pyperplan stopped after {wall_seconds:g} s" + (
            "" if cpu_seconds is None else f" or {cpu_seconds:g} s of CPU"))
    status, payload = message
    if status == "solved":
        return result("solved", payload)
    return result(status, message=payload)


# ---------------------------------------------------------------- registry

PLANNERS: dict[str, Callable[..., PlanResult]] = {
    "fd": fast_downward,
    "pyperplan": pyperplan_plan,
}


def plan(domain, problem, planner: str = "fd", wall_seconds: float = DEFAULT_TIMEOUT,
         **options) -> PlanResult:
    """Plans with a registered back-end on PDDL files."""
    if planner not in PLANNERS:
        raise ValueError(f"unknown planner {planner!r}; one of {sorted(PLANNERS)}")
    if not wall_seconds > 0:
        raise ValueError(f"timeout must be positive, got {wall_seconds}")
    return PLANNERS[planner](domain, problem, wall_seconds=wall_seconds, **options)


def plan_pddl(domain_text: str, problem_text: str, planner: str = "fd",
              wall_seconds: float = DEFAULT_TIMEOUT, **options) -> PlanResult:
    """Plans on PDDL given as text (written to a temporary directory)."""
    with tempfile.TemporaryDirectory(prefix="symplan-pddl-") as tmp:
        d, p = Path(tmp) / "domain.pddl", Path(tmp) / "problem.pddl"
        d.write_text(domain_text)
        p.write_text(problem_text)
        return plan(d, p, planner, wall_seconds, **options)
