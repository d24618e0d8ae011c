"""Symbolic states: the read-out of one scene as arrays over named objects, and as ground facts.

A symbolic state holds P unary bits `p_j(o)` per object and K relational bits
`r_k(o, o')` per ordered pair, as the read-out produces them. Planning needs them as
positive STRIPS facts (paper, III-D): a true bit is the atom `(pJ o)`, a false bit the
atom `(not_pJ o)`; likewise `(rK o o')` / `(not_rK o o')`. The state is closed-world,
so every bit becomes exactly one of the two atoms.

Self-relations r_k(o, o) exist in the read-out but are left out by default everywhere
(operators, problems): a relation learned from pairwise attention says little about an
object with itself, and a noisy self-bit would only split operator groups. Pass
`self_relations=True` to keep them as `(rK o o)` literals.

Atoms are `symbolic.structs.Atom`s, `Atom("p0", "o1")`, `Atom("not_r2", "o1", "o3")`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from drake_symplan.symbolic.structs import Atom

# PDDL names: a letter, then letters, digits, '-' or '_'. Fast Downward lowercases
# everything it reads, so object names are required to be lowercase already; then a
# plan step names the same objects that the problem did.
_NAME = re.compile(r"^[a-z][a-z0-9_-]*$")


def check_name(name: str) -> str:
    """`name` if it is a lowercase PDDL name, else ValueError."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(
            f"{name!r} is not a usable PDDL object name (lowercase letter, then "
            "lowercase letters, digits, '-' or '_')"
        )
    return name


def ordered_pairs(objects, self_relations: bool = False, contacts=None) -> list[tuple]:
    """The ordered pairs (i, j) of the indices `objects`, each object with itself only with
    `self_relations`, only the pairs in contact where `contacts` [n, n] bool is given."""
    return [(i, j) for i in objects for j in objects
            if (self_relations or i != j) and (contacts is None or contacts[i, j])]


def bit_atoms(unary, relational, objects=None, pairs=None, names=None,
              self_relations: bool = False, unary_uncertain=None, relational_uncertain=None
              ) -> tuple[list[tuple], list[tuple]]:
    """(atoms, unknown): a state's bits as closed-world atoms, the one place they are made.

    unary [n, P], relational [K, n, n] bits. For each index i of `objects` (default: all)
    and unary symbol j, `(pJ x)` for a true bit and `(not_pJ x)` for a false one; then for
    each ordered index pair (i, j) of `pairs` (default: `ordered_pairs(objects,
    self_relations)`) and relation k, `(rK x y)` / `(not_rK x y)`; x, y are `names[i]`,
    `names[j]` (default: the indices, as slots). A bit flagged in `unary_uncertain` [n, P]
    or `relational_uncertain` [K, n, n] makes no atom: its key (symbol, args) goes to
    `unknown`. Plain tuples, in that order (an `Atom` compares and hashes alike)."""
    objects = range(len(unary)) if objects is None else objects
    pairs = ordered_pairs(objects, self_relations) if pairs is None else pairs
    names = range(len(unary)) if names is None else names
    out, unknown = [], []
    for i in objects:
        x = names[i]
        for j in range(unary.shape[1]):
            if unary_uncertain is None or not unary_uncertain[i, j]:
                out.append((f"p{j}" if unary[i, j] else f"not_p{j}", x))
            else:
                unknown.append((f"p{j}", x))
    for i, j in pairs:
        x, y = names[i], names[j]
        for k in range(relational.shape[0]):
            if relational_uncertain is None or not relational_uncertain[k, i, j]:
                out.append((f"r{k}" if relational[k, i, j] else f"not_r{k}", x, y))
            else:
                unknown.append((f"r{k}", x, y))
    return out, unknown


def predicate_names(n_unary: int, n_relations: int) -> tuple[list[str], list[str]]:
    """Names of the unary and the binary symbol predicates, both polarities."""
    unary = [name for j in range(n_unary) for name in (f"p{j}", f"not_p{j}")]
    binary = [name for k in range(n_relations) for name in (f"r{k}", f"not_r{k}")]
    return unary, binary


@dataclass(frozen=True)
class SymbolicState:
    """Unary and relational bits of named objects.

    objects: n distinct lowercase names. unary: [n, P] bool. relational: [K, n, n]
    bool with relational[k, i, j] = r_k(objects[i], objects[j]).
    """

    objects: tuple[str, ...]
    unary: np.ndarray
    relational: np.ndarray

    def __post_init__(self):
        objects = tuple(check_name(o) for o in self.objects)
        if len(set(objects)) != len(objects):
            raise ValueError(f"object names are not distinct: {objects}")
        unary = np.asarray(self.unary).astype(bool)
        relational = np.asarray(self.relational).astype(bool)
        n = len(objects)
        if unary.ndim != 2 or unary.shape[0] != n:
            raise ValueError(f"unary has shape {unary.shape}, expected ({n}, P)")
        if relational.ndim != 3 or relational.shape[1:] != (n, n):
            raise ValueError(f"relational has shape {relational.shape}, expected (K, {n}, {n})")
        object.__setattr__(self, "objects", objects)
        object.__setattr__(self, "unary", unary)
        object.__setattr__(self, "relational", relational)

    @classmethod
    def from_arrays(
        cls,
        unary: np.ndarray,
        relational: np.ndarray,
        mask: np.ndarray | None = None,
        names: list[str] | None = None,
    ) -> SymbolicState:
        """From one padded row of a symbolic data set ([N, P], [K, N, N], [N]).

        Keeps the objects where `mask` is True; `names` (one per kept object) default
        to o0, o1, ... in slot order.
        """
        unary = np.asarray(unary)
        relational = np.asarray(relational)
        keep = np.arange(unary.shape[0]) if mask is None else np.flatnonzero(mask)
        if names is None:
            names = [f"o{i}" for i in range(len(keep))]
        if len(names) != len(keep):
            raise ValueError(f"{len(names)} names for {len(keep)} objects")
        return cls(tuple(names), unary[keep], relational[:, keep][:, :, keep])

    @property
    def n_unary(self) -> int:
        return self.unary.shape[1]

    @property
    def n_relations(self) -> int:
        return self.relational.shape[0]

    def index(self, name: str) -> int:
        try:
            return self.objects.index(name)
        except ValueError:
            raise ValueError(f"unknown object {name!r}; objects are {self.objects}") from None

    def facts(self, self_relations: bool = False, pairs=None) -> list[Atom]:
        """The full closed-world state: one atom per bit (`bit_atoms`), relations of the
        index `pairs` only where given."""
        atoms = bit_atoms(self.unary, self.relational, pairs=pairs, names=self.objects,
                          self_relations=self_relations)[0]
        return [Atom.of(a) for a in atoms]

    def goal_facts(
        self, contacts: set[tuple[str, str]] | None, self_relations: bool = False
    ) -> list[Atom]:
        """Goal atoms (paper IV-C): unary atoms of every object, relation atoms only
        for object pairs in contact in the goal scene.

        Contact is symmetric: a pair (a, b) in `contacts` gives the relation atoms of
        both (a, b) and (b, a). With `self_relations`, every object's self-relations
        are part of the goal too. `contacts=None` means every pair (the full state).
        """
        n = len(self.objects)
        if contacts is None:
            return self.facts(self_relations)
        pairs: set[tuple[int, int]] = set()
        for a, b in contacts:
            i, j = self.index(a), self.index(b)
            if i == j:
                raise ValueError(f"object {a!r} is listed in contact with itself")
            pairs.update({(i, j), (j, i)})
        if self_relations:
            pairs.update((i, i) for i in range(n))
        return self.facts(self_relations, sorted(pairs))


def difference_facts(objects: tuple[str, ...] | list[str]) -> list[Atom]:
    """`(different a b)` for every ordered pair of distinct objects.

    Positive STRIPS has no `(not (= ?a ?b))`; these static facts keep the parameters
    of an action bound to distinct objects instead.
    """
    return [Atom("different", a, b) for a in objects for b in objects if a != b]
