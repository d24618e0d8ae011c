"""Training settings: Table I's defaults, configs/table1.yaml, the typed YAML loader and
`symplan train --config` (flags given override the file, the file overrides defaults)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from conftest import parse_learning_args

from drake_symplan.cli import learning_cmds
from drake_symplan.cli.main import CommandError
from drake_symplan.learning.trainer import TrainConfig
from drake_symplan.typed_yaml import read_fields

TABLE1 = Path(__file__).resolve().parents[1] / "configs" / "table1.yaml"


@dataclasses.dataclass
class Example:
    name: str
    rate: float = 0.5
    count: int = 1
    limit: int | None = None
    flag: bool = False
    options: dict = dataclasses.field(default_factory=dict)


def test_defaults_are_table1_settings():
    cfg = TrainConfig("relational", "d", "o")
    assert (cfg.epochs, cfg.batch_size, cfg.lr, cfg.patience) == (300, 128, 1e-3, 30)
    assert (cfg.grad_clip, cfg.temperature, cfg.hard, cfg.seed) == (10.0, 3.0, True, 0)


def test_table1_file_holds_the_defaults():
    fields = read_fields(TABLE1, TrainConfig)
    assert fields == {"epochs": 300, "batch_size": 128, "lr": 0.001, "patience": 30,
                      "grad_clip": 10.0, "temperature": 3.0, "hard": True, "threads": 1}
    defaults = TrainConfig("relational", "d", "o")
    assert all(getattr(defaults, k) == v for k, v in fields.items() if k != "threads")
    assert defaults.threads is None  # Table I ran single-threaded; the default leaves torch's


def test_typed_loader_converts_and_checks_types(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("name: a\nrate: 1e-3\ncount: 4\nlimit: null\nflag: true\n"
                    "options: {n_unary: 4}\n")
    assert read_fields(path, Example) == {"name": "a", "rate": 0.001, "count": 4, "limit": None,
                                          "flag": True, "options": {"n_unary": 4}}
    path.write_text("rate: 2\nlimit: 3\n")  # an int where a float is declared is that float
    fields = read_fields(path, Example)
    assert fields == {"rate": 2.0, "limit": 3} and isinstance(fields["rate"], float)
    path.write_text("")
    assert read_fields(path, Example) == {}
    for text, message in [
        ("name: a\nrte: 1\nzz: 2\n", r"c.yaml: unknown keys \['rte', 'zz'\]; Example has \["),
        ("count: 1.5\n", r"c.yaml: count: expected int, got float 1.5"),
        ("count: true\n", r"c.yaml: count: expected int, got bool True"),
        ("rate: fast\n", r"c.yaml: rate: expected a finite float, got str 'fast'"),
        ("flag: 1\n", r"c.yaml: flag: expected bool, got int 1"),
        ("limit: x\n", r"c.yaml: limit: expected int \| None, got str 'x'"),
        ("options: [1]\n", r"c.yaml: options: expected dict, got list \[1\]"),
        ("- 1\n", r"c.yaml: expected a mapping of Example settings, got list"),
        ("rate: [1\n", r"c.yaml: invalid YAML \(line 2, column 1\)"),
    ]:
        path.write_text(text)
        with pytest.raises(ValueError, match=message):
            read_fields(path, Example)
    with pytest.raises(FileNotFoundError, match="nope.yaml: no such file"):
        read_fields(tmp_path / "nope.yaml", Example)


def test_train_flags_override_the_config_file_which_overrides_defaults(tmp_path):
    path = tmp_path / "run.yaml"
    path.write_text("model: attentive\ndata: D\nout: O\nepochs: 2\nlr: 5.0e-4\n"
                    "model_kwargs: {n_heads: 2, n_unary: 4}\n")
    cfg = learning_cmds.train_config(parse_learning_args(
        ["train", "--config", str(path), "--epochs", "7", "--model-option", "n_unary=2",
         "--no-progress"]))
    assert (cfg.model, cfg.data, cfg.out) == ("attentive", "D", "O")
    assert cfg.epochs == 7 and cfg.lr == 5e-4 and cfg.patience == 30
    assert cfg.model_kwargs == {"n_heads": 2, "n_unary": 2} and cfg.progress is False
    cfg = learning_cmds.train_config(parse_learning_args(
        ["train", "--config", str(TABLE1), "--model", "deepsym", "--data", "D", "--out", "O",
         "--seed", "2", "--soft"]))
    assert (cfg.epochs, cfg.lr, cfg.patience, cfg.threads, cfg.seed) == (300, 1e-3, 30, 1, 2)
    assert cfg.hard is False and cfg.progress is True
    plain = learning_cmds.train_config(parse_learning_args(["train", "--model", "deepsym", "--data", "D",
                                               "--out", "O"]))
    assert plain == TrainConfig("deepsym", "D", "O")
    with pytest.raises(CommandError, match="give --data, --out, as flags or in the --config"):
        learning_cmds.train_config(parse_learning_args(["train", "--model", "deepsym"]))
