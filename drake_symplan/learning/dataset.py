"""Transitions as in-memory torch tensors, episode-level splits, normalisation statistics.

The whole data set lives in memory as four tensors (no DataLoader, no worker
processes): a batch is one `index_select` per tensor. Splits are drawn over
*episodes*, never over transition indices, so transitions of one episode (which
share objects and scenes) never straddle train and test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from drake_symplan.datasets import TransitionArrays

SPLITS = ("train", "val", "test")
DEFAULT_FRACTIONS = (0.8, 0.1, 0.1)


@dataclass
class TensorSet:
    """state [T, N, d_o], action [T, N, A], effect [T, N, E] float32; mask [T, N] bool;
    next_state [T, N, d_o] where the data has it (the symbolic transition objective)."""

    state: torch.Tensor
    action: torch.Tensor
    effect: torch.Tensor
    mask: torch.Tensor
    next_state: torch.Tensor | None = None

    @classmethod
    def from_arrays(cls, arrays: TransitionArrays, index: np.ndarray | None = None) -> TensorSet:
        if index is not None:
            arrays = arrays.subset(index)
        return cls(
            torch.as_tensor(np.ascontiguousarray(arrays.state, dtype=np.float32)),
            torch.as_tensor(np.ascontiguousarray(arrays.action, dtype=np.float32)),
            torch.as_tensor(np.ascontiguousarray(arrays.effect, dtype=np.float32)),
            torch.as_tensor(np.ascontiguousarray(arrays.mask, dtype=bool)),
            None if arrays.next_state is None else
            torch.as_tensor(np.ascontiguousarray(arrays.next_state, dtype=np.float32)),
        )

    def __len__(self) -> int:
        return self.mask.shape[0]

    def to(self, device: torch.device | str) -> TensorSet:
        """The set on `device` (itself when it is there already)."""
        return TensorSet(*(None if t is None else t.to(device) for t in (
            self.state, self.action, self.effect, self.mask, self.next_state)))

    def batch(self, index: torch.Tensor, with_next: bool = False) -> tuple[torch.Tensor, ...]:
        """(state, action, effect, mask) of the transitions at `index`; `with_next`: and
        their next_state (None where the set has none)."""
        index = index.to(self.state.device)  # the order is drawn on the CPU
        out = (self.state.index_select(0, index), self.action.index_select(0, index),
               self.effect.index_select(0, index), self.mask.index_select(0, index))
        if not with_next:
            return out
        return (*out, None if self.next_state is None else self.next_state.index_select(0, index))

    def batches(self, batch_size: int, generator: torch.Generator | None = None,
                with_next: bool = False):
        """Mini-batches covering the set once; shuffled when a generator is given."""
        n = len(self)
        order = torch.randperm(n, generator=generator) if generator is not None else torch.arange(n)
        for start in range(0, n, batch_size):
            yield self.batch(order[start:start + batch_size], with_next)


def split_by_episode(
    episode: np.ndarray, seed: int, fractions: tuple[float, float, float] = DEFAULT_FRACTIONS
) -> dict[str, np.ndarray]:
    """Transition indices of the train/val/test splits, drawn over shuffled episodes.

    Each split gets round(fraction * n_episodes) episodes (train takes the rest);
    with three or more episodes no split is empty.
    """
    if len(fractions) != 3 or abs(sum(fractions) - 1.0) > 1e-6 or min(fractions) < 0:
        raise ValueError(f"split fractions must be three non-negative numbers summing to 1, "
                         f"got {fractions}")
    episodes = np.unique(episode)
    if len(episodes) < 3:
        raise ValueError(f"need at least 3 episodes to split by episode, got {len(episodes)}")
    shuffled = np.random.default_rng(seed).permutation(episodes)
    n = len(shuffled)
    n_val = max(1, round(fractions[1] * n))
    n_test = max(1, round(fractions[2] * n))
    groups = {
        "test": shuffled[:n_test],
        "val": shuffled[n_test:n_test + n_val],
        "train": shuffled[n_test + n_val:],
    }
    return {name: np.flatnonzero(np.isin(episode, groups[name])) for name in SPLITS}


def normalization_stats(arrays: TransitionArrays) -> dict[str, torch.Tensor]:
    """Mean and std of state features and effects over real objects (std >= 1e-6, else 1)."""
    real = arrays.mask.astype(bool)
    stats = {}
    for key in ("state", "effect"):
        values = getattr(arrays, key)[real].astype(np.float64)
        if len(values) == 0:
            raise ValueError("cannot compute normalisation statistics without real objects")
        mean, std = values.mean(axis=0), values.std(axis=0)
        std = np.where(std < 1e-6, 1.0, std)
        stats[f"{key}_mean"] = torch.as_tensor(mean, dtype=torch.float32)
        stats[f"{key}_std"] = torch.as_tensor(std, dtype=torch.float32)
    return stats
