"""`symplan` entry point: dispatches to the command modules in COMMAND_MODULES.

Every command keeps one contract, enforced here: exit status 0 when it did its job, 1
when it ran but its answer is negative (no plan, unsolvable, timeout, infeasible action:
the command returns a `NegativeAnswer`), 2 for bad input (a flag, a missing or malformed
file: a `CommandError`, ValueError or file error), reported as ONE line on stderr,
`symplan CMD: error: ...`, naming the file or flag, with nothing written.
"""

from __future__ import annotations

import argparse
import importlib
import json
import re
import sys

# Each module defines `register(subparsers)`, which adds its sub-commands and sets
# `func` on them; a func takes the parsed args and returns a JSON-able dict (printed
# when --json is given) or None. Modules are imported lazily so that `symplan plan`
# does not pay for importing Drake.
COMMAND_MODULES = [
    "drake_symplan.cli.world_cmds",
    "drake_symplan.cli.perception_cmds",
    "drake_symplan.cli.data_cmds",
    "drake_symplan.cli.learning_cmds",
    "drake_symplan.cli.planning_cmds",
]

EXIT_OK, EXIT_NEGATIVE, EXIT_BAD_INPUT = 0, 1, 2


class CommandError(Exception):
    """A user-facing error: printed as one line, exit code 2, no traceback."""


class NegativeAnswer(dict):
    """A command's result whose answer is negative (no plan, unsolvable, timeout, an
    infeasible action): printed like any result, exit status 1."""


# Errors that mean the input was bad: reported in one line, exit status 2.
BAD_INPUT = (CommandError, ValueError, FileNotFoundError, NotADirectoryError,
             IsADirectoryError, PermissionError)


class Parser(argparse.ArgumentParser):
    """Usage errors in one line (`symplan CMD: error: ...`), exit status 2."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def positive_int(text: str) -> int:
    """argparse type: an integer of at least 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="symplan", description=__doc__)
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


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as e:  # --help (0) or a usage error (2), already printed
        return e.code if isinstance(e.code, int) else EXIT_BAD_INPUT
    try:
        result = args.func(args)
    except BAD_INPUT as e:
        print(f"symplan {command_name(args)}: error: {one_line(e)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if result is not None and getattr(args, "json", False):
        print(json.dumps(result, indent=2))
    return EXIT_NEGATIVE if isinstance(result, NegativeAnswer) else EXIT_OK


if __name__ == "__main__":
    # `python -m drake_symplan.cli.main`: run the imported module's main, whose
    # CommandError and NegativeAnswer are the classes the command modules use.
    from drake_symplan.cli.main import main as imported_main

    sys.exit(imported_main())
