"""Resumable runs of `symplan` commands: a Stage is one command with the file that says it
finished; a StageRunner runs the ones not done yet, logs them and stops at the first
failure (`symplan reproduce`, `symplan curve`, the demo's --from-scratch)."""

from __future__ import annotations

import dataclasses as dc
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from drake_symplan.atomic import write_atomic


class StageFailed(RuntimeError):
    """A stage's command exited non-zero; the message names it and ends with its stderr."""


@dc.dataclass
class Stage:
    """One command; `done` exists once it has finished (None: it runs whenever asked).
    With `stdout`, what it prints is written there (atomically, on success). `resume`:
    arguments added when `partial` exists (a stage interrupted before). `timeout`: after
    so many seconds it is stopped (SIGTERM), which is no failure (a budget)."""

    name: str
    argv: list
    done: Path | None
    stdout: Path | None = None
    partial: Path | None = None
    resume: tuple = ()
    timeout: float | None = None


class StageRunner:
    """Runs stages in `out` (their logs in out/logs), `jobs` at a time where asked; `log`
    records each stage's command and seconds, or that it was skipped. `announce`: the line
    said as a stage starts, from its name and command."""

    def __init__(self, out: Path, jobs: int = 2, say=print,
                 announce: str = "  {name}: {command}"):
        self.out, self.jobs, self.say, self.announce = Path(out), jobs, say, announce
        self.log: list[dict] = []

    def run(self, *stages: Stage) -> None:
        """Runs `stages` one after another."""
        for stage in stages:
            self._run(stage)

    def _parallel(self, stages: list) -> None:
        """Runs `stages` (each a Stage or a tuple run in order) `jobs` at a time."""
        def go(item):
            for stage in item if isinstance(item, tuple) else (item,):
                self._run(stage)

        with ThreadPoolExecutor(max_workers=self.jobs) as pool:
            for future in [pool.submit(go, item) for item in stages]:
                future.result()

    def _run(self, stage: Stage) -> None:
        argv = [str(a) for a in stage.argv]
        done = stage.done is not None and stage.done.exists()
        if stage.partial is not None and stage.partial.exists() and not done:
            argv += list(stage.resume)
        entry = {"stage": stage.name, "command": "symplan " + " ".join(argv)}
        if done:
            self.log.append({**entry, "skipped": True})
            return
        self.say(self.announce.format(name=stage.name, command=entry["command"]))
        logs = self.out / "logs"
        logs.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        err_path = logs / (stage.name.replace(" ", "_").replace("/", "_") + ".err")
        with open(err_path, "w") as err:
            proc = subprocess.Popen([sys.executable, "-m", "drake_symplan.cli.main", *argv],
                                    stdout=subprocess.PIPE, stderr=err, text=True)
            try:
                stdout, _ = proc.communicate(timeout=stage.timeout)
            except subprocess.TimeoutExpired:
                proc.terminate()
                proc.communicate()
                self.say("    stopped at the budget")
                self.log.append({**entry, "stopped": True,
                                 "seconds": round(time.perf_counter() - t0, 1)})
                return
        if proc.returncode != 0:
            tail = err_path.read_text().strip().splitlines()[-1:] or ["(no message)"]
            raise StageFailed(f"{stage.name} failed (exit {proc.returncode}; log "
                              f"{err_path}): {tail[0]}")
        if stage.stdout is not None:
            write_atomic(stage.stdout, stdout)
        self.log.append({**entry, "seconds": round(time.perf_counter() - t0, 1)})
