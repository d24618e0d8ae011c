"""`symplan` entry point: builds the parser from the command modules in COMMAND_MODULES,
runs the command and maps its outcome to the exit status.

Every command keeps one contract, enforced here: exit status 0 when it did its job, 1
when it ran but its answer is negative (no plan, unsolvable, timeout, infeasible action:
the command returns a `NegativeAnswer`), 2 for bad input (a flag, a missing or malformed
file, a place that cannot be written: a `CommandError`, ValueError or file error),
reported as ONE line on stderr, `symplan CMD: error: ...`, naming the file or flag, with
nothing written (empty folders it made are removed). Ctrl-C: one line saying what is
kept, exit status 130. A reader that
closes stdout early (`symplan data stats DIR | head -1`) ends the command quietly, with
the status of a command killed by SIGPIPE (141), as other Unix tools do.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import json
import math
import os
import re
import select
import sys
import textwrap
from pathlib import Path

# Each module defines `register(subparsers)`, which adds its sub-commands and sets
# `func` on them; a func takes the parsed args and returns a JSON-able dict (printed
# when --json is given) or None, or an int, its exit status, when it printed its result
# itself (the demo: its JSON comes before its Meshcat prompt). Modules are imported lazily so that `symplan plan`
# does not pay for importing Drake.
COMMAND_MODULES = [
    "drake_symplan.cli.world_cmds",
    "drake_symplan.cli.perception_cmds",
    "drake_symplan.cli.frames_cmds",
    "drake_symplan.cli.data_cmds",
    "drake_symplan.cli.learning_cmds",
    "drake_symplan.cli.planning_cmds",
    "drake_symplan.cli.agent_cmds",
    "drake_symplan.cli.goal_cmds",
    "drake_symplan.cli.inspect_cmds",
    "drake_symplan.cli.reproduce_cmds",
    "drake_symplan.cli.demo_cmds",
    "drake_symplan.cli.report_cmds",
]

EXIT_OK, EXIT_NEGATIVE, EXIT_BAD_INPUT = 0, 1, 2
EXIT_CLOSED_STDOUT = 128 + 13  # as if killed by SIGPIPE
EXIT_INTERRUPTED = 128 + 2  # Ctrl-C: as if killed by SIGINT

# What a command interrupted with Ctrl-C (or killed) leaves, where it resumes; the data are
# as after kill -9. A command not here writes its outputs whole at its end, if at all.
INTERRUPTED = {
    "collect": "the shards written are kept and the same command resumes",
    "train": "the run keeps its last finished epoch in last.pt, if one finished; the same "
             "command with --resume continues it",
    "problems make": "the problems written are kept and the same command resumes",
    "eval planning": "with --records, the solves recorded are kept and the same command "
                     "resumes after them",
    "reproduce": "the stages done are kept and the same command resumes",
    "curve": "the points done are kept and the same command resumes",
}

# The commands in pipeline order, for `symplan --help`.
PIPELINE = (
    ("scene sample", "write a random valid scene file (YAML)"),
    ("act", "execute one pick/place on a scene in full physics"),
    ("perceive", "perceive a scene with the depth cameras"),
    ("collect", "collect exploration transitions (random or active) into a data set"),
    ("data stats", "summarise a data set"),
    ("train", "train an effect model (RelationalDeepSym or a baseline) on a data set"),
    ("eval effects", "test-set effect error of trained runs"),
    ("symbols", "read unary and relational symbols of a data set out of a trained run"),
    ("explain", "what each learned symbol means, from perceived features and contacts"),
    ("operators", "learn lifted operators from the symbols and write a PDDL domain"),
    ("bundle", "a trained run and its learned operators in one model directory"),
    ("eval operators", "a model's domain on held-out episodes, at the symbolic level"),
    ("eval rollout", "the continuous model's position error after k actions, held out"),
    ("plan", "plan on a PDDL domain and problem (Fast Downward or pyperplan)"),
    ("inspect", "show a scene's symbols and a plan to a goal in Meshcat"),
    ("solve", "perceive start and goal, plan, execute with the arm, check within 5 cm"),
    ("problems make", "planning problems: random starts, goals k arm actions away"),
    ("eval planning", "models on a problem set in full physics"),
    ("reproduce", "all of the above at a scale, every results table into one directory"),
    ("curve", "random against active exploration by data size: the learning curve"),
    ("demo", "the shipped problem (or --seed N's): plan, the UR10 executes it, 5 cm check"),
)
DESCRIPTION = "\n\n".join([
    textwrap.fill("A UR10 in Drake explores pick/place actions on blocks it perceives with "
                  "depth cameras; models learn unary and relational symbols from the effects, "
                  "and lifted operators over those symbols make a PDDL domain to plan with.", 88),
    "The pipeline, in order:\n" + "\n".join(
        f"  {name:<{max(len(n) for n, _ in PIPELINE) + 2}}{summary}" for name, summary in PIPELINE),
    textwrap.fill("`symplan COMMAND --help` tells a command's options. Scene files (YAML) come "
                  "from `symplan scene sample` or a problem set of `symplan problems make` "
                  "(PROBLEM/start.yaml, PROBLEM/goal.yaml).", 88),
])
EXIT_STATUS = ("Exit status: 0 done, 1 a negative answer (no plan, unsolvable, timeout, "
               "infeasible action, a failed verdict), 2 bad input (one line on stderr).")


class CommandError(Exception):
    """A user-facing error: printed as one line, exit code 2, no traceback."""


class NegativeAnswer(dict):
    """A command's result whose answer is negative (no plan, unsolvable, timeout, an
    infeasible action): printed like any result, exit status 1."""


# Errors that mean the input was bad: reported in one line, exit status 2.
BAD_INPUT = (CommandError, ValueError, FileNotFoundError, FileExistsError,
             NotADirectoryError, IsADirectoryError, PermissionError)
# An OSError with one of these errnos is a place that cannot be written (or read): bad
# input too, told in one line naming the path (a read-only file system, a full disk).
FILE_ERRNOS = frozenset(getattr(errno, name) for name in (
    "EROFS", "ENOSPC", "EDQUOT", "EACCES", "EPERM", "EFBIG", "ENAMETOOLONG", "ELOOP",
    "ENOENT", "ENOTDIR", "EISDIR", "EEXIST", "EXDEV", "EMFILE", "ENFILE")
    if hasattr(errno, name))
# The options that name what a command writes, for an OSError that names no file.
OUTPUT_OPTIONS = ("out", "record", "records", "plot", "work")


class HelpFormatter(argparse.HelpFormatter):
    """Says each option's default where its help does not already."""

    def _get_help_string(self, action):
        text = action.help or ""
        if "default" in text or action.required or action.default in (
                None, False, [], argparse.SUPPRESS) or not action.option_strings:
            return text
        return f"{text} (default: %(default)s)"


class Parser(argparse.ArgumentParser):
    """Usage errors in one line (`symplan CMD: error: ...`), exit status 2; every
    command's help ends with the exit statuses and says its options' defaults."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        kwargs.setdefault("epilog", EXIT_STATUS)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def _get_value(self, action, arg_string):
        """A backstop under the options' types (cli/options.py: each says its range): no
        option takes a number that is not finite or an integer past 64 bits, whatever
        its type (`inf`, `nan`, `1e400`, a 400-digit integer): bad input naming it."""
        value = super()._get_value(action, arg_string)
        if isinstance(value, float) and not math.isfinite(value):
            raise argparse.ArgumentError(action, f"must be a finite number, got {shown(arg_string)}")
        if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 2**63:
            raise argparse.ArgumentError(action, "must be an integer within 64 bits (|n| < "
                                         f"2**63), got {shown(arg_string)}")
        return value


def bounded(cast, within, what: str):
    """An argparse type: `cast(text)` where `within(value)` holds, else bad input saying
    that it must be `what` (argparse names the option: `argument --x: must be ...`)."""
    def parse(text: str):
        try:
            value = cast(text)
        except (ValueError, OverflowError):  # not a number; past int()'s 4,300 digits
            value = None
        if value is None or not within(value):
            raise argparse.ArgumentTypeError(f"must be {what}, got {shown(text)}")
        return value

    return parse


def shown(text: str, width: int = 40) -> str:
    """`text` quoted for a message, cut after `width` characters (a 400-digit number)."""
    return repr(text) if len(text) <= width else repr(text[:width]) + "..."


# The integer and positive types here; every other range, and these re-exported, in
# cli/options.py (the options' one place for what a number may be).
positive_int = bounded(int, lambda v: v >= 1, "a positive integer")
nonnegative_int = bounded(int, lambda v: v >= 0, "a non-negative integer")
positive_float = bounded(float, lambda v: 0 < v < math.inf, "a positive number")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="symplan", description=DESCRIPTION,
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    subparsers = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def command_name(args: argparse.Namespace) -> str:
    """'data stats' for `symplan data stats ...`."""
    subcommands = [v for k, v in vars(args).items() if k.endswith("_command") and v]
    return " ".join([args.command, *subcommands])


def one_line(error: BaseException) -> str:
    return re.sub(r"\s*\n\s*", " ", str(error)).strip()


def file_problem(error: OSError, args: argparse.Namespace) -> str:
    """'/mnt/ro/scene.yaml: Read-only file system' for an OSError while a command read or
    wrote a file; one that names no file (a full disk under a library's writer) is told
    with the command's output options."""
    what = error.strerror or one_line(error)
    if error.filename is not None:
        both = f"{error.filename} -> {error.filename2}" if error.filename2 else error.filename
        return f"{both}: {what}"
    given = [f"--{k} {getattr(args, k)}" for k in OUTPUT_OPTIONS
             if getattr(args, k, None) not in (None, "", False)]
    return f"{what} (writing {', '.join(given)})" if given else what


def run(parser: argparse.ArgumentParser, argv: list[str], name: str | None = None) -> int:
    """Parses `argv` with `parser`, runs its command and returns the exit status; bad
    input is one line on stderr, `NAME: error: ...` (NAME: `symplan CMD` by default). A
    reader that has closed stdout ends it quietly (EXIT_CLOSED_STDOUT)."""
    try:
        code = run_command(parser, argv, name)
        sys.stdout.flush()  # here, where a reader that has gone is caught
    except BrokenPipeError:
        if not stdout_closed():
            raise  # some other pipe: a bug to see
        # Whatever is left to print or flush goes nowhere, also at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_CLOSED_STDOUT
    return code


def new_folders(args: argparse.Namespace) -> list[Path]:
    """The paths of the command's output options that do not exist yet, with their
    ancestors that do not: what a command refused half-way may have made empty."""
    found = []
    for key in OUTPUT_OPTIONS:
        value = getattr(args, key, None)
        if isinstance(value, (str, os.PathLike)) and str(value):
            path = Path(value).absolute()
            while not path.exists() and path != path.parent:
                found.append(path)
                path = path.parent
    return found


def remove_empty(folders: list[Path]) -> None:
    """Removes the empty folders in and of `folders` (made by the command: they did not
    exist before it), deepest first: bad input leaves no empty folder behind, and whatever
    was written in them stays, with the folders that hold it."""
    for folder in sorted(set(folders), key=lambda p: len(p.parts), reverse=True):
        if not folder.is_dir() or folder.is_symlink():
            continue
        for root, _, _ in os.walk(folder, topdown=False):
            try:
                os.rmdir(root)
            except OSError:  # not empty
                pass


def stdout_closed() -> bool:
    """Whether stdout is a pipe whose reader has closed it."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(event & select.POLLERR for _, event in poller.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll here, or no stdout file
        return True


def run_command(parser: argparse.ArgumentParser, argv: list[str], name: str | None) -> int:
    """`run` without the closed-stdout guard."""
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help (0) or a usage error (2), already printed
        return e.code if isinstance(e.code, int) else EXIT_BAD_INPUT
    made = new_folders(args)
    try:
        result = args.func(args)
    except BAD_INPUT as e:
        remove_empty(made)
        print(f"{name or 'symplan ' + command_name(args)}: error: {one_line(e)}",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:
        remove_empty(made)
        if e.errno not in FILE_ERRNOS:
            raise
        print(f"{name or 'symplan ' + command_name(args)}: error: {file_problem(e, args)}",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        command = command_name(args)
        kept = INTERRUPTED.get(command)
        print(f"{name or 'symplan ' + command}: interrupted" + (f"; {kept}" if kept else ""),
              file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception:  # a bug, shown as such; an empty folder it made is not left
        remove_empty(made)
        raise
    if isinstance(result, int):  # the command printed its result itself
        return result
    if result is not None and getattr(args, "json", False):
        print(json.dumps(result, indent=2))
    return EXIT_NEGATIVE if isinstance(result, NegativeAnswer) else EXIT_OK


def main(argv: list[str] | None = None) -> int:
    try:
        return run(build_parser(), list(sys.argv[1:] if argv is None else argv))
    except KeyboardInterrupt:  # before a command started (its own is told in run_command)
        print("symplan: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    # `python -m drake_symplan.cli.main`: run the imported module's main, whose
    # CommandError and NegativeAnswer are the classes the command modules use.
    from drake_symplan.cli.main import main as imported_main

    sys.exit(imported_main())
