"""Training runs end to end: checkpoints, log, resume, eval effects, symbols, errors."""

from __future__ import annotations

import argparse
import csv
import dataclasses

import numpy as np
import pytest
import torch
from conftest import parse_learning_args, write_rule_data
from synthetic_rule import same_group_rule

from drake_symplan.cli import learning_cmds
from drake_symplan.evaluation.effects import aggregate_runs
from drake_symplan.learning.checkpoint import load_run
from drake_symplan.learning.dataset import split_by_episode
from drake_symplan.learning.effect_error import effect_metrics, object_errors_cm, summarize_errors
from drake_symplan.learning.readout import read_symbols, readout_dataset
from drake_symplan.learning.trainer import TrainConfig, _check_resumable, train
from drake_symplan.shards import write_manifest, write_shard

torch.set_num_threads(1)
SMALL = {"epochs": 2, "batch_size": 64, "lr": 1e-3, "threads": 1, "progress": False}


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    return write_rule_data(tmp_path_factory.mktemp("data"), 300, shards=2)


def test_split_is_by_episode_seeded_and_complete():
    episode = np.repeat(np.arange(20), 3)
    splits = split_by_episode(episode, seed=4)
    again = split_by_episode(episode, seed=4)
    assert all(np.array_equal(splits[k], again[k]) for k in splits)
    assert [len(splits[k]) // 3 for k in ("train", "val", "test")] == [16, 2, 2]
    groups = [set(episode[splits[k]]) for k in ("train", "val", "test")]
    assert not (groups[0] & groups[1] or groups[0] & groups[2] or groups[1] & groups[2])
    assert sorted(np.concatenate(list(splits.values()))) == list(range(60))
    with pytest.raises(ValueError, match="at least 3 episodes"):
        split_by_episode(np.zeros(5, int), seed=0)


def test_resume_refuses_a_run_saved_without_a_setting_now_in_the_config(tmp_path):
    cfg = TrainConfig("relational", "d", str(tmp_path), **SMALL)
    then = dataclasses.asdict(cfg)
    _check_resumable({"data_fingerprint": "f", "train_config": dict(then)}, cfg, "f", tmp_path)
    del then["grad_clip"]  # a run started before the setting existed
    with pytest.raises(ValueError, match=r"\['grad_clip'\] differ"):
        _check_resumable({"data_fingerprint": "f", "train_config": then}, cfg, "f", tmp_path)


def test_errors_exclude_padding_and_group_by_count():
    effect = torch.zeros(2, 3, 6)
    pred = torch.zeros(2, 3, 6)
    pred[0, 0] = 0.06  # 6 cm on every component of a real object
    pred[0, 2] = 9.0  # a padded slot: ignored
    mask = torch.tensor([[True, True, False], [True, True, True]])
    summary = summarize_errors(object_errors_cm(pred, effect, mask))
    assert summary["objects"] == 5
    assert summary["error_cm"] == pytest.approx(6.0 / 5)
    assert summary["by_count"]["2"]["error_cm"] == pytest.approx(3.0)
    assert summary["by_count"]["3"]["error_cm"] == pytest.approx(0.0)
    models = aggregate_runs([
        {"run": "a", "model": "m", "error_cm": 1.0, "by_count": {"2": {"error_cm": 1.0}},
         "by_role": {"other": {"error_cm": 4.0}}},
        {"run": "b", "model": "m", "error_cm": 3.0, "by_count": {"2": {"error_cm": 2.0}},
         "by_role": {"source": {"error_cm": 1.0}, "other": {"error_cm": 2.0}}},
    ])
    assert models["m"]["error_cm"] == {"mean": 2.0, "std": pytest.approx(2 ** 0.5), "runs": 2}
    assert models["m"]["by_count"]["2"]["mean"] == 1.5
    assert list(models["m"]["by_role"]) == ["other", "source"]
    assert models["m"]["by_role"]["other"]["mean"] == 3.0
    assert models["m"]["by_role"]["source"] == {"mean": 1.0, "std": 0.0, "runs": 1}
    assert "by_outcome" not in models["m"]
    order = aggregate_runs([{"run": r, "model": r, "error_cm": 1.0, "by_count": {}}
                            for r in ("reference", "zz", "deepsym", "relational", "attentive")])
    assert list(order) == ["relational", "attentive", "deepsym", "reference", "zz"]


class _Constant(torch.nn.Module):
    """Predicts a fixed effect tensor, whatever the input."""

    def __init__(self, pred):
        super().__init__()
        self.pred = pred

    def forward(self, state, action, mask):
        return self.pred[: len(state)]


def test_errors_by_role_and_outcome():
    from drake_symplan.learning.dataset import TensorSet

    # Transition 0: source (1 cm off), target (2 cm), another object (6 cm).
    # Transition 1: source (3 cm), target (0 cm), padding (ignored).
    action = torch.zeros(2, 3, 8)
    action[:, 0, 0] = action[:, 1, 4] = 1.0
    pred = torch.zeros(2, 3, 6)
    pred[0, 0], pred[0, 1], pred[0, 2], pred[1, 0], pred[1, 2] = 0.01, 0.02, 0.06, 0.03, 5.0
    mask = torch.tensor([[True, True, True], [True, True, False]])
    data = TensorSet(torch.zeros(2, 3, 9), action, torch.zeros(2, 3, 6), mask)
    metrics = effect_metrics(_Constant(pred), data, np.array([1, 0]), ("calm", "busy"))
    roles = {k: v["error_cm"] for k, v in metrics["by_role"].items()}
    assert roles == pytest.approx({"source": 2.0, "target": 1.0, "other": 6.0})
    assert metrics["by_role"]["other"]["objects"] == 1
    assert metrics["by_outcome"]["busy"] == {"error_cm": pytest.approx(3.0), "objects": 3}
    assert metrics["by_outcome"]["calm"] == {"error_cm": pytest.approx(1.5), "objects": 2}
    with pytest.raises(ValueError, match="1 outcome labels for 2 transitions"):
        effect_metrics(_Constant(pred), data, np.array([1]), ("calm", "busy"))


def test_train_resume_eval_and_symbols(data_dir, tmp_path):
    straight = train(TrainConfig("relational", str(data_dir), str(tmp_path / "a"),
                                 **{**SMALL, "epochs": 3}))
    assert straight["epochs"] == 3 and straight["test"]["objects"] > 0
    for name in ("best.pt", "last.pt", "config.json", "log.csv", "metrics.json"):
        assert (tmp_path / "a" / name).is_file()

    train(TrainConfig("relational", str(data_dir), str(tmp_path / "b"), **SMALL))
    with pytest.raises(ValueError, match="already holds a run"):
        train(TrainConfig("relational", str(data_dir), str(tmp_path / "b"), **SMALL))
    with pytest.raises(ValueError, match="differ"):
        train(TrainConfig("relational", str(data_dir), str(tmp_path / "b"),
                          **{**SMALL, "lr": 0.5}), resume=True)
    with open(tmp_path / "b" / "log.csv", "a") as f:  # a row of an epoch never saved
        f.write("3,1,1,1,1,1\n")
    resumed = train(TrainConfig("relational", str(data_dir), str(tmp_path / "b"),
                                **{**SMALL, "epochs": 3}), resume=True)
    # Two epochs and a resumed third give exactly the run of three straight epochs.
    assert resumed["epochs"] == 3
    a = torch.load(tmp_path / "a" / "last.pt", weights_only=False)["model_state"]
    b = torch.load(tmp_path / "b" / "last.pt", weights_only=False)["model_state"]
    assert all(torch.equal(a[k], b[k]) for k in a)
    with open(tmp_path / "b" / "log.csv") as f:
        assert [row["epoch"] for row in csv.DictReader(f)] == ["1", "2", "3"]

    args = parse_learning_args(["eval", "effects", str(tmp_path / "a"), str(tmp_path / "b"),
                   "--json", "--plot", str(tmp_path / "plot.png")])
    result = args.func(args)
    stats = result["models"]["relational"]["error_cm"]
    assert stats["runs"] == 2 and stats["std"] == pytest.approx(0.0, abs=1e-6)
    assert result["runs"][0]["error_cm"] == pytest.approx(straight["test"]["error_cm"])
    assert (tmp_path / "plot.png").stat().st_size > 0

    args = parse_learning_args(["symbols", str(tmp_path / "a"), "--data", str(data_dir),
                   "--out", str(tmp_path / "symbols.npz"), "--json"])
    summary = args.func(args)
    assert summary["transitions"] == 300 and summary["relations"] == 3
    with np.load(tmp_path / "symbols.npz") as z:
        saved = {k: z[k] for k in z.files}
    assert set(saved) == {
        "unary", "relational", "next_unary", "next_relational", "action", "mask",
        "unary_uncertain", "relational_uncertain", "next_unary_uncertain",
        "next_relational_uncertain"}
    assert saved["unary"].dtype == np.uint8 and saved["relational"].shape == (300, 3, 4, 4)
    pad = ~(saved["mask"][:, None, :, None] & saved["mask"][:, None, None, :])
    assert not saved["relational"][np.broadcast_to(pad, saved["relational"].shape)].any()

    model, config = load_run(tmp_path / "a")
    assert config["model"] == "relational" and not model.training
    arrays = same_group_rule(300, seed=0, episode_length=5)[0]
    one = read_symbols(model, arrays.state[7, :2], arrays.mask[7, :2])
    assert one[0].shape == (2, 1) and one[2].shape == (3, 2, 2)
    np.testing.assert_array_equal(one[2], saved["relational"][7, :, :2, :2])


def test_evaluate_runs_checks_the_data_fingerprint(data_dir, tmp_path):
    from drake_symplan.evaluation.effects import evaluate_runs, format_summary

    train(TrainConfig("deepsym", str(data_dir), str(tmp_path / "r"), **{**SMALL, "epochs": 1}))
    result = evaluate_runs([tmp_path / "r"], outcome_names=("a", "b"))
    assert [r["model"] for r in result["runs"]] == ["deepsym"]
    assert "by_outcome" not in result["runs"][0]  # the data set records no outcomes
    assert format_summary(result["models"])[0].startswith("deepsym: ")
    other = tmp_path / "other"
    write_manifest(other)
    write_shard(other, 0, same_group_rule(30, seed=1, episode_length=5)[0])
    with pytest.raises(ValueError, match="trained on other data.*fingerprints differ"):
        evaluate_runs([tmp_path / "r"], other)


def test_baseline_readout_has_no_relations(data_dir, tmp_path):
    args = parse_learning_args(["train", "--model", "deepsym", "--data", str(data_dir), "--out",
                   str(tmp_path / "d"), "--epochs", "1", "--threads", "1", "--no-progress",
                   "--temperature", "2", "--model-option", "n_unary=2", "--json"])
    result = args.func(args)
    assert result["model"] == "deepsym" and result["epochs"] == 1
    assert load_run(tmp_path / "d")[1]["model_config"]["temperature"] == 2.0
    symbols = readout_dataset(tmp_path / "d", data_dir)
    assert symbols.unary.shape == (300, 4, 2)
    assert symbols.relational.shape == (300, 0, 4, 4)
    assert symbols.next_relational_uncertain.dtype == bool


def test_model_options_are_parsed_and_checked_against_the_model():
    assert learning_cmds.parse_model_options(["n_unary=4", "own_message=false"]) == {
        "n_unary": 4, "own_message": False}
    with pytest.raises(ValueError, match="'n_unary' is not KEY=VALUE"):
        learning_cmds.parse_model_options(["n_unary"])
    with pytest.raises(ValueError, match=r"'attentive' has no option \['key_dim'\].*'n_heads'"):
        TrainConfig("attentive", "d", "o", model_kwargs={"key_dim": 8})
    with pytest.raises(ValueError, match=r"\['temperature'\] are set by the trainer"):
        TrainConfig("relational", "d", "o", model_kwargs={"temperature": 1.0})
    TrainConfig("relational", "d", "o", model_kwargs={"key_dim": 8, "n_relations": 2})


def test_missing_run_and_data_errors_name_the_path(tmp_path):
    with pytest.raises(FileNotFoundError, match="best.pt"):
        (tmp_path / "run").mkdir()
        load_run(tmp_path / "run")
    with pytest.raises(FileNotFoundError, match="nothing to resume"):
        train(TrainConfig("relational", str(tmp_path), str(tmp_path / "r"), **SMALL),
              resume=True)
    with pytest.raises(FileNotFoundError, match="nowhere"):
        train(TrainConfig("relational", str(tmp_path / "nowhere"), str(tmp_path / "r"), **SMALL))


def test_other_modules_can_add_eval_subcommands():
    parser = argparse.ArgumentParser()
    subparsers = parser.add_subparsers(dest="command", required=True)
    learning_cmds.register(subparsers)
    planning = learning_cmds.eval_subparsers(subparsers).add_parser("planning")
    planning.set_defaults(func=lambda args: {"planned": True})
    args = parser.parse_args(["eval", "planning"])
    assert args.func(args) == {"planned": True}
    assert parser.parse_args(["eval", "effects", "run"]).runs == ["run"]


@pytest.mark.parametrize("option, problem", [
    ("n_unary=-1", "model 'relational' cannot run with options {'n_unary': -1}: "),
    ("key_dim=nope", "model 'relational' cannot be made with options {'key_dim': 'nope'}: "),
])
def test_a_model_option_the_model_cannot_run_with_writes_no_run(option, problem, data_dir,
                                                                tmp_path, capsys):
    from conftest import assert_bad_input, run

    out = tmp_path / "runs" / "r"
    code, stdout, err = run(["train", "--model", "relational", "--data", data_dir, "--out", out,
                             "--model-option", option, "--epochs", "1", "--no-progress"],
                            capsys)
    assert_bad_input(code, stdout, err, f"symplan train: error: {problem}")
    assert list(tmp_path.iterdir()) == []
