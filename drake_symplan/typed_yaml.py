"""Typed YAML configuration files for dataclasses (PyYAML only: no Drake, no torch).

`read_fields(path, cls)` reads a YAML mapping and checks it against the fields of
dataclass `cls`: unknown keys are refused by name, every value must have its field's
type (an int where a float is declared is taken as that float, and so is a number in
exponent notation such as 1e-3, which YAML 1.1 reads as a string; a list where a tuple
is declared is taken as that tuple); the result goes into `cls(**fields)`, possibly with
other values on top. Errors are ValueErrors of one line that start with the file's name.
`shipped_config(name)` finds a file of the repo's configs/, in a checkout or installed.
"""

from __future__ import annotations

import dataclasses
import math
import re
import types
import typing
from pathlib import Path

import yaml

_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def parse_yaml(text: str) -> object:
    """`yaml.safe_load(text)`, with what Python refuses while reading it as a YAMLError:
    nesting past the recursion limit, an integer past int()'s 4,300 digits."""
    try:
        return yaml.safe_load(text)
    except RecursionError:
        raise yaml.YAMLError("invalid YAML (nested too deeply)") from None
    except ValueError as e:  # yaml's int(): "Exceeds the limit (4300 digits) ..."
        raise yaml.YAMLError(f"invalid YAML ({str(e).split(';')[0]})") from None


def yaml_problem(error: yaml.YAMLError) -> str:
    """'invalid YAML (line L, column C)' for a parser error, positions counted from 1;
    parse_yaml's own errors (no position) as they say."""
    mark = getattr(error, "problem_mark", None) or getattr(error, "context_mark", None)
    if mark is None:
        text = str(error)
        return text if text.startswith("invalid YAML (") else "invalid YAML"
    return f"invalid YAML (line {mark.line + 1}, column {mark.column + 1})"


def read_text(path: Path) -> str:
    """The UTF-8 text of file `path`; ValueError naming it when it is not UTF-8."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: not UTF-8 text (byte {e.start})") from None


def read_yaml(path: str | Path) -> object:
    """The parsed contents of YAML file `path` (None when it is empty)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        return parse_yaml(read_text(path))
    except yaml.YAMLError as e:
        raise ValueError(f"{path}: {yaml_problem(e)}") from e


def number(value) -> float | None:
    """`value` as a finite float when it is a number (a YAML int or float, or text that
    reads as one: YAML 1.1 takes 1e-3 for text), else None: a bool, other text, a list,
    nan, inf, an integer too large for a float."""
    if isinstance(value, str) and _NUMBER.fullmatch(value.strip()):
        value = float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        value = float(value)
    except OverflowError:
        return None
    return value if math.isfinite(value) else None


class _Mismatch(Exception):
    pass


def _type_name(hint) -> str:
    return getattr(hint, "__name__", None) or str(hint)


def _convert(value, hint):
    """`value` as type `hint`, or _Mismatch."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        for arg in args:
            try:
                return _convert(value, arg)
            except _Mismatch:
                continue
        raise _Mismatch
    if hint is typing.Any:
        return value
    if hint is type(None):
        if value is None:
            return None
        raise _Mismatch
    if hint is float:
        if (converted := number(value)) is None:
            raise _Mismatch
        return converted
    if hint in (bool, int, str):
        if isinstance(value, hint) and not (hint is int and isinstance(value, bool)):
            return value
        raise _Mismatch
    if hint is dict or origin is dict:
        if not isinstance(value, dict):
            raise _Mismatch
        if not args:
            return dict(value)
        return {_convert(k, args[0]): _convert(v, args[1]) for k, v in value.items()}
    if hint is list or origin is list:
        if not isinstance(value, list):
            raise _Mismatch
        return [_convert(v, args[0]) for v in value] if args else list(value)
    if hint is tuple or origin is tuple:  # a YAML list; tuple[X, ...] or of fixed length
        if not isinstance(value, list):
            raise _Mismatch
        if not args:
            return tuple(value)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0]) for v in value)
        if len(args) != len(value):
            raise _Mismatch
        return tuple(_convert(v, a) for v, a in zip(value, args, strict=True))
    raise TypeError(f"typed_yaml cannot check fields of type {hint}")


def check_fields(cls: type, data: object, source: str) -> dict:
    """`data` (a parsed YAML mapping) checked against the fields of dataclass `cls`."""
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"{source}: expected a mapping of {cls.__name__} settings, "
                         f"got {type(data).__name__}")
    fields = [f.name for f in dataclasses.fields(cls) if f.init]
    unknown = sorted(str(k) for k in data if k not in fields)
    if unknown:
        raise ValueError(f"{source}: unknown keys {unknown}; {cls.__name__} has {fields}")
    hints = typing.get_type_hints(cls)
    out = {}
    for key, value in data.items():
        try:
            out[key] = _convert(value, hints[key])
        except _Mismatch:
            shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:40] + "..."
            what = "a finite float" if hints[key] is float else _type_name(hints[key])
            raise ValueError(f"{source}: {key}: expected {what}, got "
                             f"{type(value).__name__} {shown}") from None
    return out


def read_config(path: str | Path | None, name: str, what: str) -> tuple[Path, dict]:
    """(the file, its non-empty top-level mapping): `path`, or configs/`name` when None; a
    ValueError naming the file and `what` the mapping should hold otherwise."""
    path = Path(path) if path is not None else shipped_config(name)
    data = read_yaml(path)
    if not isinstance(data, dict) or not data:
        raise ValueError(f"{path}: expected a mapping of {what}")
    return path, data


def shipped_config(name: str) -> Path:
    """The configuration file `name` of configs/: the checkout's, beside the package, or,
    installed from a wheel, the package data drake_symplan_configs (pyproject.toml)."""
    checkout = Path(__file__).resolve().parents[1] / "configs" / name
    if checkout.is_file():
        return checkout
    from importlib import resources

    try:
        return Path(str(resources.files("drake_symplan_configs"))) / name
    except ModuleNotFoundError:
        return checkout  # neither: read_yaml names the missing file


def read_fields(path: str | Path, cls: type) -> dict:
    """The settings in YAML file `path`, checked against dataclass `cls` (see module doc)."""
    return check_fields(cls, read_yaml(path), str(path))

