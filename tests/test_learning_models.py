"""Gumbel-sigmoid, the norm-3 layer, the three models and the continuous reference:
padding, equivariance, roles."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from drake_symplan.actions import Action, encode_action
from drake_symplan.learning.gumbel import GumbelSigmoid, gumbel_sigmoid, read_bits
from drake_symplan.learning.layers import NormedLinear, Packed, packed_transformer
from drake_symplan.learning.models import DeepSym, build_model, object_transformer

torch.set_num_threads(1)
D = 5


def _batch(b: int = 6, n: int = 4, seed: int = 0):
    """Random scenes with 2..n real objects (padding at the end), source and target set."""
    rng = np.random.default_rng(seed)
    state = rng.normal(size=(b, n, D)).astype(np.float32)
    action = np.zeros((b, n, 8), np.float32)
    mask = np.zeros((b, n), bool)
    names = [f"o{i}" for i in range(n)]
    for t in range(b):
        k = int(rng.integers(2, n + 1))
        mask[t, :k] = True
        s, g = rng.choice(k, size=2, replace=False)
        action[t, :k] = encode_action(Action(names[s], "left", names[g], "right"), names[:k])
    return torch.tensor(state), torch.tensor(action), torch.tensor(mask)


def _models():
    torch.manual_seed(0)
    return {
        "relational": build_model("relational", state_dim=D).eval(),
        "attentive": build_model("attentive", state_dim=D).eval(),
        "deepsym": build_model("deepsym", state_dim=D, max_objects=4).eval(),
        "reference": build_model("reference", state_dim=D).eval(),
    }


def test_gumbel_sigmoid_goes_to_bits_as_temperature_goes_to_zero():
    torch.manual_seed(0)
    logits = torch.linspace(-4, 4, 20001)
    far = {}
    for t in (1.0, 0.1, 1e-4):
        y = gumbel_sigmoid(logits, temperature=t, hard=False)
        far[t] = float(torch.minimum(y, 1 - y).mean())
    assert far[1.0] > far[0.1] > far[1e-4]
    assert far[1e-4] < 1e-3
    # The sample is 1 with probability sigmoid(logit), at any temperature.
    y = gumbel_sigmoid(torch.full((40000,), 1.0), temperature=1e-4, hard=False)
    assert abs(float((y > 0.5).float().mean()) - float(torch.sigmoid(torch.tensor(1.0)))) < 0.01


def test_straight_through_outputs_bits_with_soft_gradient():
    torch.manual_seed(0)
    logits = torch.zeros(1000, requires_grad=True)
    y = gumbel_sigmoid(logits, temperature=1.0, hard=True)
    assert set(torch.unique(y.detach()).tolist()) == {0.0, 1.0}
    y.sum().backward()
    assert bool((logits.grad > 0).all()) and float(logits.grad.max()) <= 0.25 + 1e-6


def test_eval_mode_is_deterministic_sign_with_uncertain_flag():
    gs = GumbelSigmoid().eval()
    logits = torch.tensor([-5.0, -0.5, 0.0, 0.5, 5.0])
    assert gs(logits).tolist() == [0.0, 0.0, 0.0, 1.0, 1.0]
    bits, uncertain = read_bits(logits, margin=1.0)
    assert bits.tolist() == [0, 0, 0, 1, 1] and bits.dtype == torch.uint8
    assert uncertain.tolist() == [False, True, True, True, False]
    with pytest.raises(ValueError):
        GumbelSigmoid(temperature=0.0)


def test_normed_linear_scales_input_and_weights_to_norm_three():
    layer = NormedLinear(2, 2)
    with torch.no_grad():
        layer.weight.copy_(torch.tensor([[2.0, 0.0], [0.0, -0.1]]))
    out = layer(torch.tensor([[10.0, 0.0], [0.0, 0.001]]))
    np.testing.assert_allclose(out.detach().numpy(), [[9.0, 0.0], [0.0, -9.0]], atol=1e-5)


def test_packed_objects_round_trip_with_zeros_in_padding():
    x = torch.arange(24.0).view(2, 3, 4)
    packed = Packed(torch.tensor([[True, False, True], [False, True, False]]))
    assert packed.pack(x)[:, 0].tolist() == [0.0, 8.0, 16.0]
    assert packed.unpack(packed.pack(x)).tolist() == [
        [list(range(0, 4)), [0.0] * 4, list(range(8, 12))],
        [[0.0] * 4, list(range(16, 20)), [0.0] * 4]]


def test_packed_transformer_matches_the_torch_encoder_on_real_objects():
    torch.manual_seed(0)
    encoder = object_transformer(d_model=16, n_heads=4, n_blocks=2, hidden=32).train()
    x = torch.randn(5, 4, 16)
    mask = torch.tensor([[1, 1, 0, 0], [1, 1, 1, 1], [1, 0, 1, 0], [0, 0, 0, 0], [1, 1, 1, 0]],
                        dtype=torch.bool)
    packed = Packed(mask)
    y = packed_transformer(encoder, packed.pack(x).requires_grad_(), packed)
    keep = mask.any(dim=1)  # torch's encoder gives NaN for a transition with no object
    want = encoder(x[keep], src_key_padding_mask=~mask[keep])
    torch.testing.assert_close(packed.unpack(y)[keep][mask[keep]], want[mask[keep]],
                               atol=1e-5, rtol=1e-5)
    y.sum().backward()  # the empty transition leaves no NaN in any gradient
    assert all(torch.isfinite(p.grad).all() for p in encoder.parameters())


@pytest.mark.parametrize("name", ["relational", "attentive", "deepsym", "reference"])
@torch.no_grad()
def test_padding_is_inert(name):
    model = _models()[name]
    state, action, mask = _batch()
    pred = model(state, action, mask)
    assert pred.shape == (6, 4, 6)
    assert float(pred[~mask].abs().max()) == 0.0
    # Move the real objects to slots (0, 2, 4, 5) of 6 and fill the rest with garbage
    # features; DeepSym gets a bigger fixed size only through its own padding.
    slots = [0, 2, 4, 5] if name != "deepsym" else [0, 1, 2, 3]
    n = 6 if name != "deepsym" else 4
    big_state = torch.randn(6, n, D) * 100
    big_action = torch.zeros(6, n, 8)
    big_mask = torch.zeros(6, n, dtype=torch.bool)
    big_state[:, slots], big_action[:, slots], big_mask[:, slots] = state, action, mask
    big_state[~big_mask] = torch.randn(int((~big_mask).sum()), D) * 100
    big = model(big_state, big_action, big_mask)
    torch.testing.assert_close(big[:, slots], pred, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("name", ["relational", "attentive", "reference"])
def test_permutation_equivariance(name):
    model = _models()[name]
    state, action, mask = _batch(n=4)
    mask[:] = True  # every slot real, so any permutation is allowed
    perm = torch.tensor([2, 0, 3, 1])
    pred = model(state, action, mask)
    torch.testing.assert_close(model(state[:, perm], action[:, perm], mask[:, perm]),
                               pred[:, perm], atol=1e-5, rtol=1e-5)
    if name == "relational":
        rel = model.relation_logits(state, mask)
        rel_p = model.relation_logits(state[:, perm], mask[:, perm])
        torch.testing.assert_close(rel_p, rel[:, :, perm][:, :, :, perm])


@torch.no_grad()
def test_relational_relations_are_bits_zero_on_padding_and_directed():
    model = _models()["relational"]
    state, action, mask = _batch()
    rel = model.relations(state, mask)
    assert rel.shape == (6, 3, 4, 4)
    assert set(torch.unique(rel).tolist()) <= {0.0, 1.0}
    pad = ~(mask[:, None, :, None] & mask[:, None, None, :]).expand_as(rel)
    assert float(rel[pad].abs().sum()) == 0.0
    logits = model.relation_logits(state, mask)
    assert float(logits.abs().max()) <= 9.0 + 1e-4  # |q| = |k| = 3
    assert not torch.allclose(logits, logits.transpose(-1, -2))


def test_deepsym_role_order_puts_source_target_rest_padding():
    names = ["a", "b", "c", "d"]
    action = torch.tensor(encode_action(Action("c", "left", "a", "center"), names))[None]
    mask = torch.tensor([[True, False, True, True]])
    assert DeepSym.role_order(action, mask).tolist() == [[2, 0, 3, 1]]


def test_deepsym_rejects_too_many_objects():
    model = _models()["deepsym"]
    state, action, mask = _batch(n=6)
    mask[:] = True
    with pytest.raises(ValueError, match="at most 4"):
        model(state, action, mask)


@pytest.mark.parametrize("name", ["relational", "attentive", "deepsym", "reference"])
def test_training_mode_gradients_reach_every_parameter(name):
    model = _models()[name].train()
    state, action, mask = _batch()
    model(state, action, mask).pow(2).sum().backward()
    for pname, p in model.named_parameters():
        assert p.grad is not None and torch.isfinite(p.grad).all(), pname


def test_reference_fits_a_continuous_effect_and_has_no_symbols():
    # The effect is a continuous function of a feature: each object rises by 0.1 x its
    # first feature. Four bits per object express it to ~3 cm (AttentiveDeepSym of the
    # same width and steps); the reference, which reads the features, to ~4 mm.
    from drake_symplan.learning.readout import read_symbols

    torch.manual_seed(0)
    state, action, mask = _batch(b=128, seed=1)
    effect = torch.zeros(128, 4, 6)
    effect[..., 2] = 0.1 * state[..., 0] * mask
    model = build_model("reference", state_dim=D, d_model=64, hidden=64)
    optimizer = torch.optim.Adam(model.parameters(), lr=3e-3)
    for _ in range(200):
        loss = ((model(state, action, mask) - effect) ** 2).sum(-1).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    model.eval()
    with torch.no_grad():
        err = (model(state, action, mask) - effect)[..., 2][mask].abs().mean()
    assert float(err) < 0.006  # m; the effect's own spread is ~0.08 m
    with pytest.raises(ValueError, match="no symbols"):
        read_symbols(model, state[0])


def test_unknown_model_name():
    with pytest.raises(ValueError, match="unknown model"):
        build_model("transformer", state_dim=D)


@torch.no_grad()
def test_relational_checkpoint_from_before_own_message_loads_unchanged():
    from drake_symplan.learning.checkpoint import model_from_checkpoint

    torch.manual_seed(0)
    old = build_model("relational", state_dim=D, own_message=False).eval()
    config = old.config()
    del config["own_message"]  # what checkpoints written before the option hold
    ckpt = {"model": "relational", "model_config": config, "model_state": old.state_dict()}
    loaded = model_from_checkpoint(ckpt).eval()
    assert loaded.own_message is False
    state, action, mask = _batch()
    torch.testing.assert_close(loaded(state, action, mask), old(state, action, mask))
    assert build_model("relational", state_dim=D).own_message  # the default


@pytest.mark.parametrize("name", ["relational", "attentive", "deepsym", "reference"])
@torch.no_grad()
def test_every_model_rebuilds_from_its_checkpoint(name):
    from drake_symplan.learning.checkpoint import model_from_checkpoint

    model = _models()[name]
    ckpt = {"model": name, "model_config": model.config(), "model_state": model.state_dict()}
    loaded = model_from_checkpoint(ckpt).eval()
    state, action, mask = _batch()
    torch.testing.assert_close(loaded(state, action, mask), model(state, action, mask))


@torch.no_grad()
def test_invariant_relational_symbols_and_effects_ignore_a_shift_of_the_table():
    torch.manual_seed(0)
    model = build_model("relational", state_dim=D, invariant=True).eval()
    state, action, mask = _batch()
    shifted = state.clone()
    shifted[..., :2] += torch.tensor([0.3, -0.2])  # every object moved together in x, y
    torch.testing.assert_close(model(shifted, action, mask), model(state, action, mask))
    torch.testing.assert_close(model.relation_logits(shifted, mask),
                               model.relation_logits(state, mask))
    torch.testing.assert_close(model.unary_logits(shifted), model.unary_logits(state))
    lifted = state.clone()
    lifted[:, 0, 2] += 0.05  # one object higher: its relations to the others change
    assert not torch.allclose(model.relation_logits(lifted, mask)[:, :, 0, 1],
                              model.relation_logits(state, mask)[:, :, 0, 1])
    perm = torch.tensor([2, 0, 3, 1])
    mask[:] = True
    torch.testing.assert_close(model.relation_logits(state[:, perm], mask[:, perm]),
                               model.relation_logits(state, mask)[:, :, perm][:, :, :, perm])
