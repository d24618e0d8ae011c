"""A small positive-STRIPS reader that checks plans: a test aid (the package writes PDDL,
symbolic/pddl.py, and never reads it back). test_planners, test_planning_grounding,
test_symbolic_bundle and test_symbolic_pddl use it."""

from __future__ import annotations

from dataclasses import dataclass

from drake_symplan.symbolic.pddl import parse_sexpr
from drake_symplan.symbolic.structs import apply


def _conj(expr) -> list:
    if not expr:
        return []
    if expr[0] == "and":
        return expr[1:]
    return [expr]


def _params(tokens: list[str]) -> list[str]:
    out, skip = [], False
    for tok in tokens:
        if skip:
            skip = False
        elif tok == "-":
            skip = True
        else:
            out.append(tok)
    return out


@dataclass
class Schema:
    params: list[str]
    pre: list[tuple[str, ...]]
    add: list[tuple[str, ...]]
    delete: list[tuple[str, ...]]


def read_domain(text: str) -> dict[str, Schema]:
    """Action schemas of a positive-STRIPS domain."""
    expr = parse_sexpr(text)
    if expr[:1] != ["define"]:
        raise ValueError("domain does not start with (define ...)")
    schemas = {}
    for part in expr[2:]:
        if not part or part[0] != ":action":
            continue
        fields = dict(zip(part[2::2], part[3::2], strict=False))
        add, delete = [], []
        for lit in _conj(fields.get(":effect", [])):
            if lit[0] == "not":
                delete.append(tuple(lit[1]))
            elif lit[0] != "increase":  # an action cost, not a fact
                add.append(tuple(lit))
        pre = [tuple(lit) for lit in _conj(fields.get(":precondition", []))]
        if any(lit[0] in ("not", "or", "=", "forall", "exists", "imply") for lit in pre):
            raise ValueError(f"action {part[1]} has a precondition that is not positive STRIPS")
        schemas[part[1]] = Schema(_params(fields.get(":parameters", [])), pre, add, delete)
    return schemas


def read_problem(text: str) -> tuple[list[str], set[tuple[str, ...]], list[tuple[str, ...]]]:
    """(objects, initial atoms, goal atoms) of a positive-STRIPS problem."""
    expr = parse_sexpr(text)
    if expr[:1] != ["define"]:
        raise ValueError("problem does not start with (define ...)")
    parts = {p[0]: p[1:] for p in expr[2:] if p and isinstance(p[0], str)}
    objects = _params(parts.get(":objects", []))
    init = {tuple(a) for a in parts.get(":init", []) if a[:1] != ["="]}  # no cost fluent
    goal = [tuple(a) for a in _conj(parts[":goal"][0])] if parts.get(":goal") else []
    return objects, init, goal


def check_plan(domain_text: str, problem_text: str, plan: list[str]) -> str | None:
    """Simulates `plan` from the problem's initial state: None when every step is
    applicable and the goal holds at the end, else what went wrong."""
    schemas = read_domain(domain_text)
    _, state, goal = read_problem(problem_text)
    for i, step in enumerate(plan):
        tokens = step.strip().strip("()").lower().split()
        if not tokens or tokens[0] not in schemas:
            return f"step {i}: unknown action in {step!r}"
        schema = schemas[tokens[0]]
        if len(tokens) - 1 != len(schema.params):
            return f"step {i}: {step!r} has {len(tokens) - 1} arguments, expected {len(schema.params)}"
        bind = dict(zip(schema.params, tokens[1:], strict=True))

        def ground(atom, bind=bind):
            return tuple(bind.get(x, x) for x in atom)

        missing = [ground(a) for a in schema.pre if ground(a) not in state]
        if missing:
            return f"step {i}: {step!r} is not applicable, missing {missing[:3]}"
        state = apply(state, map(ground, schema.add), map(ground, schema.delete))
    unmet = [g for g in goal if g not in state]
    if unmet:
        return f"goal not reached after {len(plan)} steps, missing {unmet[:3]}"
    return None
