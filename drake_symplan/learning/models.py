"""The three effect predictors of the paper's Table I.

Every model maps a padded batch (state [B, N, d_o], action [B, N, ACTION_DIM],
mask [B, N]) to per-object effects [B, N, EFFECT_DIM] in metres (zero on padded
slots), through a binary bottleneck that can be read out as symbols:

- `RelationalDeepSym` (the paper's model): unary bits per object from an encoder, K
  relation types from a value-less self-attention with Gumbel-sigmoid weights
  alpha^k_ij = GS(q^k_i . k^k_j), messages h^k_i = sum_j alpha^k_ij z_j with
  z_j = MLP([unary_j; action_j]), decoder on [z_i; h^1_i; ...; h^K_i]. (The paper's
  equation 2 prints z_i inside the sum; its text, message passing over related
  objects, needs z_j.) Self-pairs (i, i) are relations like any other. The decoder
  also sees the object's own z_i (`own_message`, default on): without it an object learns
  its own role in the action only through a self-relation, which spends a relation type
  on identity (measured: test effect error 1.49 -> 1.31 cm on a 9k-transition hand data
  set). z_i is a function of symbols and action only, so the decoder still reads nothing
  but symbols. Permutation-equivariant; padded objects take part in no relation.
- `DeepSym` (Ahmetoglu et al. 2022): unary bits per object, laid out in a fixed-size
  vector ordered [source, target, the other objects, padding]; one decoder predicts
  every slot's effect, which is put back in the caller's object order.
- `AttentiveDeepSym` (Ahmetoglu et al. 2022, attentive): unary bits per object, then
  transformer encoder layers over the objects, then a per-object decoder.

`ContinuousReference` is not a symbol learner: the attentive model without its
bottleneck (the transformer reads the standardised features themselves). Its test
error is the data set's floor for the three symbolic models, what they could reach if
symbols cost nothing; it has no symbols to read out.

`transition_weight` > 0 (Relational and Attentive) adds learning/transition.py's head and
loss: the bits must also predict the next scene's bits from the bits and the action.

Features are standardised and effects de-standardised with training-set statistics
held in buffers (`set_normalization`), so checkpoints are self-contained. Per-object
layers run on the real objects only (`layers.Packed`); padded slots are never computed.
"""

from __future__ import annotations

import torch
from torch import nn

from drake_symplan.actions import ACTION_DIM, EFFECT_DIM, IS_SOURCE, IS_TARGET
from drake_symplan.learning.effect_error import effect_loss
from drake_symplan.learning.gumbel import DEFAULT_HARD, DEFAULT_TEMPERATURE, GumbelSigmoid
from drake_symplan.learning.layers import (
    MLP,
    NormedLinear,
    Packed,
    packed_transformer,
    scale_to_norm,
)
from drake_symplan.learning.transition import (
    TransitionHead,
    target_bits,
    transition_loss,
)


class EffectModel(nn.Module):
    """Shared parts: normalisation buffers, the unary encoder, the constructor config."""

    n_relations = 0

    def __init__(
        self,
        state_dim: int,
        n_unary: int,
        hidden: int = 128,
        layers: int = 2,
        temperature: float = DEFAULT_TEMPERATURE,
        hard: bool = DEFAULT_HARD,
    ):
        super().__init__()
        self.state_dim = state_dim
        self.n_unary = n_unary
        self._config = {
            "state_dim": state_dim, "n_unary": n_unary, "hidden": hidden, "layers": layers,
            "temperature": temperature, "hard": hard,
        }
        self.register_buffer("state_mean", torch.zeros(state_dim))
        self.register_buffer("state_std", torch.ones(state_dim))
        self.register_buffer("effect_mean", torch.zeros(EFFECT_DIM))
        self.register_buffer("effect_std", torch.ones(EFFECT_DIM))
        if n_unary > 0:
            self.encoder = MLP(state_dim, [hidden] * layers)
            self.unary_head = NormedLinear(hidden, n_unary)
            self.gs = GumbelSigmoid(temperature, hard)

    def config(self) -> dict:
        """Keyword arguments that rebuild this model (see `build_model`)."""
        return dict(self._config)

    @torch.no_grad()
    def set_normalization(
        self,
        state_mean: torch.Tensor,
        state_std: torch.Tensor,
        effect_mean: torch.Tensor,
        effect_std: torch.Tensor,
    ) -> None:
        self.state_mean.copy_(state_mean)
        self.state_std.copy_(state_std)
        self.effect_mean.copy_(effect_mean)
        self.effect_std.copy_(effect_std)

    def _features(self, state: torch.Tensor) -> torch.Tensor:
        return (state - self.state_mean) / self.state_std

    def _effects(self, out: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return (out * self.effect_std + self.effect_mean) * mask.unsqueeze(-1)

    def unary_logits(self, state: torch.Tensor) -> torch.Tensor:
        """[B, N, n_unary] logits of the unary symbols."""
        if self.n_unary == 0:
            raise ValueError(f"{type(self).__name__} has no symbols to read out")
        return self.unary_head(self.encoder(self._features(state)))

    def relation_logits(self, state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor | None:
        """[B, K, N, N] logits of r_k(o_i, o_j), or None for a model without relations."""
        return None

    def _unary_bits(self, features: torch.Tensor) -> torch.Tensor:
        """Unary bits (sampled in training) of standardised features [..., d_o]."""
        return self.gs(self.unary_head(self.encoder(features)))

    transition_weight = 0.0

    def training_loss(self, state: torch.Tensor, action: torch.Tensor, effect: torch.Tensor,
                      mask: torch.Tensor, next_state: torch.Tensor | None = None
                      ) -> torch.Tensor:
        """The effect loss, plus `transition_weight` times the symbolic transition loss
        where the model has the head and the batch the next state."""
        if self.transition_weight <= 0 or next_state is None:
            return effect_loss(self(state, action, mask), effect, mask.to(state.dtype))
        effects, h, relations = self._parts(state, action, mask)
        target_rel = (target_bits(self.relation_logits(next_state, mask))
                      if self.n_relations else None)
        target_unary = (target_bits(self.unary_logits(next_state))
                        if self.n_unary else None)
        return (effect_loss(effects, effect, mask.to(state.dtype))
                + self.transition_weight * transition_loss(
                    self.transition(h, relations), target_unary, target_rel, mask))

    def _parts(self, state, action, mask) -> tuple:
        """(effects, per-object messages [B, N, H], relation bits or None)."""
        raise NotImplementedError(f"{type(self).__name__} has no symbolic transition head")


def object_transformer(d_model: int, n_heads: int, n_blocks: int, hidden: int) -> nn.Module:
    """Transformer encoder layers over a set of objects (no dropout, batch first)."""
    block = nn.TransformerEncoderLayer(
        d_model, n_heads, dim_feedforward=hidden, dropout=0.0, batch_first=True
    )
    return nn.TransformerEncoder(block, n_blocks, enable_nested_tensor=False)


OFFSET_SCALE = 0.05  # m: relative positions in box sizes


class RelationalDeepSym(EffectModel):
    """Unary symbols + K relation types from value-less sigmoid self-attention."""

    def __init__(
        self,
        state_dim: int,
        n_unary: int = 1,
        n_relations: int = 3,
        key_dim: int = 16,
        z_dim: int = 64,
        hidden: int = 128,
        layers: int = 2,
        temperature: float = DEFAULT_TEMPERATURE,
        hard: bool = DEFAULT_HARD,
        own_message: bool = True,
        invariant: bool = False,
        transition_weight: float = 0.0,
    ):
        super().__init__(state_dim, n_unary, hidden, layers, temperature, hard)
        self._config.update(n_relations=n_relations, key_dim=key_dim, z_dim=z_dim,
                            own_message=own_message, invariant=invariant,
                            transition_weight=transition_weight)
        self.n_relations = n_relations
        self.key_dim = key_dim
        self.own_message = own_message
        self.invariant = invariant
        if invariant:
            # Symbols that do not move with the table: the unary encoder does not see the
            # absolute x, y; a relation reads both objects (without x, y) and their offset.
            self.encoder = MLP(state_dim - 2, [hidden] * layers)
            self.pair = MLP(2 * (state_dim - 2) + 3, [hidden] * layers)
            self.pair_head = NormedLinear(hidden, n_relations)
        else:
            self.attention = MLP(state_dim, [hidden] * layers, 2 * n_relations * key_dim)
        self.message = MLP(n_unary + ACTION_DIM, [hidden] * layers, z_dim)
        self.decoder = MLP((n_relations + own_message) * z_dim, [hidden] * layers, EFFECT_DIM)
        self.transition_weight = transition_weight
        if transition_weight > 0:
            self.transition = TransitionHead((n_relations + own_message) * z_dim, n_unary,
                                             n_relations, hidden)

    def _features(self, state: torch.Tensor) -> torch.Tensor:
        f = super()._features(state)
        return f[..., 2:] if self.invariant else f

    def relation_logits(self, state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        if self.invariant:
            return self._invariant_logits(self._features(state), state)
        return self._pair_logits(self.attention(self._features(state)))

    def _invariant_logits(self, f: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        """[B, K, N, N] from MLP([f_i; f_j; (p_j - p_i) / OFFSET_SCALE])."""
        b, n, d = f.shape
        p = state[..., :3]
        offset = (p.unsqueeze(1) - p.unsqueeze(2)) / OFFSET_SCALE  # [B, i, j, 3] = p_j - p_i
        pair = torch.cat([f.unsqueeze(2).expand(b, n, n, d), f.unsqueeze(1).expand(b, n, n, d),
                          offset], dim=-1)
        return self.pair_head(self.pair(pair)).permute(0, 3, 1, 2)

    def _pair_logits(self, qk: torch.Tensor) -> torch.Tensor:
        """[B, K, N, N] q^k_i . k^k_j from the attention MLP's output [B, N, 2 K key_dim]."""
        b, n, _ = qk.shape
        qk = scale_to_norm(qk.view(b, n, 2, self.n_relations, self.key_dim))
        qk = qk.permute(2, 0, 3, 1, 4)  # [2, B, K, N, key_dim]
        return qk[0] @ qk[1].transpose(-1, -2)

    def _relation_bits(self, logits: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        m = mask.to(logits.dtype)
        pair = (m.unsqueeze(-1) * m.unsqueeze(-2)).unsqueeze(1)
        return self.gs(logits) * pair

    def relations(self, state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """[B, K, N, N] relation bits (sampled in training), zero wherever a slot is padding."""
        return self._relation_bits(self.relation_logits(state, mask), mask)

    def forward(self, state: torch.Tensor, action: torch.Tensor, mask: torch.Tensor):
        return self._parts(state, action, mask)[0]

    def _parts(self, state, action, mask) -> tuple:
        b, n, _ = state.shape
        packed = Packed(mask)
        x = packed.pack(self._features(state))
        unary = self._unary_bits(x)
        z = self.message(torch.cat([unary, packed.pack(action)], dim=-1))  # [M, D]
        if self.invariant:
            logits = self._invariant_logits(packed.unpack(x), state)
        else:
            logits = self._pair_logits(packed.unpack(self.attention(x)))
        alpha = self._relation_bits(logits, mask)  # [B, K, N, N]
        h = (alpha.reshape(b, self.n_relations * n, n) @ packed.unpack(z))
        h = h.view(b, self.n_relations, n, -1).transpose(1, 2).reshape(b, n, -1)
        h = packed.pack(h)  # [M, K * D], heads concatenated
        if self.own_message:
            h = torch.cat([z, h], dim=-1)
        return self._effects(packed.unpack(self.decoder(h)), mask), packed.unpack(h), alpha


class DeepSym(EffectModel):
    """Fixed-size DeepSym: slots ordered [source, target, rest, padding]."""

    def __init__(
        self,
        state_dim: int,
        max_objects: int,
        n_unary: int = 4,
        hidden: int = 128,
        layers: int = 2,
        temperature: float = DEFAULT_TEMPERATURE,
        hard: bool = DEFAULT_HARD,
    ):
        super().__init__(state_dim, n_unary, hidden, layers, temperature, hard)
        self._config.update(max_objects=max_objects)
        self.max_objects = max_objects
        slot = n_unary + 1 + ACTION_DIM  # bits, is-real, action encoding
        self.decoder = MLP(max_objects * slot, [hidden] * layers, max_objects * EFFECT_DIM)

    @staticmethod
    def role_order(action: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """[B, N] permutation putting source, target, other real objects, padding first."""
        n = mask.shape[1]
        rank = torch.where(mask, 2.0, 3.0)
        rank = torch.where(action[..., IS_TARGET] > 0.5, 1.0, rank)
        rank = torch.where(action[..., IS_SOURCE] > 0.5, 0.0, rank)
        rank = rank * n + torch.arange(n, device=mask.device)  # stable within a rank
        return rank.argsort(dim=1)

    def forward(self, state: torch.Tensor, action: torch.Tensor, mask: torch.Tensor):
        b, n, _ = state.shape
        m = self.max_objects
        packed = Packed(mask)
        bits = packed.unpack(self._unary_bits(packed.pack(self._features(state))))
        slots = torch.cat([bits, mask.unsqueeze(-1).to(state.dtype),
                           action * mask.unsqueeze(-1)], dim=-1)
        order = self.role_order(action, mask)
        slots = slots.gather(1, order.unsqueeze(-1).expand_as(slots))
        if n > m:
            if mask.sum(dim=1).max() > m:
                raise ValueError(f"DeepSym was built for at most {m} objects")
            slots = slots[:, :m]
        elif n < m:
            slots = torch.cat([slots, slots.new_zeros(b, m - n, slots.shape[-1])], dim=1)
        out = self.decoder(slots.reshape(b, -1)).view(b, m, EFFECT_DIM)
        if n > m:
            out = torch.cat([out, out.new_zeros(b, n - m, EFFECT_DIM)], dim=1)
        else:
            out = out[:, :n]
        inverse = order.argsort(dim=1)
        out = out.gather(1, inverse.unsqueeze(-1).expand_as(out))
        return self._effects(out, mask)


class AttentiveDeepSym(EffectModel):
    """Unary bits per object, transformer encoder layers over objects, decoder."""

    def __init__(
        self,
        state_dim: int,
        n_unary: int = 4,
        n_heads: int = 4,
        n_blocks: int = 2,
        d_model: int = 128,
        hidden: int = 128,
        layers: int = 2,
        temperature: float = DEFAULT_TEMPERATURE,
        hard: bool = DEFAULT_HARD,
        transition_weight: float = 0.0,
    ):
        super().__init__(state_dim, n_unary, hidden, layers, temperature, hard)
        self._config.update(n_heads=n_heads, n_blocks=n_blocks, d_model=d_model,
                            transition_weight=transition_weight)
        self.embed = nn.Linear(n_unary + ACTION_DIM, d_model)
        self.transformer = object_transformer(d_model, n_heads, n_blocks, hidden)
        self.decoder = MLP(d_model, [hidden] * layers, EFFECT_DIM)
        self.transition_weight = transition_weight
        if transition_weight > 0:
            self.transition = TransitionHead(d_model, n_unary, 0, hidden)

    def forward(self, state: torch.Tensor, action: torch.Tensor, mask: torch.Tensor):
        return self._parts(state, action, mask)[0]

    def _parts(self, state, action, mask) -> tuple:
        packed = Packed(mask)
        bits = self._unary_bits(packed.pack(self._features(state)))
        x = self.embed(torch.cat([bits, packed.pack(action)], dim=-1))
        x = packed_transformer(self.transformer, x, packed)
        return self._effects(packed.unpack(self.decoder(x)), mask), packed.unpack(x), None


class ContinuousReference(EffectModel):
    """AttentiveDeepSym without the bottleneck: features and action into the transformer.

    `temperature` and `hard` are accepted, like every model's, and unused.
    """

    def __init__(
        self,
        state_dim: int,
        n_heads: int = 4,
        n_blocks: int = 2,
        d_model: int = 128,
        hidden: int = 128,
        layers: int = 2,
        temperature: float = DEFAULT_TEMPERATURE,
        hard: bool = DEFAULT_HARD,
    ):
        super().__init__(state_dim, 0, hidden, layers, temperature, hard)
        del self._config["n_unary"]
        self._config.update(n_heads=n_heads, n_blocks=n_blocks, d_model=d_model)
        self.embed = MLP(state_dim + ACTION_DIM, [hidden] * (layers - 1), d_model)
        self.transformer = object_transformer(d_model, n_heads, n_blocks, hidden)
        self.decoder = MLP(d_model, [hidden] * layers, EFFECT_DIM)

    def forward(self, state: torch.Tensor, action: torch.Tensor, mask: torch.Tensor):
        packed = Packed(mask)
        x = self.embed(packed.pack(torch.cat([self._features(state), action], dim=-1)))
        x = packed_transformer(self.transformer, x, packed)
        return self._effects(packed.unpack(self.decoder(x)), mask)


MODELS: dict[str, type[EffectModel]] = {
    "relational": RelationalDeepSym,
    "attentive": AttentiveDeepSym,
    "deepsym": DeepSym,
    "reference": ContinuousReference,
}


def build_model(name: str, **kwargs) -> EffectModel:
    """The model registered as `name`, built with `kwargs` (see each class)."""
    if name not in MODELS:
        raise ValueError(f"unknown model {name!r}; expected one of {sorted(MODELS)}")
    return MODELS[name](**kwargs)
