"""A model bundle: what solving needs in one directory, the trained symbol model and its
learned operators, and the verbs the closed loop uses (read symbols, write a problem, map a
plan step to an action, predict and check a step's effect).

Layout of a bundle directory (`models/learned/` is the shipped default):

- `model.pt`: the effect model's checkpoint (learning/checkpoint.py format);
- `operators.json`: the operators as atom lists with reliabilities, the learner, its
  settings and the atom semantics (which bits make atoms, see effect_operators.py);
- `domain.pddl` (with `:action-costs`, for Fast Downward) and `domain_strips.pddl` (the
  same actions without costs, for pyperplan);
- `provenance.json`: commands, seeds, data fingerprints and the bundle's measured figures.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from drake_symplan.structs import Action
from drake_symplan.symbolic.effect_operators import (
    EffectOperator,
    Semantics,
    atoms_and_unknown,
    ground_slots,
    key,
)
from drake_symplan.symbolic.pddl import domain_pddl, plan_step_action, problem_from_atoms
from drake_symplan.symbolic.states import Atom, SymbolicState, check_name

FILES = ("model.pt", "operators.json", "domain.pddl", "domain_strips.pddl", "provenance.json")
DEFAULT_MARGIN = 3.0


class BundleError(ValueError):
    """A bundle directory that cannot be used; the message names the directory or file."""


def default_bundle_dir() -> Path:
    """The shipped default model: models/learned/ in the repo (package data when installed)."""
    return Path(str(resources.files("drake_symplan_models"))) / "learned"


@dataclass
class Reading:
    """The symbols of one perceived scene, with the bits read too close to call and the
    pairs perceived in contact."""

    state: SymbolicState
    unary_uncertain: np.ndarray  # [n, P] bool
    relational_uncertain: np.ndarray  # [K, n, n] bool
    contacts: set = field(default_factory=set)  # {(a, b)} perceived in contact

    @property
    def objects(self) -> tuple[str, ...]:
        return self.state.objects

    def contact_matrix(self, pairs=None) -> np.ndarray:
        names = {n: i for i, n in enumerate(self.objects)}
        c = np.zeros((len(names), len(names)), bool)
        for a, b in self.contacts if pairs is None else pairs:
            c[names[a], names[b]] = c[names[b], names[a]] = True
        return c


def planning_operators(operators: list[EffectOperator]) -> list[EffectOperator]:
    """The operators the planner sees: of those with the same preconditions and effects
    (they differ in their offsets only), the cheapest (most reliable; the more frequent on
    a tie). Fewer actions to ground; the agent picks the offsets among all of them when it
    executes a step (agent/refine.py)."""
    best: dict[tuple, EffectOperator] = {}
    for op in operators:  # most frequent first
        key = (op.n_params, frozenset(op.pre), frozenset(op.add), frozenset(op.delete))
        if key not in best or op.cost < best[key].cost:
            best[key] = op
    kept = {id(op) for op in best.values()}
    return [op for op in operators if id(op) in kept]


def operators_to_json(operators: list[EffectOperator], semantics: Semantics, info: dict) -> dict:
    return {"semantics": dataclasses.asdict(semantics),
            **info, "operators": [
                {**op.to_dict(), "pre_slots": [list(a) for a in op.pre],
                 "add_slots": [list(a) for a in op.add],
                 "delete_slots": [list(a) for a in op.delete], "n_params": op.n_params}
                for op in operators]}


def operators_from_json(data: dict) -> tuple[list[EffectOperator], Semantics]:
    ops = []
    for d in data["operators"]:
        def atoms(k):
            return tuple((a[0], *(int(x) for x in a[1:])) for a in d[k])  # noqa: B023

        ops.append(EffectOperator(
            d["index"], d["grasp"], d["release"], d["n_params"], atoms("pre_slots"),
            atoms("add_slots"), atoms("delete_slots"), d["count"], d["applicable"],
            d["succeeded"], data.get("cost_scale", 10.0)))
    return ops, Semantics(**{"degree": False, "guess_uncertain": False, **data["semantics"]})


class ModelBundle:
    """A loaded bundle (see the module docstring)."""

    def __init__(self, path: Path, model, operators: list[EffectOperator], semantics: Semantics,
                 info: dict, provenance: dict, margin: float = DEFAULT_MARGIN):
        self.path, self.model, self.operators = path, model, operators
        self.semantics, self.info, self.provenance, self.margin = (
            semantics, info, provenance, margin)
        self.by_name = {op.name: op for op in operators}
        n_unary, n_rel = info["n_unary"], info["n_relations"]
        planned = planning_operators(operators)
        self.domain = domain_pddl(planned, n_unary, n_rel, costs=True)
        self.domain_strips = domain_pddl(planned, n_unary, n_rel, costs=False)

    @classmethod
    def load(cls, path: str | Path | None = None) -> ModelBundle:
        from drake_symplan.learning.checkpoint import model_from_checkpoint, read_checkpoint

        path = Path(path) if path is not None else default_bundle_dir()
        if not path.is_dir():
            raise BundleError(f"model directory {path} does not exist")
        for name in ("model.pt", "operators.json"):
            if not (path / name).is_file():
                raise BundleError(f"model directory {path} has no {name}")
        try:
            data = json.loads((path / "operators.json").read_text())
            operators, semantics = operators_from_json(data)
            model = model_from_checkpoint(read_checkpoint(path / "model.pt")).eval()
        except (ValueError, KeyError, TypeError, OSError, RuntimeError) as e:
            raise BundleError(f"model directory {path}: cannot read it ({e})") from e
        if not operators:
            raise BundleError(f"model directory {path}: operators.json holds no operators")
        prov = path / "provenance.json"
        provenance = json.loads(prov.read_text()) if prov.is_file() else {}
        info = {k: v for k, v in data.items() if k not in ("operators", "semantics")}
        return cls(path, model, operators, semantics, info, provenance,
                   info.get("margin", DEFAULT_MARGIN))

    # --- symbols ------------------------------------------------------------------

    def read(self, names: list[str], features: np.ndarray, contacts=()) -> Reading:
        """The symbols of a perceived scene: object names, features [n, d_o], contact pairs."""
        from drake_symplan.learning.readout import read_symbols

        names = [check_name(n) for n in names]
        unary, unary_unc, rel, rel_unc = read_symbols(self.model, features, margin=self.margin)
        return Reading(SymbolicState(tuple(names), unary, rel), unary_unc.astype(bool),
                       rel_unc.astype(bool), {tuple(p) for p in contacts})

    def atoms(self, reading: Reading, contacts=None, contacts_only: bool | None = None,
              guess: bool = False) -> tuple[set[Atom], set[tuple]]:
        """(atoms, unknown keys) of a reading under the bundle's semantics; `contacts`
        overrides the reading's contact pairs; with `guess` (a problem's initial state)
        uncertain bits are read by their sign where the semantics says so."""
        s, sem = reading.state, self.semantics
        use_contacts = sem.contacts_only if contacts_only is None else contacts_only
        c = reading.contact_matrix(contacts)
        unc = sem.certain_only and not (guess and sem.guess_uncertain)
        atoms, unknown = atoms_and_unknown(
            s.unary, reading.unary_uncertain if unc else None, s.relational,
            reading.relational_uncertain if unc else None, c if use_contacts else None,
            np.ones(len(s.objects), bool), c.sum(-1) if sem.degree else None)
        names = s.objects
        return ({(a[0], *(names[i] for i in a[1:])) for a in atoms},
                {(k[0], *(names[i] for i in k[1:])) for k in unknown})

    def goal_atoms(self, goal: Reading, goal_contacts=None) -> set[Atom]:
        """Unary atoms, and relation atoms only between objects in contact (paper IV-C)."""
        return self.atoms(goal, goal_contacts, contacts_only=True)[0]

    def problem(self, start: Reading, goal: Reading, goal_contacts=None, name: str = "goal",
                costs: bool = True, objects=None) -> str:
        """The planning problem from `start` to `goal`; `objects` (a subset of the scene's)
        keeps only them and the atoms over them (see `focus`)."""
        if set(start.objects) != set(goal.objects):
            raise ValueError(f"start and goal name different objects: {sorted(start.objects)} "
                             f"vs {sorted(goal.objects)}")
        keep = set(start.objects if objects is None else objects)

        def kept(atoms):
            return sorted(a for a in atoms if set(a[1:]) <= keep)

        return problem_from_atoms([n for n in start.objects if n in keep],
                                  kept(self.atoms(start, guess=True)[0]),
                                  kept(self.goal_atoms(goal, goal_contacts)), name, costs=costs)

    def focus(self, start: Reading, goal: Reading, goal_contacts=None) -> tuple[str, ...]:
        """The objects a plan most likely needs: those in a goal atom that does not hold at
        the start, and the objects in contact with them at the start or in the goal. The
        planner tries these first (as PLOI, Silver et al. 2021, with a rule for the
        score): grounding grows with the cube of the object count."""
        contacts = goal.contacts if goal_contacts is None else goal_contacts
        missing = self.goal_atoms(goal, goal_contacts) - self.atoms(start, guess=True)[0]
        changed = {n for atom in missing for n in atom[1:]}
        pairs = {tuple(p) for p in start.contacts} | {tuple(p) for p in contacts}
        near = {b for a, b in pairs if a in changed} | {a for a, b in pairs if b in changed}
        return tuple(n for n in start.objects if n in changed | near)

    def plan(self, start: Reading, goal: Reading, planner: str = "fd", timeout: float = 10.0,
             goal_contacts=None):
        """Plans from start to goal; a planning.PlanResult. The `focus` objects first; only
        if that proves unsolvable, all of them, in the time left."""
        from drake_symplan.planning.planners import PlanResult, plan_pddl

        t0 = time.perf_counter()
        focus = self.focus(start, goal, goal_contacts)
        if not focus:  # the goal's atoms hold already: the empty plan
            return PlanResult("solved", [], time.perf_counter() - t0, "", planner)
        costs = planner == "fd"  # pyperplan reads no action costs
        domain = self.domain if costs else self.domain_strips
        for objects in ([focus, None] if len(focus) < len(start.objects) else [None]):
            text = self.problem(start, goal, goal_contacts, costs=costs, objects=objects)
            found = plan_pddl(domain, text, planner, max(t0 + timeout - time.perf_counter(),
                                                         1e-3))
            if found.status != "unsolvable":
                break
        found.seconds = time.perf_counter() - t0
        return found

    # --- plan steps ---------------------------------------------------------------

    def action_of(self, step: str) -> Action:
        return plan_step_action(step).action

    def operator_of(self, step: str) -> EffectOperator:
        name = step.strip().strip("()").split()[0].lower()
        if name not in self.by_name:
            raise ValueError(f"plan step {step!r} names no operator of {self.path}")
        return self.by_name[name]

    def expected(self, before: Reading, step: str) -> tuple[list[Atom], list[Atom]]:
        """The (add, delete) atoms the step's operator predicts, grounded on its arguments."""
        op = self.operator_of(step)
        args = plan_step_action(step).args
        return ground_slots(op.add, args), ground_slots(op.delete, args)

    def mismatches(self, after: Reading, step: str, before: Reading | None = None) -> list[Atom]:
        """Predicted atoms that did not come true (an add that is absent, a delete still
        present); bits read as uncertain after the step are no evidence either way."""
        atoms, unknown = self.atoms(after)
        add, delete = self.expected(before if before is not None else after, step)
        missing = [a for a in add if a not in atoms and key(a) not in unknown]
        kept = [a for a in delete if a in atoms]
        return missing + kept

    def reliability(self, plan: list[str]) -> float:
        return float(np.prod([self.operator_of(s).reliability for s in plan])) if plan else 1.0


# --- making a bundle --------------------------------------------------------------------

LEARNERS = ("effect", "paper")


def learn_bundle_operators(data, learner: str = "effect", min_count: int = 10,
                           support: float = 0.95):
    """(operators, semantics, info) learned from a SymbolDataset by `learner`:
    "effect" (effect_operators.py) or "paper" (operators.py, the paper's method as
    implemented, measured under its own semantics: every bit, every pair)."""
    from drake_symplan.symbolic.effect_operators import (
        EFFECT,
        PAPER,
        EffectLearnConfig,
        from_paper,
        learn_effect_operators,
        lift_transitions,
        measure_reliability,
    )
    from drake_symplan.symbolic.operators import LearnConfig, learn_operators

    if learner == "effect":
        result = learn_effect_operators(data, EffectLearnConfig(min_count, support))
        return result.operators, EFFECT, result.summary()
    if learner == "paper":
        result = learn_operators(data, LearnConfig(min_count=min_count))
        operators = [from_paper(op) for op in result.operators]
        measure_reliability(operators, lift_transitions(data, PAPER))
        return operators, PAPER, {"learner": "paper", **result.summary()}
    raise ValueError(f"unknown learner {learner!r}; one of {LEARNERS}")


def write_bundle(out: str | Path, run_dir: str | Path, operators, semantics: Semantics,
                 info: dict, provenance: dict, margin: float = DEFAULT_MARGIN) -> Path:
    """Writes a bundle directory (every file atomically) from a run's best checkpoint."""
    from drake_symplan.learning.checkpoint import BEST, load_run, read_checkpoint, save_checkpoint

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    model, _ = load_run(run_dir)
    ckpt = read_checkpoint(Path(run_dir) / BEST)
    # What rebuilds the model and says where it came from; no optimizer state.
    save_checkpoint(out / "model.pt", {k: ckpt[k] for k in (
        "model", "model_config", "model_state", "epoch", "train_config", "data_fingerprint",
        "metrics") if k in ckpt})
    data = operators_to_json(operators, semantics, {
        **info, "n_unary": model.n_unary, "n_relations": model.n_relations, "margin": margin})
    from drake_symplan.atomic import write_atomic

    write_atomic(out / "operators.json", json.dumps(data, indent=1))
    write_atomic(out / "domain.pddl",
                 domain_pddl(planning_operators(operators), model.n_unary, model.n_relations,
                             costs=True))
    write_atomic(out / "domain_strips.pddl",
                 domain_pddl(planning_operators(operators), model.n_unary, model.n_relations,
                             costs=False))
    write_atomic(out / "provenance.json", json.dumps(provenance, indent=1))
    return out
