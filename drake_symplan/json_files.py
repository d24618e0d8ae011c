"""Reading JSON that a user gave (standard library only): every failure is a `JSONFileError`,
a ValueError (bad input, exit status 2 at the CLI) whose message names the file.

    read_json(path)                       the object in a .json file (a dict unless `expect`)
    parse_json(text, source)              the same for text read elsewhere (a line, an array)
"""

from __future__ import annotations

import json
from pathlib import Path

KINDS = {dict: "an object", list: "an array", object: "any value"}


class JSONFileError(ValueError):
    """A JSON file (or line) that cannot be used; the message names it."""


def parse_json(text: str, source: str, expect: type = dict):
    """The value of JSON `text`, read from `source` (a file's name, 'FILE, line N'),
    which must be an `expect` (dict, list, or object for any)."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as e:
        raise JSONFileError(f"{source}: invalid JSON (line {e.lineno}, column {e.colno}: "
                            f"{e.msg})") from e
    if not isinstance(value, expect):
        raise JSONFileError(f"{source}: expected {KINDS.get(expect, expect.__name__)}, got "
                            f"{type_name(value)}")
    return value


def read_json(path: str | Path, expect: type = dict):
    """The value of the JSON file `path` (parse_json); a file that is not UTF-8 text is a
    JSONFileError too, a missing one FileNotFoundError naming it."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist")
    try:
        text = path.read_text()
    except UnicodeDecodeError as e:
        raise JSONFileError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from e
    return parse_json(text, str(path), expect)


def type_name(value) -> str:
    """'an array' for [1, 2], 'a number' for 3: a JSON value's kind, as a message says it."""
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, bool):
        return "a boolean"
    if value is None:
        return "null"
    return "a number"
