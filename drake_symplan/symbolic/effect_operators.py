"""Effect-first operator learning: group transitions by what changed, intersect preconditions,
and measure each operator's reliability on every transition it applies to.

A transition's symbolic state is a set of atoms over its objects (slots): `(pJ o)` /
`(not_pJ o)` for every *certain* unary bit, and `(rK o o')` / `(not_rK o o')` for the
certain relation bits of the pairs perceived *in contact* only (the paper keeps goal
relations only between touching objects; here preconditions and effects do the same, so a
relation between two boxes apart never splits or blocks an operator). A bit read close
to its logit's zero is uncertain and makes no atom at all.

Learning (after predicators' cluster-and-intersect): transitions are lifted with `?o0` the
source, `?o1` the target and `?o2`... the other relevant objects (in the order that gives
the smallest effect, then preconditions), grouped by (grasp, release, objects, effect),
and a group's preconditions are the atoms present in at least `support` of its
transitions. Every group seen `min_count` times becomes an operator; one grounded action
may thus have several operators, one per outcome. An operator's reliability is how often
its effect followed among all training transitions where its preconditions held for its
action (any binding of its parameters): the planner's cost, -log of it, makes plans prefer
reliable outcomes. Operators whose effect is empty (the action did nothing symbolic) are
not written to the domain but stay alternatives in the reliabilities of the others.
"""

from __future__ import annotations

import itertools
import time
from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

from drake_symplan.actions import OFFSETS
from drake_symplan.datasets import SymbolDataset
from drake_symplan.symbolic.operators import action_roles
from drake_symplan.symbolic.states import bit_atoms, ordered_pairs
from drake_symplan.symbolic.structs import LiftedOperator
from drake_symplan.symbolic.structs import bit_key as key

MAX_DEGREE = 3  # contact degrees above this read as this

# A slot atom: (predicate, object slot[, object slot]); lifted, the slots are parameter
# indices (?o0 = 0). Kept as small int tuples until written out.
SlotAtom = tuple


@dataclass(frozen=True)
class EffectLearnConfig:
    """min_count: transitions a (action, effect) group needs to become an operator.
    support: share of a group's transitions an atom must hold in to be a precondition.
    cost_scale: an operator's plan cost is 1 + round(cost_scale * -ln(reliability))."""

    min_count: int = 10
    support: float = 0.95
    cost_scale: float = 10.0
    absorb: bool = True  # rare effects that are a frequent one seen through uncertain bits

    def __post_init__(self):
        if self.min_count < 1:
            raise ValueError(f"min_count must be >= 1, got {self.min_count}")
        if not 0.5 < self.support <= 1.0:
            raise ValueError(f"support must be in (0.5, 1], got {self.support}")


@dataclass
class EffectOperatorSet:
    operators: list[LiftedOperator]  # the domain's: non-empty effect, most frequent first
    n_unary: int
    n_relations: int
    n_transitions: int
    n_groups: int
    config: EffectLearnConfig
    seconds: float = 0.0
    timings: dict = field(default_factory=dict)

    def summary(self) -> dict:
        rel = [op.reliability for op in self.operators]
        return {
            "learner": "effect", "operators": len(self.operators), "groups": self.n_groups,
            "transitions": self.n_transitions, "min_count": self.config.min_count,
            "support": self.config.support,
            "mean_reliability": float(np.mean(rel)) if rel else 0.0,
            "seconds": round(self.seconds, 3), "timings": self.timings,
        }


# ---------------------------------------------------------------- states as atom sets


def degree_atom(n: int) -> str:
    """`touching0` .. `touching3` (3 or more): how many objects an object touches."""
    return f"touching{min(int(n), MAX_DEGREE)}"


def atoms_and_unknown(unary, unary_unc, rel, rel_unc, contacts, real, degree=None):
    """(atoms, unknown): the certain atoms (states.bit_atoms over the real slots, relations
    of the pairs in contact) and the keys (symbol, slots) of the uncertain bits."""
    slots = np.flatnonzero(real)
    out, unknown = bit_atoms(unary, rel, slots, ordered_pairs(slots, contacts=contacts),
                             unary_uncertain=unary_unc, relational_uncertain=rel_unc)
    if degree is not None:
        out += [(degree_atom(degree[i]), int(i)) for i in slots]
    return frozenset(out), frozenset(unknown)


def changes(before: frozenset, after: frozenset, unknown_before: frozenset,
            unknown_after: frozenset) -> tuple[frozenset, frozenset]:
    """(add, delete) between two atom sets; a bit that was uncertain on the other side is no
    change (it may have held all along), a relation whose contact ended is deleted."""
    add = frozenset(a for a in after - before if key(a) not in unknown_before)
    delete = frozenset(a for a in before - after if key(a) not in unknown_after)
    return add, delete


def _rename(atoms, mapping: dict[int, int]) -> frozenset:
    """Atoms with slots renamed by `mapping`; atoms naming an unmapped slot are dropped."""
    out = []
    for a in atoms:
        if all(s in mapping for s in a[1:]):
            out.append((a[0], *(mapping[s] for s in a[1:])))
    return frozenset(out)


@dataclass
class Lifted:
    """One transition seen from the roles: its atom sets per binding of the other objects."""

    grasp: int
    release: int
    n: int  # relevant objects
    before: frozenset  # slot atoms
    after: frozenset
    unknown_before: frozenset  # keys of uncertain bits
    unknown_after: frozenset
    bindings: dict  # tuple of other slots (in parameter order) -> slot -> parameter map
    read_before: frozenset = frozenset()  # `before`, uncertain bits read by their sign
    _views: dict = field(default_factory=dict, repr=False)

    def view(self, sel: tuple) -> tuple[frozenset, frozenset, frozenset]:
        """(read_before, after, unknown_after) lifted by the binding `sel`, computed once:
        reliability checks every operator of an action against every transition."""
        if sel not in self._views:
            m = self.bindings[sel]
            self._views[sel] = (_rename(self.read_before, m), _rename(self.after, m),
                                _rename(self.unknown_after, m))
        return self._views[sel]


@dataclass(frozen=True)
class Semantics:
    """Which bits make atoms. The learner here: certain bits, relations between objects in
    contact, and each object's contact degree (`touchingN`: it touches N objects of the
    scene, 3 meaning 3 or more), the perceived fact that positive STRIPS otherwise cannot
    state: "and nothing else touches ?o0". The paper's operators as implemented (`PAPER`):
    every bit, every pair."""

    certain_only: bool = True
    contacts_only: bool = True
    degree: bool = True
    # Whether an operator applies (and a problem's initial state) reads an uncertain bit
    # by its sign, its most likely value; preconditions, effects and goals stay certain.
    guess_uncertain: bool = True


    def read(self, unary, unary_unc, rel, rel_unc, contacts, real=None, guess: bool = False,
             contacts_only: bool | None = None, degree=None) -> tuple[frozenset, frozenset]:
        """(atoms, unknown keys) of one scene's symbols over slots under these semantics:
        unary [N, P], rel [K, N, N] and their uncertainty flags, contacts [N, N] bool (the
        whole scene's: the degrees count them), real [N] (None: all). With `guess` (a
        problem's initial state) uncertain bits are read by their sign where
        `guess_uncertain` says so; `contacts_only` overrides the relation rule (goals:
        only pairs in contact); `degree` [N], the contact counts where the relevance graph
        is wider than contact (None: the counts of `contacts`)."""
        certain = self.certain_only and not (guess and self.guess_uncertain)
        only = self.contacts_only if contacts_only is None else contacts_only
        real = np.ones(len(unary), bool) if real is None else real
        return atoms_and_unknown(unary, unary_unc if certain else None, rel,
                                 rel_unc if certain else None, contacts if only else None,
                                 real, (contacts.sum(-1) if degree is None else degree)
                                 if self.degree else None)


EFFECT = Semantics()
PAPER = Semantics(certain_only=False, contacts_only=False, degree=False, guess_uncertain=False)


def lift_transitions(data: SymbolDataset, semantics: Semantics = EFFECT) -> list[Lifted]:
    """Every transition's slot atom sets and role bindings."""
    if semantics.contacts_only and (data.contacts is None or data.next_contacts is None):
        raise ValueError("operators over contacts need the perceived contacts of each "
                         "transition (a data set collected with whole scenes)")
    if semantics.degree and (data.degree is None or data.next_degree is None):
        raise ValueError("contact-degree atoms need each object's contact count in its whole "
                         "scene (a data set collected with whole scenes)")
    mask = data.mask.astype(bool)
    src, tgt, grasp, release = action_roles(data.action, mask)
    out = []
    for t in range(len(data)):
        unc = [None if a is None or not semantics.certain_only else a[t] for a in (
            data.unary_uncertain, data.relational_uncertain,
            data.next_unary_uncertain, data.next_relational_uncertain)]
        c0, c1 = ((data.contacts[t], data.next_contacts[t]) if semantics.contacts_only
                  else (None, None))
        d0, d1 = ((data.degree[t], data.next_degree[t]) if semantics.degree else (None, None))
        before, unknown_before = atoms_and_unknown(
            data.unary[t], unc[0], data.relational[t], unc[1], c0, mask[t], d0)
        after, unknown_after = atoms_and_unknown(
            data.next_unary[t], unc[2], data.next_relational[t], unc[3], c1, mask[t], d1)
        s, g = int(src[t]), int(tgt[t])
        others = [int(i) for i in np.flatnonzero(mask[t]) if i not in (s, g)]
        bindings = {}
        for r in range(len(others) + 1):
            for sel in itertools.permutations(others, r):
                bindings[sel] = {s: 0, g: 1, **{o: 2 + i for i, o in enumerate(sel)}}
        read_before = before
        if semantics.guess_uncertain:
            read_before = atoms_and_unknown(data.unary[t], None, data.relational[t], None, c0,
                                             mask[t], d0)[0]
        out.append(Lifted(int(grasp[t]), int(release[t]), int(mask[t].sum()), before, after,
                          unknown_before, unknown_after, bindings, read_before))
    return out


def _sorted(atoms) -> tuple:
    return tuple(sorted(atoms, key=lambda a: (a[0], a[1:])))


def _canonical(tr: Lifted) -> tuple[tuple, tuple, tuple, frozenset]:
    """(add, delete, pre, unknown keys before or after) lifted with all objects as
    parameters, in the order of the other objects that gives the smallest (effect,
    preconditions)."""
    best = None
    full = [sel for sel in tr.bindings if len(sel) == tr.n - 2]
    for sel in full:
        m = tr.bindings[sel]
        add, delete = changes(*(_rename(x, m) for x in (
            tr.before, tr.after, tr.unknown_before, tr.unknown_after)))
        candidate = (_sorted(add), _sorted(delete), _sorted(_rename(tr.before, m)),
                     _rename(tr.unknown_before | tr.unknown_after, m))
        if best is None or candidate[:3] < best[:3]:
            best = candidate
    return best


def situation(tr: Lifted) -> tuple:
    """What the action met, whatever its objects are named: (grasp, release, objects, atoms
    before as operators read them) in the order of the other objects that gives the
    smallest atoms. Transitions in one situation differ only in what followed."""
    pre = min(_sorted(_rename(tr.read_before, tr.bindings[sel]))
              for sel in tr.bindings if len(sel) == tr.n - 2)
    return tr.grasp, tr.release, tr.n, pre


def situation_effect(tr: Lifted) -> tuple[tuple, tuple]:
    """(situation, symbolic effect (add, delete)) named by the same binding: of the
    orderings of the other objects that give the situation's atoms, the one giving the
    smallest effect, so two transitions that differ only in names get equal keys."""
    where = situation(tr)
    effects = []
    for sel, m in tr.bindings.items():
        if len(sel) == tr.n - 2 and _sorted(_rename(tr.read_before, m)) == where[3]:
            add, delete = changes(*(_rename(x, m) for x in (
                tr.before, tr.after, tr.unknown_before, tr.unknown_after)))
            effects.append((_sorted(add), _sorted(delete)))
    return where, min(effects)


def _compatible(add, delete, unknown, group_add, group_delete) -> bool:
    """Whether a transition's effect is the group's, but for bits it could not read: every
    change it saw is the group's, and every change of the group it lacks is on a bit that
    was uncertain before or after."""
    if not (set(add) <= set(group_add) and set(delete) <= set(group_delete)):
        return False
    missing = (set(group_add) - set(add)) | (set(group_delete) - set(delete))
    return all(key(a) in unknown for a in missing)


# ---------------------------------------------------------------- learning


def learn_effect_operators(data: SymbolDataset, config: EffectLearnConfig | None = None,
                           lifted: list[Lifted] | None = None,
                           semantics: Semantics = EFFECT) -> EffectOperatorSet:
    """Effect-first operators of a symbolic data set with contacts (module docstring), its
    states read under `semantics` (unless `lifted` gives them already)."""
    config = config or EffectLearnConfig()
    t0 = time.perf_counter()
    lifted = lifted if lifted is not None else lift_transitions(data, semantics)
    if not lifted:
        raise ValueError("no transitions to learn operators from")
    t1 = time.perf_counter()
    groups: dict[tuple, list[tuple]] = defaultdict(list)
    for tr in lifted:
        add, delete, pre, unknown = _canonical(tr)
        groups[(tr.grasp, tr.release, tr.n, add, delete)].append((pre, unknown))
    t2 = time.perf_counter()
    kept = sorted(((k, v) for k, v in groups.items() if len(v) >= config.min_count),
                  key=lambda kv: (-len(kv[1]), kv[0]))
    if config.absorb:
        # A transition of a rare effect that is a frequent effect seen through uncertain
        # bits counts for the frequent one (the largest such group).
        by_head = defaultdict(list)
        for k, members in kept:
            by_head[k[:3]].append((k, members))
        for k, members in groups.items():
            if len(members) >= config.min_count:
                continue
            for (_, _, _, g_add, g_del), target in by_head.get(k[:3], ()):
                extra = [m for m in members if _compatible(k[3], k[4], m[1], g_add, g_del)]
                if extra:
                    target.extend(extra)
                    break
        kept.sort(key=lambda kv: (-len(kv[1]), kv[0]))
    candidates = []
    for (g, r, n, add, delete), members in kept:
        counts: dict = defaultdict(int)
        for pre, _ in members:
            for a in pre:
                counts[a] += 1
        # An atom's support counts the members that could read its bit.
        pre = _sorted(a for a, c in counts.items() if c >= config.support * sum(
            key(a) not in unknown for _, unknown in members))
        candidates.append(LiftedOperator(0, OFFSETS[g], OFFSETS[r], n, pre, add, delete,
                                         len(members), cost_scale=config.cost_scale))
    measure_reliability(candidates, lifted)
    t3 = time.perf_counter()
    operators = [op for op in candidates if op.add or op.delete]
    for rank, op in enumerate(operators):
        op.index = rank
    return EffectOperatorSet(
        operators, data.n_unary, data.n_relations, len(lifted), len(groups), config,
        seconds=t3 - t0,
        timings={"lift": round(t1 - t0, 3), "group": round(t2 - t1, 3),
                 "reliability": round(t3 - t2, 3)})


def by_action(lifted: list[Lifted]) -> dict[tuple, list[Lifted]]:
    """The transitions by their action, (grasp, release) as OFFSETS indices."""
    out: dict[tuple, list[Lifted]] = defaultdict(list)
    for tr in lifted:
        out[(tr.grasp, tr.release)].append(tr)
    return out


def action_of(op: LiftedOperator) -> tuple[int, int]:
    """The operator's action as `by_action` keys it."""
    return OFFSETS.index(op.grasp), OFFSETS.index(op.release)


def counted(op: LiftedOperator, transitions: list[Lifted]) -> tuple[int, int]:
    """(transitions where `op` applies, those where its effect followed)."""
    applicable = succeeded = 0
    for tr in transitions:
        verdict = follows(op, tr)
        if verdict is not None:
            applicable += 1
            succeeded += verdict
    return applicable, succeeded


def measure_reliability(operators: list[LiftedOperator], lifted: list[Lifted]) -> None:
    """Sets each operator's `applicable` and `succeeded` counts on the transitions."""
    actions = by_action(lifted)
    for op in operators:
        op.applicable, op.succeeded = counted(op, actions.get(action_of(op), []))


def _grounded(op: LiftedOperator, tr: Lifted):
    """For each binding of the operator's parameters to the transition's objects under
    which its preconditions hold: the lifted (after, unknown after) sets."""
    pre = frozenset(op.pre)
    for sel in tr.bindings:
        if len(sel) != op.n_params - 2:
            continue
        before, after, unknown = tr.view(sel)
        if pre <= before:
            yield after, unknown


def follows(op: LiftedOperator, tr: Lifted) -> bool | None:
    """None if the operator does not apply to the transition (action or preconditions);
    else whether its effect followed for some binding: every add holds after (or its bit
    is uncertain there) and no delete does."""
    if (OFFSETS.index(op.grasp), OFFSETS.index(op.release)) != (tr.grasp, tr.release):
        return None
    applied = False
    for after, unknown in _grounded(op, tr):
        applied = True
        if all(a in after or key(a) in unknown for a in op.add) and \
                not any(a in after for a in op.delete):
            return True
    return False if applied else None


def predicts(op: LiftedOperator, tr: Lifted) -> bool | None:
    """None if the operator does not apply; else whether its predicted next state holds
    every atom observed after (the goal's atoms) for some binding."""
    if (OFFSETS.index(op.grasp), OFFSETS.index(op.release)) != (tr.grasp, tr.release):
        return None
    add, delete = frozenset(op.add), frozenset(op.delete)
    applied = False
    for sel, m in tr.bindings.items():
        if len(sel) != op.n_params - 2:
            continue
        if not frozenset(op.pre) <= _rename(tr.read_before, m):
            continue
        applied = True
        # Atoms of objects that are not parameters must carry over unchanged.
        everyone = {**m, **{s: 100 + s for s in _slots(tr) if s not in m}}
        if (_rename(tr.after, everyone) - add) <= (_rename(tr.read_before, everyone) - delete):
            return True
    return False if applied else None


def _slots(tr: Lifted) -> set[int]:
    return {s for a in tr.read_before | tr.before | tr.after for s in a[1:]}
