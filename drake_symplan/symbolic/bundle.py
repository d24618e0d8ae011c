"""A model bundle: what planning needs in one directory, as data (load, save, learn).

Layout of a bundle directory (`models/learned/` is the shipped default):

- `model.pt`: the effect model's checkpoint (learning/checkpoint.py format), or the
  hand-made symbols' (learning/handmade.py, `symplan bundle --symbols handmade`);
- `operators.json`: the lifted operators with their reliabilities, the learner, its
  settings and the atom semantics (`operators_json`, the one layout, versioned);
- `domain.pddl` (with `:action-costs`, for Fast Downward) and `domain_strips.pddl` (the
  same actions without costs, for pyperplan);
- `provenance.json`: commands, seeds, data fingerprints and the bundle's measured figures;
- `continuous.pt` (optional): the effect models that bilevel planning rolls forward instead
  of the symbol model (abstraction/continuous.py): one, or an ensemble's members (models
  without the bottleneck trained on other seeds; their disagreement is the uncertainty).

What a bundle does with scenes (read symbols, plan, check steps) is the abstraction layer's
(drake_symplan/abstraction/).
"""

from __future__ import annotations

import dataclasses
import json
from importlib import resources
from pathlib import Path

from drake_symplan.atomic import write_atomic
from drake_symplan.boxes import CONTACT_TOLERANCE
from drake_symplan.json_files import read_json, type_name
from drake_symplan.learning.checkpoint import (
    best_checkpoint,
    load_run,
    model_from_checkpoint,
    models_from_file,
    read_checkpoint,
    save_checkpoint,
)
from drake_symplan.learning.gumbel import DEFAULT_MARGIN
from drake_symplan.learning.handmade import HandmadeSymbols
from drake_symplan.symbolic import relation_patterns
from drake_symplan.symbolic.effect_operators import (
    EFFECT,
    PAPER,
    EffectLearnConfig,
    Semantics,
    learn_effect_operators,
    lift_transitions,
    measure_reliability,
)
from drake_symplan.symbolic.generalize import generalize as generalize_operators
from drake_symplan.symbolic.operators import LearnConfig, learn_operators
from drake_symplan.symbolic.pddl import domain_pddl
from drake_symplan.symbolic.structs import LiftedOperator, PlanningOperators

FILES = ("model.pt", "operators.json", "domain.pddl", "domain_strips.pddl", "provenance.json")
CONTINUOUS = "continuous.pt"
LEARNERS = ("effect", "paper")
OPERATORS_FORMAT, OPERATORS_VERSION = "drake_symplan operators", 2


class BundleError(ValueError):
    """A bundle directory that cannot be used; the message names the directory or file."""


def default_bundle_dir() -> Path:
    """The shipped default model: models/learned/ in the repo (package data when installed)."""
    return Path(str(resources.files("drake_symplan_models"))) / "learned"


def operators_json(operators: list[LiftedOperator], semantics: Semantics, info: dict) -> dict:
    """operators.json: the format and version, the semantics, `info` (the learner's
    summary, symbol counts) and each operator's `LiftedOperator.to_dict`."""
    return {"format": OPERATORS_FORMAT, "version": OPERATORS_VERSION,
            "semantics": dataclasses.asdict(semantics), **info,
            "operators": [op.to_dict() for op in operators]}


def read_operators_json(data: dict) -> tuple[list[LiftedOperator], Semantics, dict]:
    """(operators, semantics, info) of operators.json; version 1 (bundles written before
    the version field) is read too. ValueError on anything else."""
    if not isinstance(data, dict):
        raise ValueError(f"operators.json holds {type_name(data)}, not an object")
    version = data.get("version", 1)
    if version not in (1, OPERATORS_VERSION):
        raise ValueError(f"operators.json version {version} is not one this code reads "
                         f"(1, {OPERATORS_VERSION})")
    for key, kind in (("operators", "list"), ("semantics", "object")):
        if not isinstance(data.get(key), list if kind == "list" else dict):
            raise ValueError(f"operators.json has no {key} {kind}")
    missing = [k for k in ("n_unary", "n_relations") if k not in data]
    if missing:
        raise ValueError(f"operators.json lacks {missing}")
    scale = data.get("cost_scale", 10.0)
    operators = [LiftedOperator.from_dict(d, scale) for d in data["operators"]]
    semantics = Semantics(**{"degree": False, "guess_uncertain": False, **data["semantics"]})
    info = {k: v for k, v in data.items()
            if k not in ("operators", "semantics", "format", "version")}
    return operators, semantics, info


class ModelBundle:
    """A loaded bundle (see the module docstring): the model, its operators (all of them;
    `planning` groups them as the planner sees them, symbolic/structs.py's
    PlanningOperators, and `planned` is the planner's share: of those with the same
    preconditions and effects, the cheapest), the semantics, the learner's info,
    provenance."""

    def __init__(self, path: Path, model, operators: list[LiftedOperator],
                 semantics: Semantics, info: dict, provenance: dict,
                 margin: float = DEFAULT_MARGIN, continuous=None):
        self.path, self.model, self.operators = path, model, operators
        # The effect models bilevel planning rolls forward: continuous.pt's, else the model.
        self.continuous = continuous if continuous is not None else [model]
        self.semantics, self.info, self.provenance, self.margin = (
            semantics, info, provenance, margin)
        self.by_name = {op.name: op for op in operators}
        self.n_unary, self.n_relations = info["n_unary"], info["n_relations"]
        # the relevance its data were collected with (data/collect.py): the graph of pairs
        # the model and the operators read, the contact rule for a bundle that names none
        self.relevance_radius = float(info.get("relevance_radius", CONTACT_TOLERANCE))
        self.planning = PlanningOperators(operators)
        self.planned = self.planning.planned
        self.domain = domain_pddl(self.planned, self.n_unary, self.n_relations, costs=True)
        self.domain_strips = domain_pddl(self.planned, self.n_unary, self.n_relations,
                                         costs=False)
        self._domains: dict[tuple[int, bool], str] = {}
        # the goal relations read in the symbols (relation_patterns.py), where measured
        self.patterns = relation_patterns.load(path)

    def domain_for(self, n_objects: int, costs: bool = True) -> str:
        """The planner's domain for a task of `n_objects` objects (pddl.domain_pddl)."""
        key = (n_objects, costs)
        if key not in self._domains:
            self._domains[key] = domain_pddl(self.planned, self.n_unary, self.n_relations,
                                             costs=costs, n_objects=n_objects)
        return self._domains[key]

    @classmethod
    def load(cls, path: str | Path | None = None, allow_empty: bool = False) -> ModelBundle:
        """The bundle in `path` (the shipped one when None); `allow_empty`: one without
        operators too (an explorer's early round, explorers/rounds.py)."""
        path = Path(path) if path is not None else default_bundle_dir()
        if not path.is_dir():
            raise BundleError(f"model directory {path} does not exist")
        for name in ("model.pt", "operators.json"):
            if not (path / name).is_file():
                raise BundleError(f"model directory {path} has no {name}")
        try:
            operators, semantics, info = read_operators_json(
                read_json(path / "operators.json", expect=object))
            model = model_from_checkpoint(read_checkpoint(path / "model.pt")).eval()
            continuous = models_from_file(path / CONTINUOUS) \
                if (path / CONTINUOUS).is_file() else None
        except (ValueError, KeyError, TypeError, AttributeError, OSError, RuntimeError) as e:
            raise BundleError(f"model directory {path}: cannot read it ({e})") from e
        if not operators and not allow_empty:
            raise BundleError(f"model directory {path}: operators.json holds no operators")
        prov = path / "provenance.json"
        provenance = read_json(prov) if prov.is_file() else {}
        return cls(path, model, operators, semantics, info, provenance,
                   info.get("margin", DEFAULT_MARGIN), continuous)


# --- making a bundle --------------------------------------------------------------------


def copy_model(run_dirs: str | Path | list, path: Path) -> Path:
    """Runs' best checkpoints as a bundle's model file: what rebuilds each model and says
    where it came from, no optimizer state. Several runs: an ensemble's members."""
    runs = run_dirs if isinstance(run_dirs, (list, tuple)) else [run_dirs]
    kept = []
    for run in runs:
        ckpt = read_checkpoint(best_checkpoint(run))
        kept.append({k: ckpt[k] for k in ("model", "model_config", "model_state", "epoch",
                                          "train_config", "data_fingerprint", "metrics")
                     if k in ckpt})
    return save_checkpoint(path, kept[0] if len(kept) == 1 else {"members": kept})


def learn_bundle_operators(data, learner: str = "effect", min_count: int = 10,
                           support: float = 0.95, contact_degree: bool = True,
                           generalize: float | None = None, bystanders: bool = False):
    """(operators, semantics, info) learned from a SymbolDataset by `learner`:
    "effect" (effect_operators.py; `contact_degree`: with contact-degree atoms;
    `generalize`: preconditions cut to what the data shows matters, within that much
    reliability, and with `bystanders` the objects no effect names, symbolic/generalize.py)
    or "paper" (operators.py, the paper's method as implemented, measured under its own
    semantics: every bit, every pair)."""
    if learner == "effect":
        semantics = EFFECT if contact_degree else dataclasses.replace(EFFECT, degree=False)
        lifted = lift_transitions(data, semantics)
        result = learn_effect_operators(data, EffectLearnConfig(min_count, support),
                                        lifted=lifted, semantics=semantics)
        info = {**result.summary(), "contact_degree": contact_degree}
        if generalize is None:
            return result.operators, semantics, info
        operators = generalize_operators(result.operators, lifted, generalize, bystanders)
        return operators, semantics, {**info, "generalize": generalize,
                                      "bystanders": bystanders}
    if learner == "paper":
        result = learn_operators(data, LearnConfig(min_count=min_count))
        measure_reliability(result.operators, lift_transitions(data, PAPER))
        return result.operators, PAPER, {"learner": "paper", **result.summary()}
    raise ValueError(f"unknown learner {learner!r}; one of {LEARNERS}")


def spans(op: LiftedOperator) -> bool:
    """Is `op` over three objects, its effect relating the box it moves to both others at
    once (a block laid across two supports)? One with more objects (boxes under the
    supports) would ground to every ordered choice of them: n^5 actions for five."""
    related = {frozenset(a[1:]) for a in op.add if len(a) == 3 and 0 in a[1:]}
    return op.n_params == 3 and len(related) == 2


def extend_operators(base: list[LiftedOperator], learned: list[LiftedOperator]
                     ) -> list[LiftedOperator]:
    """`base` as it is, then the `learned` operators that span (`spans`), numbered after
    it: operators a data set of its own taught (a bridge over two cubes) added to a
    bundle's, whose other operators keep the reliabilities of the data they came from."""
    added = [op for op in learned if spans(op)]
    return [*base, *(dataclasses.replace(op, index=len(base) + i)
                     for i, op in enumerate(added))]


def write_bundle(out: str | Path, run_dir: str | Path | HandmadeSymbols, operators,
                 semantics: Semantics, info: dict, provenance: dict,
                 margin: float = DEFAULT_MARGIN,
                 continuous_run: str | Path | list | None = None) -> Path:
    """Writes a bundle directory (every file atomically) from a run's best checkpoint (or
    the hand-made symbols' model, learning/handmade.py, nothing trained), and
    `continuous_run`'s (one run or several) as continuous.pt."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if isinstance(run_dir, HandmadeSymbols):
        model = run_dir
        save_checkpoint(out / "model.pt", model.checkpoint())
    else:
        model, _ = load_run(run_dir)
        copy_model(run_dir, out / "model.pt")
    if continuous_run is not None:
        copy_model(continuous_run, out / CONTINUOUS)
    data = operators_json(operators, semantics, {
        **info, "n_unary": model.n_unary, "n_relations": model.n_relations, "margin": margin})
    write_atomic(out / "operators.json", json.dumps(data, indent=1))
    planned = PlanningOperators(operators).planned
    for name, costs in (("domain.pddl", True), ("domain_strips.pddl", False)):
        write_atomic(out / name, domain_pddl(planned, model.n_unary, model.n_relations,
                                             costs=costs))
    write_atomic(out / "provenance.json", json.dumps(provenance, indent=1))
    return out
