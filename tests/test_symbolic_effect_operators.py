"""Effect-first operators on tiny hand-made symbolic data sets with known answers."""

from __future__ import annotations

import numpy as np

from drake_symplan.actions import Action, encode_action
from drake_symplan.datasets import SymbolDataset
from drake_symplan.evaluation.operators import familiarity, prediction_scores
from drake_symplan.symbolic.effect_operators import (
    EffectLearnConfig,
    atoms_and_unknown,
    learn_effect_operators,
    lift_transitions,
    predicts,
)


def state_atoms(*args, **kwargs) -> frozenset:
    """The certain atoms of one state (effect_operators.atoms_and_unknown)."""
    return atoms_and_unknown(*args, **kwargs)[0]


def dataset(rows) -> SymbolDataset:
    """rows: (unary [2,1], next_unary, contacts_after, rel_after [1,2,2], uncertain_unary)."""
    t = len(rows)
    out = {k: [] for k in ("unary", "next_unary", "relational", "next_relational",
                           "contacts", "next_contacts", "unary_uncertain")}
    for u, nu, c_after, r_after, unc in rows:
        out["unary"].append(u)
        out["next_unary"].append(nu)
        out["relational"].append(np.zeros((1, 2, 2), np.uint8))
        out["next_relational"].append(r_after)
        out["contacts"].append(np.zeros((2, 2), bool))
        out["next_contacts"].append(c_after)
        out["unary_uncertain"].append(unc)
    action = np.stack([encode_action(Action("a", "center", "b", "center"), ["a", "b"])] * t)
    arrays = {k: np.array(v) for k, v in out.items()}
    arrays["degree"] = arrays["contacts"].sum(-1)
    arrays["next_degree"] = arrays["next_contacts"].sum(-1)
    return SymbolDataset(action=action, mask=np.ones((t, 2), bool), **arrays)


ON = np.array([[[0, 1], [0, 0]]], np.uint8)  # r0(a, b): a on b
TOUCH = np.array([[False, True], [True, False]])
APART = np.zeros((2, 2), bool)
CERTAIN = np.zeros((2, 1), bool)


def stack(u_b: int, works: bool, unc=CERTAIN):
    u = np.array([[1], [u_b]], np.uint8)
    return (u, u, TOUCH if works else APART, ON if works else np.zeros((1, 2, 2), np.uint8), unc)


def test_an_effect_group_gets_intersected_preconditions_and_its_reliability():
    rows = [stack(1, True)] * 20 + [stack(0, False)] * 20 + [stack(1, False)] * 5
    ops = learn_effect_operators(dataset(rows), EffectLearnConfig(min_count=3))
    assert len(ops.operators) == 1  # the no-effect groups make no operator
    op = ops.operators[0]
    assert op.n_params == 2 and (op.grasp, op.release) == ("center", "center")
    assert sorted(" ".join(a) for a in op.preconditions()) == [
        "different ?o0 ?o1", "p0 ?o0", "p0 ?o1", "touching0 ?o0", "touching0 ?o1"]
    add, delete = op.effects()
    assert sorted(" ".join(a) for a in add) == [
        "not_r0 ?o1 ?o0", "r0 ?o0 ?o1", "touching1 ?o0", "touching1 ?o1"]
    assert sorted(" ".join(a) for a in delete) == ["touching0 ?o0", "touching0 ?o1"]
    # Applies where b has p0 (25 transitions), and 20 of them stacked.
    assert (op.applicable, op.succeeded) == (25, 20) and op.reliability == 0.8
    assert op.cost == 1 + round(10 * -np.log(0.8))


def test_uncertain_bits_make_no_atoms_and_support_tolerates_them():
    unc = np.array([[False], [True]])  # b's bit uncertain in one transition
    rows = [stack(1, True)] * 19 + [stack(1, True, unc)]
    ops = learn_effect_operators(dataset(rows), EffectLearnConfig(min_count=3, support=0.95))
    pre = sorted(" ".join(a) for a in ops.operators[0].preconditions())
    assert pre == ["different ?o0 ?o1", "p0 ?o0", "p0 ?o1", "touching0 ?o0",
                   "touching0 ?o1"]
    # Even a strict intersection keeps p0 ?o1: the transition that could not read b's bit
    # does not vote on it (19 of the 19 that could).
    strict = learn_effect_operators(dataset(rows), EffectLearnConfig(min_count=3, support=1.0))
    assert "p0 ?o1" in [" ".join(a) for a in strict.operators[0].preconditions()]
    # One that read it as 0 does vote against it.
    rows[-1] = stack(0, True)
    mixed = learn_effect_operators(dataset(rows), EffectLearnConfig(min_count=3, support=1.0))
    assert "p0 ?o1" not in [" ".join(a) for a in mixed.operators[0].preconditions()]
    atoms = state_atoms(np.array([[1], [1]]), unc, np.zeros((1, 2, 2)), None, APART,
                        np.array([True, True]))
    assert atoms == {("p0", 0)}
    assert state_atoms(np.array([[1], [1]]), unc, np.zeros((1, 2, 2)), None, APART,
                       np.array([True, True]), degree=np.array([0, 5])) == {
        ("p0", 0), ("touching0", 0), ("touching3", 1)}  # degrees above 3 read as 3


def test_relations_only_between_objects_in_contact_and_prediction_of_the_goal():
    u = np.array([[1], [1]], np.uint8)
    b_on_a = (u, u, TOUCH, np.array([[[0, 0], [1, 0]]], np.uint8), CERTAIN)
    lifted = lift_transitions(dataset([stack(1, True), stack(1, False), b_on_a]))
    assert ("r0", 0, 1) in lifted[0].after and ("not_r0", 1, 0) in lifted[0].after
    assert not any(a[0].endswith("r0") for a in lifted[1].after)  # apart: no relation atoms
    op = learn_effect_operators(dataset([stack(1, True)] * 3),
                                EffectLearnConfig(min_count=1)).operators[0]
    assert predicts(op, lifted[0]) is True
    assert predicts(op, lifted[1]) is False  # the goal: both still touch nothing
    assert predicts(op, lifted[2]) is False  # the goal has b on a, the operator a on b



def test_a_rare_effect_seen_through_an_uncertain_bit_counts_for_the_frequent_one():
    rows = [stack(1, True)] * 12
    data = dataset(rows + [stack(1, True)] * 3)
    unsure = np.zeros((15, 1, 2, 2), bool)
    unsure[12:, 0, 1, 0] = True  # not_r0(b, a) unreadable after in the last three
    data.next_relational_uncertain = unsure
    absorbed = learn_effect_operators(data, EffectLearnConfig(min_count=10))
    assert [op.count for op in absorbed.operators] == [15]
    alone = learn_effect_operators(data, EffectLearnConfig(min_count=10, absorb=False))
    assert [op.count for op in alone.operators] == [12]


def test_an_uncertain_bit_is_read_by_its_sign_for_applicability_only():
    op = learn_effect_operators(dataset([stack(1, True)] * 3),
                                EffectLearnConfig(min_count=1)).operators[0]
    unsure_b = np.array([[False], [True]])  # b's p0 reads 1, but too close to call
    lifted = lift_transitions(dataset([stack(1, True, unsure_b)]))
    assert ("p0", 1) not in lifted[0].before and ("p0", 1) in lifted[0].read_before
    assert predicts(op, lifted[0]) is True
    from drake_symplan.symbolic.effect_operators import EFFECT, Semantics

    strict = Semantics(**{**EFFECT.__dict__, "guess_uncertain": False})
    assert predicts(op, lift_transitions(dataset([stack(1, True, unsure_b)]), strict)[0]) is None


def test_without_contact_degrees_the_same_groups_make_operators_with_no_touching_atoms():
    from drake_symplan.symbolic.bundle import learn_bundle_operators

    rows = [stack(1, True)] * 20 + [stack(0, False)] * 20 + [stack(1, False)] * 5
    operators, semantics, info = learn_bundle_operators(dataset(rows), "effect", 3, 0.95,
                                                        contact_degree=False)
    assert not semantics.degree and info["contact_degree"] is False and len(operators) == 1
    op = operators[0]
    assert sorted(" ".join(a) for a in op.preconditions()) == [
        "different ?o0 ?o1", "p0 ?o0", "p0 ?o1"]
    add, delete = op.effects()
    assert sorted(" ".join(a) for a in add) == ["not_r0 ?o1 ?o0", "r0 ?o0 ?o1"]
    assert not list(delete)
    assert (op.applicable, op.succeeded) == (25, 20)


def test_selective_scores_count_only_situations_the_training_data_saw_often():
    # b's bit is p0 in 25 training transitions (20 stacked) and not in 2 (both stacked), so
    # the one operator needs only p0 ?o0 and applies to both situations.
    train = dataset([stack(1, True)] * 20 + [stack(1, False)] * 5 + [stack(0, True)] * 2)
    ops = learn_effect_operators(train, EffectLearnConfig(min_count=3)).operators
    assert len(ops) == 1 and "p0 ?o1" not in [" ".join(a) for a in ops[0].preconditions()]
    u = np.array([[1], [0]], np.uint8)
    b_on_a = (u, u, TOUCH, np.array([[[0, 0], [1, 0]]], np.uint8), CERTAIN)
    heldout = dataset([stack(1, True), stack(0, True), b_on_a, stack(1, False)])
    scores = prediction_scores(ops, heldout, familiar=familiarity(train), min_seen=(1, 5, 50))
    # Three transitions change symbols; the operator applies to all and predicts two.
    assert scores["changed"] == 3 and scores["coverage"] == 1.0
    assert scores["precision"] == scores["precision_top1"] == 2 / 3
    assert scores["alternatives"] == 1.0
    seen = {row["min_seen"]: row for row in scores["selective"]}
    assert (seen[1]["coverage"], seen[1]["precision"]) == (1.0, 2 / 3)
    # Seen at least 5 times: only the first (b with p0, 25 times), predicted.
    assert (seen[5]["coverage"], seen[5]["precision"]) == (1 / 3, 1.0)
    assert (seen[50]["coverage"], seen[50]["precision"]) == (0.0, 0.0)
