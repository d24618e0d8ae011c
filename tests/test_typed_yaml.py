"""typed_yaml.py: what YAML and Python accept and a setting does not, in one line naming
the file and the key."""

from __future__ import annotations

import dataclasses

import pytest
from conftest import assert_bad_input, run

from drake_symplan.typed_yaml import read_fields, read_yaml


@dataclasses.dataclass
class Example:
    rate: float = 1.0
    count: int = 1


@pytest.mark.parametrize("text, message", [
    ("rate: .nan\n", "c.yaml: rate: expected a finite float, got float nan"),
    ("rate: -.inf\n", "c.yaml: rate: expected a finite float, got float -inf"),
    ("rate: 1e400\n", "c.yaml: rate: expected a finite float, got str '1e400'"),
    (f"rate: {'9' * 400}\n", f"c.yaml: rate: expected a finite float, got int {'9' * 40}..."),
    ("rate: true\n", "c.yaml: rate: expected a finite float, got bool True"),
])
def test_numbers_that_are_not_finite_are_refused_by_name(text, message, tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(text)
    with pytest.raises(ValueError) as caught:
        read_fields(path, Example)
    assert str(caught.value) == f"{tmp_path}/{message}"


@pytest.mark.parametrize("content, problem", [
    (b"rate: \xff\n", "not UTF-8 text (byte 6)"),
    (b"rate: " + b"[" * 5000 + b"]" * 5000 + b"\n", "invalid YAML (nested too deeply)"),
])
def test_a_file_python_cannot_read_is_named(content, problem, tmp_path):
    path = tmp_path / "c.yaml"
    path.write_bytes(content)
    with pytest.raises(ValueError) as caught:
        read_yaml(path)
    assert str(caught.value) == f"{path}: {problem}"


def test_a_train_config_with_a_nan_rate_writes_no_run(tmp_path, capsys):
    config = tmp_path / "train.yaml"
    config.write_text("lr: .nan\n")
    code, out, err = run(["train", "--config", config, "--model", "reference", "--data",
                          tmp_path, "--out", tmp_path / "run"], capsys)
    assert_bad_input(code, out, err)
    assert err == (f"symplan train: error: {config}: lr: expected a finite float, got float "
                   "nan\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["train.yaml"]


@dataclasses.dataclass
class WithTuples:
    sizes: tuple[int, ...] = ()
    pair: tuple[int, int] | None = None


def test_a_list_is_read_as_a_tuple_of_its_declared_items(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("sizes: [1, 2, 3]\npair: [4, 5]\n")
    assert read_fields(path, WithTuples) == {"sizes": (1, 2, 3), "pair": (4, 5)}
    path.write_text("pair: [4, 5, 6]\n")
    with pytest.raises(ValueError, match=r"c.yaml: pair: expected .*, got list \[4, 5, 6\]"):
        read_fields(path, WithTuples)
