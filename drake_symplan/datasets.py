"""The data sets that pass between layers: padded transition batches (what `data` stores
and `learning` trains on) and the symbols read out of them. No Drake and no torch here."""

from __future__ import annotations

import dataclasses
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drake_symplan.actions import ACTION_DIM, EFFECT_DIM
from drake_symplan.atomic import write_atomic

# The outcome class a data set records per transition (data/exploration.py: classify), by
# index; what `symplan data stats` and the effect error by outcome report.
OUTCOMES = ("no_effect", "placed", "tipped", "carried_along", "fell_off", "other")


@dataclass
class TransitionArrays:
    """A padded batch of transitions: what `data` stores and `learning` trains on.

    T transitions, each with up to N relevant objects (action arguments plus the
    objects in contact with them), padded to N with `mask` False. Object order inside
    a transition carries no meaning (the models are permutation-equivariant), except
    for the DeepSym baseline, which reorders by the action roles itself.
    """

    state: np.ndarray  # [T, N, d_o] float32, perceived features before the action
    action: np.ndarray  # [T, N, ACTION_DIM] float32, see encode_action
    effect: np.ndarray  # [T, N, EFFECT_DIM] float32, metres
    mask: np.ndarray  # [T, N] bool, True for real objects
    episode: np.ndarray  # [T] int64, episode id (splits are by episode)
    next_state: np.ndarray | None = None  # [T, N, d_o] float32, perceived after

    def __post_init__(self):
        t, n = self.mask.shape
        for key in ("state", "action", "effect", "next_state"):
            arr = getattr(self, key)
            if arr is not None and arr.shape[:2] != (t, n):
                raise ValueError(f"{key} has shape {arr.shape}, expected ({t}, {n}, ...)")
        if self.action.shape[2] != ACTION_DIM or self.effect.shape[2] != EFFECT_DIM:
            raise ValueError("action/effect width does not match ACTION_DIM/EFFECT_DIM")
        if self.episode.shape != (t,):
            raise ValueError(f"episode has shape {self.episode.shape}, expected ({t},)")

    def __len__(self) -> int:
        return self.mask.shape[0]

    def subset(self, index: np.ndarray) -> TransitionArrays:
        ns = None if self.next_state is None else self.next_state[index]
        return TransitionArrays(
            self.state[index], self.action[index], self.effect[index],
            self.mask[index], self.episode[index], ns,
        )


@dataclass
class ObjectState:
    """What the skills need to know of an object: from a scene file or from perception."""

    name: str
    type: str  # "cube" | "long"
    position: np.ndarray  # box centre, world frame, metres
    yaw: float = 0.0  # radians about world z
    tilt: float = 0.0  # radians between the box's local z and world z


@dataclass
class SymbolDataset:
    """Symbols before and after each of T transitions: what `learning.readout` reads out of
    a trained model (`symplan symbols` saves it as symbols.npz) and what
    `symbolic.operators` learns operators from.

    Up to N objects per transition, padded to N with `mask` False (padded slots read 0);
    P unary and K relational symbols, relational[t, k, i, j] = r_k(o_i, o_j); bits are 0/1
    (uint8 or bool). Each optional `*_uncertain` array (bool, the shape of its bit array)
    flags the bits read from a logit close to 0; None: none known to be uncertain.
    """

    unary: np.ndarray  # [T, N, P]
    relational: np.ndarray  # [T, K, N, N]
    next_unary: np.ndarray  # [T, N, P], after the action
    next_relational: np.ndarray  # [T, K, N, N]
    action: np.ndarray  # [T, N, ACTION_DIM] float32, see encode_action
    mask: np.ndarray  # [T, N] bool, True for real objects
    unary_uncertain: np.ndarray | None = None
    relational_uncertain: np.ndarray | None = None
    next_unary_uncertain: np.ndarray | None = None
    next_relational_uncertain: np.ndarray | None = None
    contacts: np.ndarray | None = None  # [T, N, N] bool: pairs perceived in contact before
    next_contacts: np.ndarray | None = None  # [T, N, N] bool: after
    degree: np.ndarray | None = None  # [T, N] int: objects of the whole scene each touches
    next_degree: np.ndarray | None = None  # [T, N] int: after

    def __post_init__(self):
        names = self.names()
        for name in names:
            if getattr(self, name) is not None:
                setattr(self, name, np.asarray(getattr(self, name)))
        if self.unary.ndim != 3 or self.relational.ndim != 4 or self.mask.ndim != 2:
            raise ValueError(
                f"expected unary [T,N,P], relational [T,K,N,N], mask [T,N]; got "
                f"{self.unary.shape}, {self.relational.shape}, {self.mask.shape}")
        t, n, p = self.unary.shape
        k = self.relational.shape[1]
        shapes = {"unary": (t, n, p), "relational": (t, k, n, n), "action": (t, n, ACTION_DIM),
                  "mask": (t, n), "contacts": (t, n, n), "degree": (t, n)}
        for name in names:
            value = getattr(self, name)
            expected = shapes[name.removeprefix("next_").removesuffix("_uncertain")]
            if value is not None and value.shape != expected:
                raise ValueError(f"{name} has shape {value.shape}, expected {expected}")

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The array names, required ones first (as stored in symbols.npz)."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray],
                    source: str = "symbolic data set") -> SymbolDataset:
        """From arrays by name (e.g. an opened symbols.npz); ValueError naming `source` and
        the arrays it lacks or has too many."""
        required = [f.name for f in dataclasses.fields(cls)
                    if f.default is dataclasses.MISSING]
        missing = [k for k in required if k not in arrays]
        if missing:
            raise ValueError(f"{source} lacks {missing}; it has {sorted(arrays)}")
        unknown = sorted(set(arrays) - set(cls.names()))
        if unknown:
            raise ValueError(f"{source} has unknown arrays {unknown}; expected {list(cls.names())}")
        try:
            return cls(**{k: arrays[k] for k in arrays})
        except ValueError as e:
            raise ValueError(f"{source}: {e}") from e

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays by name, the absent optional ones left out."""
        return {k: getattr(self, k) for k in self.names() if getattr(self, k) is not None}

    def __getitem__(self, name: str) -> np.ndarray:
        """Read access by name, as for the dict of arrays this class replaced."""
        if name not in self.names() or getattr(self, name) is None:
            raise KeyError(name)
        return getattr(self, name)

    def __len__(self) -> int:
        return self.mask.shape[0]

    @property
    def n_objects(self) -> int:
        return self.mask.shape[1]

    @property
    def n_unary(self) -> int:
        return self.unary.shape[2]

    @property
    def n_relations(self) -> int:
        return self.relational.shape[1]

    def save(self, path: str | Path) -> Path:
        """Writes the arrays to `path` (compressed .npz, exactly that name) atomically."""
        arrays = self.arrays()
        return write_atomic(path, lambda f: np.savez_compressed(f, **arrays))

    @classmethod
    def load(cls, path: str | Path) -> SymbolDataset:
        """A data set saved with `save` (symbols.npz); errors name the file."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no symbols file {path}")
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except (OSError, ValueError, TypeError, EOFError, KeyError, zipfile.BadZipFile,
                zlib.error) as e:  # TypeError: a .npy, not an .npz; the rest: cut short
            raise ValueError(f"cannot read symbols file {path}: "
                             f"{str(e).strip() or type(e).__name__}") from e
        return cls.from_arrays(arrays, f"symbols file {path}")


@dataclass
class SceneSymbols:
    """The symbols of whole perceived scenes around T transitions (every object, not only
    the relevant ones), in identity slots kept through an episode's chain of steps: what
    multi-step problems are made of. M scene slots, `mask` [T, M] marks the real objects."""

    unary: np.ndarray  # [T, M, P] uint8, before the action
    relational: np.ndarray  # [T, K, M, M] uint8
    unary_uncertain: np.ndarray  # bool, like unary
    relational_uncertain: np.ndarray
    next_unary: np.ndarray  # after the action
    next_relational: np.ndarray
    next_unary_uncertain: np.ndarray
    next_relational_uncertain: np.ndarray
    mask: np.ndarray  # [T, M] bool
    contacts: np.ndarray  # [T, M, M] bool, perceived contact pairs before
    next_contacts: np.ndarray  # after
    episode: np.ndarray  # [T] int64
    step: np.ndarray  # [T] step within the episode
    chain: np.ndarray  # [T] identity chain within the episode (see data/exploration.py)
    # The pairs in contact where `contacts` is a wider relevance graph (vicinity): what the
    # degree atoms count; None: `contacts` themselves.
    touching: np.ndarray | None = None
    next_touching: np.ndarray | None = None

    def __len__(self) -> int:
        return self.mask.shape[0]
