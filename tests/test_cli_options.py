"""cli/options.py: every numeric option's type says its range; a value out of it is one
line naming the option and the rule, exit status 2, before anything is written."""

from __future__ import annotations

import argparse

import pytest
from conftest import assert_bad_input, run

from drake_symplan.cli import main as cli_main
from drake_symplan.cli import options

BIG = "9" * 400  # a 400-digit integer: Python takes it, numpy, torch and Drake do not

SCENE = ["scene", "sample", "--objects", "2"]
COLLECT = ["collect", "--transitions", "10"]
TRAIN = ["train", "--model", "reference", "--data", "DATA"]


@pytest.mark.parametrize("argv, flag, value, rule", [
    (COLLECT, "--seed", "-1", "an integer seed in [0, 2**32)"),
    (COLLECT, "--seed", "1e23", "an integer seed in [0, 2**32)"),
    (COLLECT, "--seed", "4294967296", "an integer seed in [0, 2**32)"),
    (COLLECT, "--noise-dropout", "2", "a fraction in [0, 1)"),
    (COLLECT, "--noise-dropout", "1", "a fraction in [0, 1)"),
    (COLLECT, "--noise-sigma", "-0.1", "a finite number >= 0"),
    (COLLECT, "--noise-sigma", "nan", "a finite number >= 0"),
    (COLLECT, "--long-fraction", "1.5", "a probability in [0, 1]"),
    (COLLECT, "--chunk-size", "0", "a positive integer"),
    (COLLECT, "--episode-length", "-2", "a positive integer"),
    (SCENE, "--yaw-jitter-deg", "inf", "a number of degrees in [0, 180]"),
    (SCENE, "--long-fraction", "-0.5", "a probability in [0, 1]"),
    (["perceive", "--scene", "S"], "--dropout", "1.5", "a fraction in [0, 1)"),
    (["perceive", "--scene", "S"], "--settle", "inf", "a finite number >= 0"),
    (TRAIN, "--lr", "inf", "a positive number"),
    (TRAIN, "--temperature", "nan", "a positive number"),
    (TRAIN, "--epochs", "0", "a positive integer"),
    (["bundle", "--out", "B"], "--margin", "-1", "a finite number >= 0"),
    (["bundle", "--out", "B"], "--support", "nan", "a probability in [0, 1]"),
    (["plan", "--domain", "D", "--problem", "P"], "--timeout", "inf", "a positive number"),
    (["solve", "--start", "S", "--goal", "G"], "--timeout", "0", "a positive number"),
    (["solve", "--start", "S", "--goal", "G"], "--max-replans", "-1",
     "a non-negative integer"),
    (["problems", "make", "--objects", "2", "--k", "1", "--count", "1"], "--seed", "-1",
     "a non-negative integer"),
])
def test_a_number_out_of_its_range_is_one_line_naming_the_option_and_the_rule(
        argv, flag, value, rule, tmp_path, capsys):
    out = tmp_path / "out"
    code, stdout, err = run([*argv, "--out", out, flag, value], capsys)
    assert_bad_input(code, stdout, err)
    command = " ".join(w for w in argv if w[:1].islower() and w not in ("reference",))
    assert err == (f"symplan {command}: error: argument {flag}: must be {rule}, got "
                   f"'{value}' (see symplan {command} --help)\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, flag, value, rule", [
    # Options whose own type is plain: the parser's backstop still refuses them.
    (["explain", "--data", "D"], "--margin", "nan", "must be a finite number, got 'nan'"),
    (["demo"], "--budget-minutes", "inf", "must be a finite number, got 'inf'"),
    (SCENE, "--seed", BIG, f"must be an integer seed in [0, 2**32), got '{BIG[:40]}'..."),
    (["solve", "--start", "S", "--goal", "G"], "--alternatives", BIG,
     f"must be an integer within 64 bits (|n| < 2**63), got '{BIG[:40]}'..."),
])
def test_numbers_no_option_takes_are_refused_whatever_its_type(argv, flag, value, rule,
                                                              capsys):
    code, out, err = run([*argv, flag, value], capsys)
    assert_bad_input(code, out, err, f"error: argument {flag}: {rule} (see symplan ")


def test_the_types_hold_their_bounds():
    assert options.seed("0") == 0 and options.seed(str(2**32 - 1)) == 2**32 - 1
    assert options.probability("0") == 0 and options.probability("1") == 1
    assert options.fraction_lost("0.99") == 0.99 and options.degrees("180") == 180
    assert options.nonnegative_float("0") == 0 and options.positive_float("1e-9") == 1e-9
    for parse, text in [(options.seed, str(2**32)), (options.seed, "1.0"),
                        (options.probability, "1.0001"), (options.fraction_lost, "1"),
                        (options.degrees, "-1"), (options.nonnegative_float, "-inf"),
                        (options.positive_float, "nan"), (options.positive_int, "1e3"),
                        (options.nonnegative_int, "9" * 5000)]:
        with pytest.raises(argparse.ArgumentTypeError, match="^must be "):
            parse(text)


def numeric_options(parser, words=()):
    """(command words, option, type) of every option of `parser` that takes a number."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from numeric_options(sub, (*words, name))
        elif action.type is not None and action.option_strings and (
                action.type in (int, float) or getattr(action.type, "__module__", "") in (
                    "drake_symplan.cli.main", "drake_symplan.cli.options")):
            yield " ".join(words), action.option_strings[0], action.type


# Plain int and float options left in modules being moved (demo_cmds, inspect_cmds): each
# is checked in its command, and main.Parser refuses non-finite and 64-bit-overflowing
# values of every option.
PLAIN = {("demo", "--objects"), ("demo", "--k"), ("demo", "--budget-minutes"),
         ("explain", "--margin")}


def test_every_numeric_option_has_a_type_that_says_its_range():
    found = list(numeric_options(cli_main.build_parser()))
    assert len(found) > 40
    plain = {(words, flag) for words, flag, kind in found if kind in (int, float)}
    assert plain == PLAIN


@pytest.fixture
def read_only(monkeypatch, tmp_path):
    """A folder in which no file can be made (EROFS), as on a read-only file system."""
    import errno
    import os
    import tempfile

    folder = tmp_path / "ro"
    folder.mkdir()
    make = tempfile.mkstemp

    def mkstemp(*args, dir=None, **kwargs):
        if dir is not None and os.path.realpath(dir) == os.path.realpath(folder):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(folder))
        return make(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    return folder


@pytest.mark.parametrize("argv, out", [
    (["scene", "sample", "--objects", "2"], "scene.yaml"),
    (["collect", "--transitions", "10"], "data"),
    (["collect", "--transitions", "10"], "data/deeper"),
    (["problems", "make", "--objects", "2", "--k", "1", "--count", "1"], "set"),
    (["operators", "--symbols", "symbols.npz"], "ops"),
])
def test_an_output_on_a_read_only_file_system_is_refused_before_any_work(argv, out, read_only,
                                                                        capsys):
    code, stdout, err = run([*argv, "--out", read_only / out], capsys)
    assert_bad_input(code, stdout, err)
    assert err.endswith(f": error: --out {read_only / out} cannot be written: {read_only}: "
                        "Read-only file system\n")
    assert list(read_only.iterdir()) == []


def test_the_writability_probe_leaves_nothing(tmp_path):
    options.check_output_dir(tmp_path / "a" / "b")
    options.check_output_file(tmp_path / "x.yaml", "--out")
    assert list(tmp_path.iterdir()) == []
