"""The symbolic transition objective (learning/transition.py) on a world where one bit the
effect alone need not hold decides the next symbols (tests/synthetic_rule.sticky_rule):
fine-tuned with it, the learner's symbols make every held-out symbolic effect the one its
training data predicts; `--init` starts such a run from an effect-only one."""

from __future__ import annotations

import pytest
import torch
from conftest import assert_bad_input, run
from synthetic_rule import sticky_rule

from drake_symplan.evaluation.operators import determinism
from drake_symplan.learning.dataset import TensorSet, normalization_stats
from drake_symplan.learning.effect_error import effect_metrics
from drake_symplan.learning.models import build_model
from drake_symplan.learning.readout import readout_dataset
from drake_symplan.learning.trainer import make_optimizer, train_step
from drake_symplan.symbolic.effect_operators import PAPER

STEPS = 600  # Adam steps effect-only, then as many with the transition loss


def _fit(train, weight: float, seed: int):
    torch.manual_seed(seed)
    model = build_model("relational", state_dim=3, hidden=64, transition_weight=weight)
    model.set_normalization(**normalization_stats(train))
    optimizer = make_optimizer(model, lr=2e-3)
    shuffle, data, done = torch.Generator().manual_seed(seed), TensorSet.from_arrays(train), 0
    model.train()
    while done < 2 * STEPS:
        for batch in data.batches(128, shuffle, with_next=done >= STEPS):
            train_step(model, optimizer, batch, grad_clip=10.0)
            done += 1
    return model.eval()


@pytest.mark.slow
def test_the_transition_objective_makes_the_symbolic_effects_deterministic():
    torch.set_num_threads(1)
    train, held_out = sticky_rule(3000, seed=0), sticky_rule(500, seed=2)
    model = _fit(train, 0.003, seed=0)
    report = determinism(readout_dataset(model, train), readout_dataset(model, held_out),
                         PAPER)
    assert report["changed"] > 100  # the bits still say where things are
    assert report["determinism_seen"] == 1.0, report
    assert report["seen"] >= 0.95, report
    error = effect_metrics(model, TensorSet.from_arrays(held_out))["error_cm"]
    assert error < 0.1  # cm, on 5 cm moves: the effects are still predicted


def test_a_model_without_the_head_reads_no_next_state():
    train = sticky_rule(50, seed=0)
    model = build_model("relational", state_dim=3, hidden=16).eval()  # no Gumbel noise
    batch = TensorSet.from_arrays(train).batch(torch.arange(8), with_next=True)
    # the next state is there, the model has no head: its loss is the effect loss alone
    assert torch.equal(model.training_loss(*batch), model.training_loss(*batch[:4]))
    with pytest.raises(NotImplementedError):  # DeepSym has no head to give the objective
        build_model("deepsym", state_dim=3, max_objects=3)._parts(*batch[:2], batch[3])


def test_init_needs_a_checkpoint(tmp_path, capsys):
    assert_bad_input(*run(["train", "--model", "relational", "--data", tmp_path, "--out",
                           tmp_path / "run", "--init", tmp_path / "missing"], capsys),
                     "no checkpoint there")
    assert not (tmp_path / "run").exists()
