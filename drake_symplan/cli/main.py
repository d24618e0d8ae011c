"""`symplan` entry point: dispatches to the command modules in COMMAND_MODULES."""

from __future__ import annotations

import argparse
import importlib
import json
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


class CommandError(Exception):
    """A user-facing error: printed as one line, exit code 2, no traceback."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="symplan", description=__doc__)
    subparsers = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        result = args.func(args)
    except (CommandError, FileNotFoundError, ValueError) as e:
        print(f"symplan {args.command}: error: {e}", file=sys.stderr)
        return 2
    if result is not None and getattr(args, "json", False):
        print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
