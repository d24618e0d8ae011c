"""PDDL domain and problem writers for learned operators (paper III-D). (The tests check
plans with a small positive-STRIPS reader of their own, tests/pddl_reader.py.)

Everything written is positive STRIPS with typing (`:strips :typing`), which both Fast
Downward and pyperplan read: symbols are `(pJ ?x)` / `(not_pJ ?x)` and `(rK ?x ?y)` /
`(not_rK ?x ?y)`, negation being explicit predicates. Distinct parameters are kept
distinct by a static `(different ?a ?b)` precondition for every parameter pair, which
problems list for every ordered pair of distinct objects.

Action names carry the offsets, the group's count and its frequency rank,
`pick_<grasp>_place_<release>_n<count>_op<rank>`; the first two parameters are always
the source and the target, so a plan step maps to a pick/place by
role, never by position in a name (symbolic/structs.py: parse_step).

As in the paper, preconditions speak only about an operator's parameters (the objects
that were relevant when it was learned). Positive STRIPS cannot say "and nothing else
touches ?o0", so a 2-parameter operator also matches a source that has a third object
in contact in the planner's state; the executor's goal check catches what that costs.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

from drake_symplan.symbolic.effect_operators import MAX_DEGREE, degree_atom
from drake_symplan.symbolic.states import SymbolicState, difference_facts, predicate_names
from drake_symplan.symbolic.structs import Atom, LiftedOperator

TYPE = "obj"
DOMAIN_NAME = "symplan"

def _atom(a: tuple) -> str:
    return Atom.of(a).pddl()


def _wrap(atoms: list[str], indent: str) -> str:
    if not atoms:
        return "(and)"
    return "(and\n" + "".join(f"{indent}  {a}\n" for a in atoms) + f"{indent})"


def domain_pddl(
    operators: Iterable[LiftedOperator],
    n_unary: int,
    n_relations: int,
    name: str = DOMAIN_NAME,
    n_transitions: int | None = None,
    costs: bool = False,
    n_objects: int | None = None,
) -> str:
    """The domain: one action schema per operator, most frequent first.

    With `costs` (operators that have a `cost`), each action increases `(total-cost)` by
    its cost (`:action-costs`, for Fast Downward; pyperplan reads the domain without).
    With `n_objects`, for tasks of that many objects: no action for an operator of more
    parameters (they must differ, so it never applies, but a planner's translator reads
    every action it is given); the predicates stay those of every operator."""
    operators = list(operators)
    unary, binary = predicate_names(n_unary, n_relations)
    # Perceived predicates the operators use besides the learned symbols (e.g. touchingN).
    declared = set(unary) | set(binary) | {"different"}
    extra = sorted({a[0]: len(a) - 1 for op in operators
                    for a in [*op.preconditions(), *op.effects()[0], *op.effects()[1]]
                    if a[0] not in declared}.items())
    degrees = {degree_atom(n) for n in range(MAX_DEGREE + 1)}
    if degrees & {p for p, _ in extra}:
        # A state or goal may hold a degree no operator mentions (an object touching more
        # objects than in training): declare the whole family so the problem parses.
        extra = sorted(dict(extra, **dict.fromkeys(degrees, 1)).items())
    preds = [f"({p} ?x - {TYPE})" for p in unary]
    preds += [f"({p} ?x ?y - {TYPE})" for p in binary + ["different"]]
    preds += [f"({p} " + " ".join(f"?x{i}" for i in range(n)) + f" - {TYPE})"
              for p, n in extra]
    lines = [
        f"; Learned by drake_symplan: {n_unary} unary and {n_relations} relational symbols.",
        f"(define (domain {name})",
        "  (:requirements :strips :typing" + (" :action-costs)" if costs else ")"),
        f"  (:types {TYPE})",
        "  (:predicates",
        *[f"    {p}" for p in preds],
        "  )",
        *(["  (:functions (total-cost) - number)"] if costs else []),
    ]
    for op in operators:
        if n_objects is not None and op.n_params > n_objects:
            continue
        add, delete = op.effects()
        effect = [_atom(a) for a in add] + [f"(not {_atom(a)})" for a in delete]
        if costs:
            effect.append(f"(increase (total-cost) {op.cost})")
        lines += [
            f"  ; {op.describe(n_transitions)}",
            f"  (:action {op.name}",
            "    :parameters (" + " ".join(f"{p} - {TYPE}" for p in op.params) + ")",
            "    :precondition " + _wrap([_atom(a) for a in op.preconditions()], "    "),
            "    :effect " + _wrap(effect, "    "),
            "  )",
        ]
    lines.append(")")
    return "\n".join(lines) + "\n"


def problem_pddl(
    start: SymbolicState,
    goal: SymbolicState,
    goal_contacts: set[tuple[str, str]] | None,
    name: str = "problem",
    domain: str = DOMAIN_NAME,
    self_relations: bool = False,
) -> str:
    """A problem from perceived start and goal states (paper IV-C).

    The start is the full closed-world state plus the `different` facts; the goal is
    every object's unary atoms plus relation atoms only for the pairs in
    `goal_contacts` (both directions; None: all pairs). Both states must name the
    same objects.
    """
    if set(start.objects) != set(goal.objects):
        raise ValueError(
            f"start and goal name different objects: {start.objects} vs {goal.objects}"
        )
    if (start.n_unary, start.n_relations) != (goal.n_unary, goal.n_relations):
        raise ValueError("start and goal have different numbers of symbols")
    return problem_from_atoms(start.objects, start.facts(self_relations),
                              goal.goal_facts(goal_contacts, self_relations), name, domain)


def problem_from_atoms(objects, init: Iterable[Atom], goal: Iterable[Atom],
                       name: str = "problem", domain: str = DOMAIN_NAME,
                       costs: bool = False) -> str:
    """A problem over `objects` with the given init and goal atoms (plus the `different`
    facts); with `costs`, it minimises `(total-cost)`."""
    objects = tuple(objects)
    init = list(init) + difference_facts(objects)
    lines = [
        f"(define (problem {name})",
        f"  (:domain {domain})",
        "  (:objects " + " ".join(objects) + f" - {TYPE})",
        "  (:init",
        *[f"    {_atom(a)}" for a in init],
        *(["    (= (total-cost) 0)"] if costs else []),
        "  )",
        "  (:goal " + _wrap([_atom(a) for a in goal], "  ") + ")",
        *(["  (:metric minimize (total-cost))"] if costs else []),
        ")",
    ]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- reading back


def parse_sexpr(text: str):
    """Nested lists of lowercase tokens; ';' starts a comment. ValueError on
    unbalanced parentheses."""
    tokens = re.findall(r"[()]|[^\s()]+", re.sub(r";[^\n]*", "", text).lower())
    stack: list[list] = [[]]
    for tok in tokens:
        if tok == "(":
            stack.append([])
        elif tok == ")":
            if len(stack) == 1:
                raise ValueError("unbalanced ')' in PDDL")
            inner = stack.pop()
            stack[-1].append(inner)
        else:
            stack[-1].append(tok)
    if len(stack) != 1:
        raise ValueError("unbalanced '(' in PDDL")
    if len(stack[0]) != 1 or not isinstance(stack[0][0], list):
        raise ValueError("PDDL text is not one (define ...) expression")
    return stack[0][0]


def check_pddl_file(path: str | Path) -> None:
    """Raises, naming `path`, unless it holds one balanced (define ...) expression: a
    syntax check only, which any planner input passes."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no PDDL file {path}")
    try:
        expr = parse_sexpr(path.read_text())
    except ValueError as e:
        raise ValueError(f"{path}: malformed PDDL: {e}") from e
    if expr[:1] != ["define"]:
        raise ValueError(f"{path}: malformed PDDL: not a (define ...) expression")
