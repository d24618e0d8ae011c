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
