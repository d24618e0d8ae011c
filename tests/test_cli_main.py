"""cli/main.py: how a command's end maps to the exit status and the one stderr line."""

from __future__ import annotations

import errno
import os
import sys
import types

import pytest
from conftest import assert_bad_input, run

from drake_symplan.cli import main as cli_main


@pytest.fixture
def probe(monkeypatch):
    """`symplan probe [--out OUT]`, whose command raises what the test sets in `raised`."""
    raised = []
    fake = types.ModuleType("fake_cmds")

    def command(args):
        raise raised[0]

    def register(subparsers):
        p = subparsers.add_parser("probe")
        p.add_argument("--out", default=None)
        p.set_defaults(func=command)

    fake.register = register
    monkeypatch.setitem(sys.modules, "fake_cmds", fake)
    monkeypatch.setattr(cli_main, "COMMAND_MODULES", ["fake_cmds"])
    return raised


def os_error(code: int, filename=None) -> OSError:
    return OSError(code, os.strerror(code), *([filename] if filename else []))


def test_a_file_that_cannot_be_written_is_one_line_naming_it(probe, capsys):
    probe.append(os_error(errno.EROFS, "/mnt/ro/scene.yaml"))
    code, out, err = run(["probe"], capsys)
    assert_bad_input(code, out, err)
    assert err == "symplan probe: error: /mnt/ro/scene.yaml: Read-only file system\n"


def test_a_full_disk_under_a_writer_that_names_no_file_names_the_output(probe, capsys):
    probe.append(os_error(errno.ENOSPC))
    code, out, err = run(["probe", "--out", "/data/set"], capsys)
    assert_bad_input(code, out, err)
    assert err == "symplan probe: error: No space left on device (writing --out /data/set)\n"


def test_an_os_error_that_is_no_file_problem_is_not_hidden(probe, capsys):
    probe.append(os_error(errno.ECONNREFUSED))
    with pytest.raises(ConnectionRefusedError):
        run(["probe"], capsys)


def test_a_scene_write_that_fails_is_one_line(monkeypatch, tmp_path, capsys):
    from drake_symplan.world import scenes

    path = tmp_path / "scene.yaml"

    def read_only(scene, where):
        raise os_error(errno.EROFS, str(where))

    monkeypatch.setattr(scenes, "save_scene", read_only)
    code, out, err = run(["scene", "sample", "--objects", "2", "--out", path], capsys)
    assert_bad_input(code, out, err)
    assert err == f"symplan scene sample: error: {path}: Read-only file system\n"
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_is_one_line_and_exit_130(probe, capsys):
    probe.append(KeyboardInterrupt())
    assert run(["probe"], capsys) == (130, "", "symplan probe: interrupted\n")


def test_ctrl_c_in_a_command_that_resumes_says_what_is_kept(monkeypatch, tmp_path, capsys):
    from drake_symplan.data import collect

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(collect, "collect", interrupted)
    code, out, err = run(["collect", "--transitions", "10", "--out", tmp_path / "d"], capsys)
    assert (code, out) == (130, "")
    assert err == ("symplan collect: interrupted; the shards written are kept and the same "
                   "command resumes\n")


def test_ctrl_c_during_a_parallel_collection_leaves_no_traceback(tmp_path):
    """The real thing: SIGINT to `symplan collect` with two worker processes once its
    first shard is written; the workers leave Ctrl-C to the parent, which ends the pool."""
    import signal
    import subprocess
    import time
    from pathlib import Path

    out = tmp_path / "data"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    proc = subprocess.Popen(
        [sys.executable, "-m", "drake_symplan.cli.main", "collect", "--transitions", "400",
         "--chunk-size", "5", "--workers", "2", "--out", str(out), "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        # Ctrl-C as a terminal gives it, whatever this test process inherited (a process
        # that ignores SIGINT passes that on, and a shell's background jobs ignore it)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 240
    while not list(out.glob("shard-*.npz")) and time.monotonic() < deadline:
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    stdout, err = proc.communicate(timeout=120)
    assert (proc.returncode, stdout) == (130, "")
    assert err == ("symplan collect: interrupted; the shards written are kept and the same "
                   "command resumes\n")
    assert {p.name for p in out.iterdir()} - {"manifest.json"} <= {
        f"shard-{c:06d}.npz" for c in range(80)}


def test_bad_input_found_half_way_leaves_no_empty_folder(monkeypatch, tmp_path, capsys):
    from pathlib import Path

    fake = types.ModuleType("fake_cmds")

    def command(args):
        (Path(args.out) / "p000").mkdir(parents=True)  # as problems make does first
        if args.keep:
            (Path(args.out) / "kept.json").write_text("{}")
        raise cli_main.CommandError("no such task")

    def register(subparsers):
        p = subparsers.add_parser("probe")
        p.add_argument("--out")
        p.add_argument("--keep", action="store_true")
        p.set_defaults(func=command)

    fake.register = register
    monkeypatch.setitem(sys.modules, "fake_cmds", fake)
    monkeypatch.setattr(cli_main, "COMMAND_MODULES", ["fake_cmds"])
    out = tmp_path / "a" / "set"
    assert run(["probe", "--out", out], capsys) == (2, "", "symplan probe: error: no such task\n")
    assert list(tmp_path.iterdir()) == []
    run(["probe", "--out", out, "--keep"], capsys)  # what was written stays, with its folders
    assert sorted(p.name for p in out.iterdir()) == ["kept.json"]
