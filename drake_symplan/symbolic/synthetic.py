"""A toy symbolic blocks world with known operators: a test and benchmark aid, no part of
the pipeline. tools/bench_operators.py (its synthetic transitions and problems) and the
tests test_symbolic_operators, test_symbolic_pddl, test_planners and
test_planning_grounding use it; nothing in the package does.

Objects are cubes or long blocks (one unary bit, p0 = long). Every object rests on the
table or on one other object, and supports at most one. K = 3 relations:

    r0(a, b): a rests centred on b
    r1(a, b): a rests off-centre on b
    r2(a, b): a supports b (b rests on a, either way)

The action pick(source, grasp) place(target, release) has these outcomes:

* something rests on the source, or on the target: nothing happens;
* a long source grasped off-centre slips with probability `slip` (nothing happens);
* release centre: the source ends centred on the target;
* release off-centre on a cube: the source falls onto the table;
* release off-centre on a long block: the source ends off-centre on it with
  probability 1 - `fall`, else it falls onto the table.

Relevant objects of a transition are the action arguments plus the objects in contact
with them before the action, as in the paper. Outcomes depend only on them, so the
operators learned from enough data are exact for the most likely outcome, and a goal
made by most-likely outcomes is reachable in the learned domain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_symplan.actions import ACTION_DIM, OFFSETS, Action, encode_action
from drake_symplan.datasets import SymbolDataset
from drake_symplan.symbolic.states import SymbolicState

N_UNARY = 1
N_RELATIONS = 3


@dataclass
class World:
    long: np.ndarray  # [n] bool
    below: np.ndarray  # [n] int, support index or -1 for the table
    offcentre: np.ndarray  # [n] bool, resting off-centre on its support

    @property
    def n(self) -> int:
        return len(self.long)

    def copy(self) -> World:
        return World(self.long.copy(), self.below.copy(), self.offcentre.copy())

    def above(self, i: int) -> int:
        on = np.flatnonzero(self.below == i)
        return int(on[0]) if len(on) else -1

    def contacts(self, i: int) -> list[int]:
        return [j for j in (int(self.below[i]), self.above(i)) if j >= 0]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(unary [n, 1], relational [3, n, n]) as uint8."""
        n = self.n
        unary = self.long[:, None].astype(np.uint8)
        rel = np.zeros((N_RELATIONS, n, n), dtype=np.uint8)
        for a in range(n):
            b = int(self.below[a])
            if b >= 0:
                rel[1 if self.offcentre[a] else 0, a, b] = 1
                rel[2, b, a] = 1
        return unary, rel

    def state(self, names: list[str] | None = None) -> SymbolicState:
        unary, rel = self.arrays()
        names = names or [f"o{i}" for i in range(self.n)]
        return SymbolicState(tuple(names), unary, rel)

    def contact_pairs(self, names: list[str] | None = None) -> set[tuple[str, str]]:
        names = names or [f"o{i}" for i in range(self.n)]
        return {(names[a], names[int(b)]) for a, b in enumerate(self.below) if b >= 0}


def random_world(n: int, rng: np.random.Generator) -> World:
    """n objects of random types, stacked at random."""
    world = World(rng.random(n) < 0.5, np.full(n, -1), np.zeros(n, dtype=bool))
    for i in rng.permutation(n):
        clear = [j for j in range(n) if j != i and world.above(j) < 0 and _placed(world, j, i)]
        if clear and rng.random() < 0.5:
            j = int(rng.choice(clear))
            world.below[i] = j
            world.offcentre[i] = bool(world.long[j] and rng.random() < 0.5)
    return world


def _placed(world: World, j: int, i: int) -> bool:
    """j is not above i (so putting i on j makes no cycle)."""
    while j >= 0:
        if j == i:
            return False
        j = int(world.below[j])
    return True


def step(
    world: World,
    action: Action,
    rng: np.random.Generator | None = None,
    slip: float = 0.3,
    fall: float = 0.15,
) -> World:
    """The world after `action` (source/target as 'o<i>'); rng=None: most likely outcome."""
    s, t = int(action.source[1:]), int(action.target[1:])
    out = world.copy()
    if world.above(s) >= 0 or world.above(t) >= 0:
        return out
    if world.long[s] and action.grasp != "center":
        if (rng is None and slip > 0.5) or (rng is not None and rng.random() < slip):
            return out
    if action.release == "center":
        out.below[s], out.offcentre[s] = t, False
    elif not world.long[t]:
        out.below[s], out.offcentre[s] = -1, False
    elif (rng is None and fall < 0.5) or (rng is not None and rng.random() >= fall):
        out.below[s], out.offcentre[s] = t, True
    else:
        out.below[s], out.offcentre[s] = -1, False
    return out


def random_action(world: World, rng: np.random.Generator) -> Action:
    s, t = rng.choice(world.n, size=2, replace=False)
    return Action(f"o{s}", OFFSETS[rng.integers(3)], f"o{t}", OFFSETS[rng.integers(3)])


def relevant(world: World, action: Action) -> list[int]:
    s, t = int(action.source[1:]), int(action.target[1:])
    objs = [s, t]
    for i in world.contacts(s) + world.contacts(t):
        if i not in objs:
            objs.append(i)
    return objs


def random_transitions(
    n_transitions: int,
    seed: int = 0,
    n_objects: tuple[int, int] = (2, 4),
    episode_length: int = 10,
    max_objects: int = 6,
    shuffle_slots: bool = True,
) -> SymbolDataset:
    """A symbolic data set (as read out of a model) from random exploration.

    Episodes start from a random scene with n_objects[0]..n_objects[1] objects; each
    transition keeps the relevant objects, padded to `max_objects` slots (in a random
    slot order when `shuffle_slots`).
    """
    rng = np.random.default_rng(seed)
    n_max = max_objects
    out = _empty_dataset(n_transitions, n_max, N_UNARY, N_RELATIONS)
    for prefix in ("", "next_"):  # perceived contacts: what the effect-first learner reads
        out[f"{prefix}contacts"] = np.zeros((n_transitions, n_max, n_max), bool)
        out[f"{prefix}degree"] = np.zeros((n_transitions, n_max), np.int8)
    world = None
    for i in range(n_transitions):
        if i % episode_length == 0:
            world = random_world(int(rng.integers(n_objects[0], n_objects[1] + 1)), rng)
        action = random_action(world, rng)
        after = step(world, action, rng)
        objs = relevant(world, action)
        if shuffle_slots:
            objs = [objs[j] for j in rng.permutation(len(objs))]
        m = len(objs)
        u, r = world.arrays()
        nu, nr = after.arrays()
        idx = np.array(objs)
        out["unary"][i, :m] = u[idx]
        out["next_unary"][i, :m] = nu[idx]
        out["relational"][i, :, :m, :m] = r[:, idx][:, :, idx]
        out["next_relational"][i, :, :m, :m] = nr[:, idx][:, :, idx]
        out["action"][i, :m] = encode_action(action, [f"o{j}" for j in objs])
        out["mask"][i, :m] = True
        for prefix, w in (("", world), ("next_", after)):
            c = np.zeros((w.n, w.n), bool)
            for a in range(w.n):
                c[a, w.contacts(a)] = True
            c |= c.T
            out[f"{prefix}contacts"][i, :m, :m] = c[idx][:, idx]
            out[f"{prefix}degree"][i, :m] = c.sum(1)[idx]
        world = after
    for key in ("unary", "relational", "next_unary", "next_relational"):
        out[f"{key}_uncertain"] = np.zeros(out[key].shape, bool)
    return SymbolDataset(**out)


def random_problem(
    n: int, n_steps: int, rng: np.random.Generator, max_tries: int = 100
) -> tuple[SymbolicState, SymbolicState, set[tuple[str, str]]]:
    """(start, goal, goal contacts): a random scene and the scene after `n_steps`
    random actions that change something, taken with their most likely outcome.
    Goals that already hold in the start (paper IV-C goal atoms) are redrawn."""
    for _ in range(max_tries):
        start = world = random_world(n, rng)
        steps = 0
        for _ in range(100 * n_steps):
            if steps == n_steps:
                break
            after = step(world, random_action(world, rng))
            if not (np.array_equal(after.below, world.below)
                    and np.array_equal(after.offcentre, world.offcentre)):
                world, steps = after, steps + 1
        goal, contacts = world.state(), world.contact_pairs()
        if not set(goal.goal_facts(contacts)) <= set(start.state().facts()):
            return start.state(), goal, contacts
    raise RuntimeError(f"no non-trivial problem in {max_tries} tries")


@dataclass(frozen=True)
class Row:
    """One hand-written symbolic transition over objects 0..n-1.

    unary: per object, its P bits. rel / next_rel: the true (k, i, j) relation bits.
    action: (source, grasp, target, release) with object indices. next_unary defaults
    to `unary`, next_rel to `rel` (no effect).
    """

    unary: tuple
    rel: frozenset | set
    action: tuple
    next_unary: tuple | None = None
    next_rel: frozenset | set | None = None


def _empty_dataset(t: int, n_max: int, n_unary: int, n_relations: int) -> dict:
    """Zeroed arrays of a `SymbolDataset` of `t` transitions, by name."""
    out = {
        "unary": np.zeros((t, n_max, n_unary), np.uint8),
        "relational": np.zeros((t, n_relations, n_max, n_max), np.uint8),
        "action": np.zeros((t, n_max, ACTION_DIM), np.float32),
        "mask": np.zeros((t, n_max), bool),
    }
    out["next_unary"] = np.zeros_like(out["unary"])
    out["next_relational"] = np.zeros_like(out["relational"])
    return out


def dataset_from_rows(
    rows: list[Row], n_relations: int = N_RELATIONS, max_objects: int | None = None
) -> SymbolDataset:
    """A symbolic data set from hand-written transitions."""
    n_max = max_objects or max(len(r.unary) for r in rows)
    n_unary = len(np.atleast_1d(rows[0].unary[0]))
    out = _empty_dataset(len(rows), n_max, n_unary, n_relations)
    for i, row in enumerate(rows):
        n = len(row.unary)
        out["mask"][i, :n] = True
        out["unary"][i, :n] = np.array(row.unary).reshape(n, n_unary)
        nu = row.unary if row.next_unary is None else row.next_unary
        out["next_unary"][i, :n] = np.array(nu).reshape(n, n_unary)
        for key, rel in (("relational", row.rel),
                         ("next_relational", row.rel if row.next_rel is None else row.next_rel)):
            for k, a, b in rel:
                out[key][i, k, a, b] = 1
        s, g, tg, r = row.action
        names = [f"o{j}" for j in range(n)]
        out["action"][i, :n] = encode_action(Action(names[s], g, names[tg], r), names)
    return SymbolDataset(**out)


def shuffled(data: SymbolDataset, seed: int = 0, slots: bool = True) -> SymbolDataset:
    """The same data set with transitions (and, if `slots`, objects inside each
    transition) in a random order."""
    rng = np.random.default_rng(seed)
    t, n = data.mask.shape
    rows = rng.permutation(t)
    perm = np.array([rng.permutation(n) if slots else np.arange(n) for _ in range(t)])
    out = {}
    for key, arr in data.arrays().items():
        arr = arr[rows]
        if slots and key.startswith(("relational", "next_relational")):
            arr = np.take_along_axis(arr, perm[:, None, :, None], axis=2)
            arr = np.take_along_axis(arr, perm[:, None, None, :], axis=3)
        elif slots and key.startswith(("unary", "next_unary", "action", "mask")):
            arr = np.take_along_axis(arr, perm.reshape((t, n) + (1,) * (arr.ndim - 2)), axis=1)
        out[key] = arr
    return SymbolDataset(**out)
