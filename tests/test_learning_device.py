"""`--device auto|cpu|cuda`: which device it resolves to (torch.cuda.is_available
monkeypatched, so the GPU branches run on a CPU-only machine too), `cuda` without a GPU
is one line and exit status 2, the device a run trained on is in its config.json, a run
resumes under another device setting, and a CPU run's numbers do not depend on the
option. The tests marked `gpu` need a CUDA GPU (skipped without one): a run on the GPU
whose checkpoints load and resume on the CPU."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch
from conftest import write_rule_data
from synthetic_rule import same_group_rule

from drake_symplan.cli import options
from drake_symplan.cli.main import main
from drake_symplan.learning import device as dev
from drake_symplan.learning.checkpoint import load_run, read_checkpoint
from drake_symplan.learning.dataset import TensorSet
from drake_symplan.learning.trainer import TrainConfig, _check_resumable, train

SMALL = {"epochs": 2, "batch_size": 64, "lr": 1e-3, "threads": 1, "progress": False}
gpu = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    return write_rule_data(tmp_path_factory.mktemp("data"), 200)


@pytest.fixture
def no_gpu(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)


def test_the_parser_offers_the_devices_the_trainer_knows():
    assert options.DEVICES == dev.DEVICES


def test_auto_is_the_gpu_when_torch_sees_one(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    assert dev.resolve_device("auto") == torch.device("cuda")
    assert dev.resolve_device("cuda") == torch.device("cuda")
    assert dev.resolve_device("cpu") == torch.device("cpu")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert dev.resolve_device("auto") == torch.device("cpu")
    with pytest.raises(ValueError, match="--device cuda: .* has no GPU here; use --device cpu"):
        dev.resolve_device("cuda")
    with pytest.raises(ValueError, match="unknown device 'tpu'"):
        dev.resolve_device("tpu")
    with pytest.raises(ValueError, match="unknown device"):
        TrainConfig("relational", "d", "o", device="gpu")


def test_cuda_without_a_gpu_is_one_line_and_writes_nothing(no_gpu, data_dir, tmp_path,
                                                             capsys):
    out = tmp_path / "run"
    for argv in (["train", "--model", "relational", "--data", str(data_dir), "--out", str(out),
                  "--device", "cuda"],
                 ["collect", "--backend", "hand", "--transitions", "8", "--out", str(out),
                  "--explorer", "active", "--device", "cuda"],
                 ["curve", "--scale", "small", "--out", str(out), "--device", "cuda"],
                 ["reproduce", "--scale", "small", "--out", str(out), "--device", "cuda"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--device cuda:" in err[0] and "--device cpu" in err[0], err
        assert not out.exists()


def test_the_pipelines_pass_the_device_to_every_training(tmp_path):
    from drake_symplan.pipelines.learning_curve import LearningCurve
    from drake_symplan.pipelines.reproduce import Reproduction

    rep = Reproduction("small", tmp_path / "rep", device="cpu")
    trains = rep.train_stages()
    assert trains and all(s.argv[s.argv.index("--device") + 1] == "cpu" for s in trains)
    curve = LearningCurve("small", tmp_path / "curve", device="cuda")
    active = curve.collect_stage("active", curve.sizes("active")[0])
    assert active.argv[active.argv.index("--device") + 1] == "cuda"
    point = curve.point_stages("random", curve.sizes("random")[0], 0)[0]
    assert point.argv[point.argv.index("--device") + 1] == "cuda"
    assert "--device" not in curve.collect_stage(None, 8).argv  # random: nothing trains


def test_the_active_rounds_train_on_the_device_given(monkeypatch, tmp_path):
    from drake_symplan.explorers import rounds

    seen = []

    def fake_train(cfg):
        seen.append(cfg.device)
        raise RuntimeError("stop")  # the device is all this test wants

    monkeypatch.setattr(rounds, "train", fake_train)
    monkeypatch.setattr(rounds.storage, "link_head", lambda out, where, n: where)
    from drake_symplan.data.collect import CollectConfig
    from drake_symplan.explorers.active import ActiveConfig

    config = CollectConfig(backend="hand", transitions=20, seed=0, chunk_size=4,
                           explorer="active", active=dataclasses.asdict(ActiveConfig(
                               warmup=12, round_size=8, members=2, epochs=3)))
    with pytest.raises(RuntimeError, match="stop"):
        rounds.learn_round(tmp_path, 1, config, ActiveConfig(**config.active), device="cpu")
    assert seen == ["cpu"]


def test_a_cpu_run_is_the_same_whatever_the_option_and_records_its_device(
        no_gpu, data_dir, tmp_path):
    runs = {}
    for name in ("cpu", "auto"):
        metrics = train(TrainConfig("relational", str(data_dir), str(tmp_path / name),
                                    device=name, **SMALL))
        runs[name] = metrics
        config = json.loads((tmp_path / name / "config.json").read_text())
        assert config["device"] == "cpu" and config["train_config"]["device"] == name
    assert runs["cpu"]["best_val_loss"] == runs["auto"]["best_val_loss"]
    assert runs["cpu"]["test"] == runs["auto"]["test"]
    a = read_checkpoint(tmp_path / "cpu" / "best.pt")["model_state"]
    b = read_checkpoint(tmp_path / "auto" / "best.pt")["model_state"]
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_a_run_resumes_under_another_device_setting(no_gpu, data_dir, tmp_path):
    cfg = TrainConfig("relational", str(data_dir), str(tmp_path / "r"), device="cpu",
                      **{**SMALL, "epochs": 1})
    train(cfg)
    resumed = train(dataclasses.replace(cfg, device="auto", epochs=2), resume=True)
    assert resumed["epochs"] == 2
    then = dataclasses.asdict(cfg)
    del then["device"]  # a run saved before the option existed resumes too
    _check_resumable({"data_fingerprint": "f", "train_config": then}, cfg, "f", tmp_path)


def test_a_tensor_set_moves_and_is_indexed_on_its_device():
    arrays, _ = same_group_rule(20, seed=0, episode_length=5)
    data = TensorSet.from_arrays(arrays)
    assert data.to("cpu").state is data.state  # already there: no copy
    meta = data.to("meta")  # a device other than the CPU's, on any machine
    assert meta.state.device.type == "meta" and meta.mask.dtype == torch.bool
    batch = meta.batch(torch.arange(5))  # a CPU index (the order is drawn on the CPU)
    assert batch[0].device.type == "meta" and batch[0].shape[0] == 5


@gpu
def test_a_gpu_run_loads_and_resumes_on_the_cpu(data_dir, tmp_path):
    cfg = TrainConfig("relational", str(data_dir), str(tmp_path / "g"), device="cuda",
                      **{**SMALL, "epochs": 1})
    metrics = train(cfg)
    config = json.loads((tmp_path / "g" / "config.json").read_text())
    assert config["device"] == "cuda" and config["gpu"]
    assert np.isfinite(metrics["best_val_loss"])
    assert "cuda" in read_checkpoint(tmp_path / "g" / "last.pt")["rng"]
    model, _ = load_run(tmp_path / "g")  # saved on the GPU, read onto the CPU
    assert all(p.device.type == "cpu" for p in model.parameters())
    on_gpu = read_checkpoint(tmp_path / "g" / "best.pt", "cuda")["model_state"]
    assert all(t.device.type == "cuda" for t in on_gpu.values())
    resumed = train(dataclasses.replace(cfg, device="cpu", epochs=2), resume=True)
    assert resumed["epochs"] == 2 and np.isfinite(resumed["best_val_loss"])
