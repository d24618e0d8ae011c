"""`symplan eval operators`: a learned domain measured at the symbolic level, no arm.

Problems come from held-out episodes (a data set collected with whole scenes, with a seed
the model never saw): start = the symbols of the perceived scene at step t, goal = the
symbols at step t+k (unary atoms, and relation atoms only between objects perceived in
contact then), over steps t..t+k-1 of one identity chain; goals the start already
satisfies are left out. Each problem is solved once, with one domain (never "solved if
any of N sampled domains works"). A found plan's reliability is the product of its
operators' reliabilities.

Beside planning: coverage (held-out transitions whose symbols change and that some
operator of the action applies to) and precision (of those, the share where one of the
applicable operators predicts every atom observed after), and a symbol-stability report.
With the model's training data also determinism: how often a held-out transition's
symbolic effect is the one most often seen in training after the same action in the same
symbols (`determinism`), the bound no operator set over these symbols can beat.
"""

from __future__ import annotations

import time
from collections import Counter, defaultdict
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from functools import cache, partial

import numpy as np

from drake_symplan.abstraction.abstraction import plan_task, reliability
from drake_symplan.actions import OFFSETS
from drake_symplan.atomic import save_figure
from drake_symplan.datasets import SceneSymbols, SymbolDataset
from drake_symplan.learning.readout import readout_scenes
from drake_symplan.planning.planners import DEFAULT_TIMEOUT, WALL_FACTOR
from drake_symplan.shards import fingerprint, load_extra
from drake_symplan.symbolic.effect_operators import (
    EFFECT,
    Semantics,
    changes,
    lift_transitions,
    predicts,
    situation,
    situation_effect,
)
from drake_symplan.symbolic.pddl import domain_pddl
from drake_symplan.symbolic.structs import Atom, LiftedOperator, Task, parse_step


@dataclass(frozen=True)
class EvalConfig:
    ks: tuple[int, ...] = (1, 2, 3)
    planner: str = "fd"
    timeout: float = DEFAULT_TIMEOUT
    max_problems: int = 50  # per (k, object count), sampled with `seed`
    seed: int = 0
    workers: int = 2  # planner calls in parallel


MIN_SEEN = (1, 2, 5, 10, 20, 50)  # the selective scores' thresholds


@dataclass
class Problem:
    k: int
    n_objects: int
    task: Task


def scene_atoms(scenes: SceneSymbols, row: int, after: bool, semantics: Semantics,
                names: dict[int, str], contacts_only: bool | None = None,
                guess: bool = False) -> list:
    """Named atoms of a whole scene (before or after the action of `row`); with `guess`,
    uncertain bits read by their sign (a problem's initial state)."""
    p = "next_" if after else ""
    whole = getattr(scenes, f"{p}contacts")[row]
    atoms, _ = semantics.read(
        getattr(scenes, f"{p}unary")[row], getattr(scenes, f"{p}unary_uncertain")[row],
        getattr(scenes, f"{p}relational")[row], getattr(scenes, f"{p}relational_uncertain")[row],
        whole, scenes.mask[row], guess=guess, contacts_only=contacts_only)
    return sorted(Atom(a[0], *(names[s] for s in a[1:])) for a in atoms)


def heldout_problems(scenes: SceneSymbols, semantics: Semantics, config: EvalConfig
                  ) -> list[Problem]:
    """Non-trivial k-step problems from the chains of the held-out scenes (module doc)."""
    rng = np.random.default_rng(config.seed)
    index = {(int(e), int(c), int(s)): i for i, (e, c, s) in
             enumerate(zip(scenes.episode, scenes.chain, scenes.step, strict=True))}
    problems = []
    for k in config.ks:
        cells: dict[int, list[Problem]] = defaultdict(list)
        for (e, c, s), i in index.items():
            rows = [index.get((e, c, s + d)) for d in range(k)]
            if any(r is None for r in rows):
                continue
            j = rows[-1]
            slots = np.flatnonzero(scenes.mask[i])
            names = {int(x): f"o{x}" for x in slots}
            init = scene_atoms(scenes, i, False, semantics, names, guess=True)
            # Goal: unary atoms, relations only between objects in contact (paper IV-C).
            goal = scene_atoms(scenes, j, True, semantics, names, contacts_only=True)
            if set(goal) <= set(init):
                continue
            task = Task(tuple(names.values()), frozenset(init), frozenset(goal))
            cells[len(slots)].append(Problem(k, len(slots), task))
        for n in sorted(cells):
            chosen = rng.permutation(len(cells[n]))[:config.max_problems]
            problems += [cells[n][i] for i in sorted(chosen)]
    return problems


def solve_problems(operators: list[LiftedOperator], n_unary: int, n_relations: int,
                   problems: list[Problem], config: EvalConfig) -> list[dict]:
    """Plans every problem with the domain of `operators` for its object count
    (pddl.domain_pddl's `n_objects`); one result dict per problem."""
    by_name = {op.name: op for op in operators}

    @cache  # the PDDL path's domain text, once per object count
    def domain(n: int) -> str:
        return domain_pddl(operators, n_unary, n_relations, costs=config.planner == "fd",
                           n_objects=n)

    def one(p: Problem) -> dict:
        # CPU seconds, so that a problem gets the same answer on a busy host as on a quiet one
        r = plan_task(operators, partial(domain, p.n_objects), p.task, config.planner,
                      WALL_FACTOR * config.timeout, cpu_seconds=config.timeout)
        steps = [parse_step(s, by_name) for s in r.plan]
        return {"k": p.k, "objects": p.n_objects, "status": r.status, "length": len(r.plan),
                "seconds": r.seconds, "reliability": reliability(steps) if r.solved else 0.0}

    with ThreadPoolExecutor(max(1, config.workers)) as pool:
        return list(pool.map(one, problems))


def prediction_scores(operators: list[LiftedOperator], data: SymbolDataset,
                      semantics: Semantics = EFFECT, familiar: Counter | None = None,
                      min_seen: tuple[int, ...] = MIN_SEEN) -> dict:
    """Coverage and precision on the transitions whose symbols change (module doc), and
    `precision_top1`: the share where the most reliable applicable operator alone predicts
    it (the outcomes are many: `alternatives` is the median count of applicable operators).
    With `familiar` (counts of the training transitions' situations) also `selective`: the
    same where the situation was seen at least N times, N in `min_seen`."""
    by_action = defaultdict(list)
    for op in operators:
        by_action[(op.grasp, op.release)].append(op)
    rows = []  # (applicable operators, any predicts, the most reliable predicts, seen)
    for tr in lift_transitions(data, semantics):
        add, delete = changes(tr.before, tr.after, tr.unknown_before, tr.unknown_after)
        if not add and not delete:
            continue
        verdicts = [(op.reliability, v) for op in by_action[(OFFSETS[tr.grasp],
                    OFFSETS[tr.release])] if (v := predicts(op, tr)) is not None]
        top = max(verdicts, key=lambda rv: rv[0])[1] if verdicts else False
        seen = familiar[situation(tr)] if familiar is not None else 0
        rows.append((len(verdicts), any(v for _, v in verdicts), top, seen))
    out = {"changed": len(rows), **_scores(rows, 0)}
    if familiar is not None:
        out["selective"] = [{"min_seen": n, **_scores(rows, n)} for n in min_seen]
    return out


def _scores(rows: list[tuple], min_seen: int) -> dict:
    covered = [r for r in rows if r[0] and r[3] >= min_seen]
    n = len(covered)
    return {"coverage": n / len(rows) if rows else 0.0,
            "precision": sum(r[1] for r in covered) / n if n else 0.0,
            "precision_top1": sum(r[2] for r in covered) / n if n else 0.0,
            "alternatives": float(np.median([r[0] for r in covered])) if n else 0.0}


def familiarity(data: SymbolDataset, semantics: Semantics = EFFECT) -> Counter:
    """How often each situation occurs among a data set's transitions (its training data
    for a learned domain): how well the learner has seen what a held-out scene meets."""
    return Counter(situation(tr) for tr in lift_transitions(data, semantics))


def determinism(train: SymbolDataset, heldout: SymbolDataset,
                semantics: Semantics = EFFECT, examples: int = 5) -> dict:
    """Of the held-out transitions whose symbols change, the share whose symbolic effect is
    the most frequent one in the training data for their situation (action and atoms
    before, whatever the objects are named; an unseen situation counts as a miss);
    `determinism_seen` the same over seen situations, `seen` their share,
    `branching_situations` the share of the training situations (seen twice or more) with
    more than one effect, and `branching`: the `examples` situations with the most
    held-out misses, each with its training effects, counts and a held-out example."""
    counts: dict[tuple, Counter] = defaultdict(Counter)
    for tr in lift_transitions(train, semantics):
        where, effect = situation_effect(tr)
        counts[where][effect] += 1
    likely = {where: c.most_common(1)[0][0] for where, c in counts.items()}
    hits = seen = changed = 0
    missed: dict[tuple, list[int]] = defaultdict(list)
    for row, tr in enumerate(lift_transitions(heldout, semantics)):
        add, delete = changes(tr.before, tr.after, tr.unknown_before, tr.unknown_after)
        if not add and not delete:
            continue
        changed += 1
        where, effect = situation_effect(tr)
        if where in likely:
            seen += 1
            hits += likely[where] == effect
            if likely[where] != effect:
                missed[where].append(row)
    repeated = [c for c in counts.values() if sum(c.values()) >= 2]
    worst = sorted(missed, key=lambda w: -len(missed[w]))[:examples]
    return {"changed": changed, "determinism": hits / changed if changed else 0.0,
            "determinism_seen": hits / seen if seen else 0.0,
            "seen": seen / changed if changed else 0.0,
            "branching_situations": (sum(len(c) > 1 for c in repeated) / len(repeated)
                                     if repeated else 0.0),
            "branching": [_branching(w, counts[w], missed[w]) for w in worst]}


def _branching(where: tuple, effects: Counter, rows: list[int]) -> dict:
    """One situation whose held-out effects depart from its most frequent one."""
    def atoms(xs):
        return [" ".join((a[0], *(f"?o{s}" for s in a[1:]))) for a in xs]

    grasp, release, n, pre = where
    return {"action": f"pick {OFFSETS[grasp]} place {OFFSETS[release]}", "objects": n,
            "before": atoms(pre), "heldout_misses": len(rows), "example_row": rows[0],
            "outcomes": [{"add": atoms(add), "delete": atoms(delete), "count": c}
                         for (add, delete), c in effects.most_common(4)]}


def stability(data: SymbolDataset, outcome: np.ndarray | None,
              semantics: Semantics = EFFECT) -> dict:
    """Share of uncertain bits; within groups of equal action and preconditions, how often
    the most frequent symbolic effect (and physical outcome class) occurs."""
    mask = data.mask.astype(bool)
    out = {"uncertain_unary": float(data.unary_uncertain[mask].mean())
           if data.unary_uncertain is not None else 0.0}
    if data.n_relations and data.relational_uncertain is not None and data.contacts is not None:
        touching = data.contacts[:, None] & np.ones(data.n_relations, bool)[None, :, None, None]
        vals = data.relational_uncertain[touching]
        out["uncertain_relational_in_contact"] = float(vals.mean()) if vals.size else 0.0
    groups: dict[tuple, list] = defaultdict(list)
    for t, tr in enumerate(lift_transitions(data, semantics)):
        add, delete = changes(tr.before, tr.after, tr.unknown_before, tr.unknown_after)
        m = tr.bindings[max(tr.bindings, key=len)]
        pre = frozenset((a[0], *(m[s] for s in a[1:])) for a in tr.before)
        effect = (frozenset((a[0], *(m[s] for s in a[1:])) for a in add),
                  frozenset((a[0], *(m[s] for s in a[1:])) for a in delete))
        cls = int(outcome[t]) if outcome is not None else 0
        groups[(tr.grasp, tr.release, tr.n, pre)].append((effect, cls))
    top_effect = top_class = total = 0
    for members in groups.values():
        if len(members) < 2:
            continue
        total += len(members)
        top_effect += Counter(e for e, _ in members).most_common(1)[0][1]
        top_class += Counter(c for _, c in members).most_common(1)[0][1]
    out["effect_consistency"] = top_effect / total if total else 0.0
    if outcome is not None:
        out["outcome_consistency"] = top_class / total if total else 0.0
    return out


def summarise(results: list[dict]) -> dict:
    """`by_k` and `by_objects` tables: solved fraction, problems, mean plan length, median
    planning seconds, mean reliability over solved problems."""
    def table(key):
        cells = defaultdict(list)
        for r in results:
            cells[str(r[key])].append(r)
        return {c: _cell(rs) for c, rs in sorted(cells.items(), key=lambda kv: int(kv[0]))}

    by_both = defaultdict(list)
    for r in results:
        by_both[f"{r['k']}/{r['objects']}"].append(r)
    return {"by_k": table("k"), "by_objects": table("objects"),
            "by_k_objects": {c: _cell(rs) for c, rs in sorted(by_both.items())},
            "overall": _cell(results)}


def _cell(rs: list[dict]) -> dict:
    solved = [r for r in rs if r["status"] == "solved"]
    return {"problems": len(rs), "solved": len(solved) / len(rs) if rs else 0.0,
            "reliability": float(np.mean([r["reliability"] for r in solved])) if solved else 0.0,
            "plan_length": float(np.mean([r["length"] for r in solved])) if solved else 0.0,
            "seconds_median": float(np.median([r["seconds"] for r in rs])) if rs else 0.0,
            "statuses": dict(Counter(r["status"] for r in rs))}


def evaluate_operators(operators: list[LiftedOperator], n_unary: int, n_relations: int,
                       heldout: SymbolDataset, scenes: SceneSymbols,
                       outcome: np.ndarray | None, semantics: Semantics,
                       config: EvalConfig, familiar: Counter | None = None) -> dict:
    """The whole report: planning tables, coverage/precision (merged into each by_k cell,
    where they do not depend on k; selective with `familiar`) and stability."""
    t0 = time.perf_counter()
    problems = heldout_problems(scenes, semantics, config)
    results = solve_problems(operators, n_unary, n_relations, problems, config)
    report = summarise(results)
    scores = prediction_scores(operators, heldout, semantics, familiar)
    for cell in report["by_k"].values():
        cell.update(coverage=scores["coverage"], precision=scores["precision"])
    report.update(scores, operators=len(operators), stability=stability(
        heldout, outcome, semantics), seconds=round(time.perf_counter() - t0, 2))
    return report


def evaluate_bundle(bundle, data_dir, config: EvalConfig, familiar_data=None) -> dict:
    """`evaluate_operators` for a loaded ModelBundle on a held-out data set directory;
    `familiar_data`: its training data (selective scores)."""
    heldout, scenes = readout_scenes(bundle.model, data_dir, bundle.margin)
    familiar = train = None
    if familiar_data is not None:
        train = readout_scenes(bundle.model, familiar_data, bundle.margin)[0]
        familiar = familiarity(train, bundle.semantics)
    report = evaluate_operators(bundle.operators, bundle.info["n_unary"],
                                bundle.info["n_relations"], heldout, scenes,
                                load_extra(data_dir, "outcome"), bundle.semantics, config,
                                familiar)
    if train is not None:
        report.update(determinism(train, heldout, bundle.semantics))
    report.update(model=str(bundle.path), data=str(data_dir), data_fingerprint=fingerprint(
        data_dir), learner=bundle.info.get("learner"), config=asdict(config))
    if familiar_data is not None:
        report.update(familiar_data=str(familiar_data),
                      familiar_fingerprint=fingerprint(familiar_data))
    return report


def plot_report(report: dict, path) -> None:
    """Solved rate and mean plan reliability by k, one line per object count."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    cells = defaultdict(dict)
    for key_, cell in report["by_k_objects"].items():
        k, n = (int(x) for x in key_.split("/"))
        cells[n][k] = cell
    for n, by_k in sorted(cells.items()):
        ks = sorted(by_k)
        axes[0].plot(ks, [by_k[k]["solved"] for k in ks], "o-", label=f"{n} objects")
        axes[1].plot(ks, [by_k[k]["reliability"] for k in ks], "o-", label=f"{n} objects")
    for ax, title in zip(axes, ("solved", "mean plan reliability (solved)"), strict=True):
        ax.set(xlabel="k (actions between start and goal)", title=title, ylim=(0, 1.05))
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle(f"{report.get('learner')} operators: coverage {report['coverage']:.2f}, "
                 f"precision {report['precision']:.2f}")
    fig.tight_layout()
    save_figure(fig, path)
