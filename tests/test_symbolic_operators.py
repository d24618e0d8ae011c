"""Operator learning on hand-written symbolic transitions with known operators."""

import dataclasses

import numpy as np
import pytest

from drake_symplan.datasets import SymbolDataset
from drake_symplan.symbolic import synthetic
from drake_symplan.symbolic.operators import LearnConfig, learn_operators
from drake_symplan.symbolic.pddl import domain_pddl
from drake_symplan.symbolic.synthetic import Row, dataset_from_rows, shuffled


def learn(rows, min_count=1, n_relations=3, **config):
    data = dataset_from_rows(rows, n_relations=n_relations)
    return learn_operators(data, LearnConfig(min_count=min_count, **config))


def strs(atoms):
    return sorted(" ".join(a) for a in atoms)


def p0_bits(op) -> list[bool]:
    """p0 of each parameter in the operator's preconditions."""
    return [("p0", i) in op.pre for i in range(op.n_params)]


def no_true_bit(op) -> bool:
    """No precondition bit is set (every precondition atom is a not_ one)."""
    return all(a[0].startswith("not_") for a in op.pre)


def test_paper_example_groups_two_samples_under_a_substitution():
    # Paper III-C: p(x1)=0, p(x2)=0, p(x3)=1, pick-place(x3, x1) and
    # p(x1)=0, p(x2)=1, p(x3)=0, pick-place(x2, x3) are one group.
    rows = [
        Row((0, 0, 1), set(), (2, "center", 0, "center")),
        Row((0, 1, 0), set(), (1, "center", 2, "center")),
    ]
    ops = learn(rows, n_relations=1)
    assert len(ops.operators) == 1
    op = ops.operators[0]
    assert op.count == 2 and op.n_params == 3
    assert p0_bits(op) == [True, False, False]  # ?o0 is the source
    assert op.name == "pick_center_place_center_n2_op0"


def test_exact_operator_preconditions_and_effects():
    # A cube (p0=0) put centred onto a long block (p0=1): r0(s, t) and r2(t, s) appear.
    rows = [Row((0, 1), set(), (0, "left", 1, "center"), next_rel={(0, 0, 1), (2, 1, 0)})] * 3
    (op,) = learn(rows).operators
    assert op.grasp == "left" and op.release == "center" and op.count == 3
    assert strs(op.preconditions()) == strs([
        ("different", "?o0", "?o1"),
        ("not_p0", "?o0"), ("p0", "?o1"),
        ("not_r0", "?o0", "?o1"), ("not_r1", "?o0", "?o1"), ("not_r2", "?o0", "?o1"),
        ("not_r0", "?o1", "?o0"), ("not_r1", "?o1", "?o0"), ("not_r2", "?o1", "?o0"),
    ])
    add, delete = op.effects()
    assert strs(add) == ["r0 ?o0 ?o1", "r2 ?o1 ?o0"]
    assert strs(delete) == ["not_r0 ?o0 ?o1", "not_r2 ?o1 ?o0"]


def test_source_and_target_roles_are_not_swapped():
    # Same symbols, roles reversed: two different operators.
    rows = [Row((0, 1), set(), (0, "center", 1, "center")),
            Row((0, 1), set(), (1, "center", 0, "center"))]
    ops = learn(rows)
    assert len(ops.operators) == 2
    assert sorted(p0_bits(op) for op in ops.operators) == [
        [False, True], [True, False]]


def test_offsets_split_groups():
    rows = [Row((0, 0), set(), (0, g, 1, r)) for g in ("left", "right") for r in ("left", "center")]
    assert len(learn(rows).operators) == 4


def test_identical_objects_tie_without_permuting():
    # Source 0 with two identical cubes 2 and 3 on it (r2(0, x), r0(x, 0)); in the
    # second row the same scene with objects listed in another order.
    rel = {(2, 0, 2), (0, 2, 0), (2, 0, 3), (0, 3, 0)}
    rows = [
        Row((1, 0, 0, 0), rel, (0, "center", 1, "center")),
        Row((0, 0, 1, 0), {(2, 2, 0), (0, 0, 2), (2, 2, 3), (0, 3, 2)},
            (2, "center", 1, "center")),
    ]
    ops = learn(rows)
    assert len(ops.operators) == 1 and ops.operators[0].n_params == 4
    assert ops.timings["permuted_transitions"] == 0


def test_tied_objects_with_different_outcomes_give_one_canonical_effect():
    # Two identical cubes on the source; one of them falls off (r0/r2 vanish).
    rel = {(2, 0, 2), (0, 2, 0), (2, 0, 3), (0, 3, 0)}
    rows = [
        Row((1, 0, 0, 0), rel, (0, "right", 1, "left"),
            next_rel=rel - {(2, 0, 2), (0, 2, 0)}),
        Row((1, 0, 0, 0), rel, (0, "right", 1, "left"),
            next_rel=rel - {(2, 0, 3), (0, 3, 0)}),
    ]
    (op,) = learn(rows).operators
    assert op.count == 2 and op.outcomes == 1 and op.effect_count == 2
    add, delete = op.effects()
    assert len(add) == 2 and len(delete) == 2


def _cycles(lengths, offset=2):
    """r0 edges of directed cycles over objects offset, offset+1, ..."""
    rel, start = set(), offset
    for m in lengths:
        for i in range(m):
            rel.add((0, start + i, start + (i + 1) % m))
        start += m
    return rel


def test_genuine_ties_are_permuted_and_told_apart():
    # A 6-cycle and two 3-cycles among six plain objects: colour refinement cannot tell
    # them apart (every object has one r0 in and one r0 out), the canonical form can.
    n = 8
    unary = (1,) + (0,) * (n - 1)
    six = Row(unary, _cycles([6]), (0, "center", 1, "center"))
    threes = Row(unary, _cycles([3, 3]), (0, "center", 1, "center"))
    data = dataset_from_rows([six, six, threes], n_relations=1)
    data = shuffled(data, seed=3)
    ops = learn_operators(data, LearnConfig(min_count=1))
    assert sorted(op.count for op in ops.operators) == [1, 2]
    assert ops.timings["permuted_transitions"] == 3


def test_most_frequent_effect_wins():
    pre = Row((0, 0), set(), (0, "center", 1, "right"))
    on = {(1, 0, 1), (2, 1, 0)}
    rows = [Row(pre.unary, set(), pre.action, next_rel=on)] * 3 + [pre] * 2
    (op,) = learn(rows).operators
    assert (op.count, op.effect_count, op.outcomes) == (5, 3, 2)
    assert strs(op.effects()[0]) == ["r1 ?o0 ?o1", "r2 ?o1 ?o0"]


def test_equally_frequent_effects_break_ties_independently_of_order():
    pre = Row((0, 0), set(), (0, "center", 1, "right"))
    moved = Row(pre.unary, set(), pre.action, next_rel={(1, 0, 1)})
    for rows in ([pre, moved], [moved, pre]):
        (op,) = learn(rows).operators
        assert op.effect_count == 1 and op.outcomes == 2
        assert op.effects() == learn([pre, moved]).operators[0].effects()


def test_threshold_drops_rare_groups_and_reports_relative_thresholds():
    common = Row((0, 0), set(), (0, "center", 1, "center"))
    rare = Row((1, 0), set(), (0, "center", 1, "center"))
    rows = [common] * 4 + [rare]
    ops = learn(rows, min_count=2)
    assert [op.count for op in ops.operators] == [4]
    assert ops.n_groups == 2 and ops.threshold == 2
    assert ops.summary()["coverage"] == pytest.approx(0.8)
    by_fraction = {r["fraction"]: r for r in ops.threshold_report() if r["by"] == "fraction"}
    assert by_fraction[1e-4]["threshold"] == 1 and by_fraction[1e-4]["operators"] == 2
    assert len(learn(rows, min_fraction=0.5).operators) == 1  # needs 3 of 5
    assert len(learn(rows, min_fraction=0.9).operators) == 0  # needs 5 of 5
    assert len(learn(rows, min_fraction=0.2).operators) == 2  # needs 1 of 5
    assert len(learn(rows, min_count=5).operators) == 0


def test_self_relations_ignored_by_default_and_kept_on_request():
    rows = [Row((0, 0), {(0, 0, 0)}, (0, "center", 1, "center")),
            Row((0, 0), set(), (0, "center", 1, "center"))]
    assert len(learn(rows).operators) == 1
    ops = learn(rows, self_relations=True)
    assert len(ops.operators) == 2
    assert any(("r0", "?o0", "?o0") in op.preconditions() for op in ops.operators)


def test_uncertain_transitions_can_be_dropped():
    rows = [Row((0, 0), set(), (0, "center", 1, "center"))] * 3
    data = dataset_from_rows(rows)
    flags = np.zeros_like(data.unary, dtype=bool)
    flags[0, 1, 0] = True
    data = dataclasses.replace(data, unary_uncertain=flags)
    ops = learn_operators(data, LearnConfig(min_count=1, drop_uncertain=True))
    assert ops.n_transitions == 2 and ops.n_dropped_uncertain == 1
    assert learn_operators(data, LearnConfig(min_count=1)).n_transitions == 3


def test_rejects_transitions_without_one_source_and_target():
    data = dataset_from_rows([Row((0, 0), set(), (0, "center", 1, "center"))])
    data.action[0, 1, 4] = 0.0
    with pytest.raises(ValueError, match="exactly one source"):
        learn_operators(data)
    with pytest.raises(TypeError, match="takes a SymbolDataset, got dict"):
        learn_operators(data.arrays())


def test_symbol_dataset_checks_names_and_shapes(tmp_path):
    data = dataset_from_rows([Row((0, 1, 0), {(0, 0, 1)}, (0, "center", 1, "center"))])
    assert (len(data), data.n_objects, data.n_unary, data.n_relations) == (1, 3, 1, 3)
    with pytest.raises(ValueError, match=r"lacks \['relational', 'next_unary'"):
        SymbolDataset.from_arrays({"unary": data.unary})
    with pytest.raises(ValueError, match=r"unknown arrays \['colour'\]"):
        SymbolDataset.from_arrays({**data.arrays(), "colour": data.unary})
    with pytest.raises(ValueError, match=r"next_relational has shape \(1, 2, 3, 3\), "
                       r"expected \(1, 3, 3, 3\)"):
        dataclasses.replace(data, next_relational=data.next_relational[:, :2])
    with pytest.raises(ValueError, match=r"relational_uncertain has shape \(1, 3, 3\)"):
        dataclasses.replace(data, relational_uncertain=np.zeros((1, 3, 3), bool))
    with pytest.raises(ValueError, match=r"action has shape \(1, 3, 7\)"):
        dataclasses.replace(data, action=data.action[:, :, :7])
    # Saved and loaded: the same arrays under the same names; errors name the file.
    data.save(tmp_path / "symbols.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["symbols.npz"]
    again = SymbolDataset.load(tmp_path / "symbols.npz")
    assert again.arrays().keys() == data.arrays().keys() == {
        "unary", "relational", "next_unary", "next_relational", "action", "mask"}
    assert all(np.array_equal(again[k], data[k]) for k in data.arrays())
    with pytest.raises(KeyError):
        again["unary_uncertain"]  # absent optional array
    with pytest.raises(FileNotFoundError, match="no symbols file .*nope.npz"):
        SymbolDataset.load(tmp_path / "nope.npz")
    (tmp_path / "bad.npz").write_text("not a zip")
    with pytest.raises(ValueError, match="cannot read symbols file .*bad.npz"):
        SymbolDataset.load(tmp_path / "bad.npz")


def test_padding_slots_anywhere_and_object_order_do_not_matter():
    data = synthetic.random_transitions(600, seed=1, max_objects=7)
    ops = learn_operators(data, LearnConfig(min_count=3))
    for seed in (1, 2):
        other = learn_operators(shuffled(data, seed=seed), LearnConfig(min_count=3))
        assert domain_pddl(other.operators, 1, 3) == domain_pddl(ops.operators, 1, 3)


def test_learned_domain_does_not_depend_on_transition_order():
    data = synthetic.random_transitions(5000, seed=2)
    config = LearnConfig(min_count=10)
    reference = domain_pddl(learn_operators(data, config).operators, 1, 3)
    for seed in (5, 6):
        again = learn_operators(shuffled(data, seed=seed, slots=False), config)
        assert domain_pddl(again.operators, 1, 3) == reference


def test_synthetic_world_operators_match_its_rules():
    data = synthetic.random_transitions(20000, seed=4)
    ops = learn_operators(data, LearnConfig(min_count=20))
    # A clear cube onto a clear cube on the table, released centred: it ends on it.
    found = [op for op in ops.operators if op.n_params == 2 and op.release == "center"
             and no_true_bit(op)]
    assert {op.grasp for op in found} == {"left", "center", "right"}
    for op in found:
        add, delete = op.effects()
        assert strs(add) == ["r0 ?o0 ?o1", "r2 ?o1 ?o0"]
        assert op.outcomes == 1
    # Off-centre onto a long block: lands off-centre 85 % of the time (stochastic).
    off = [op for op in ops.operators if op.n_params == 2 and op.release == "left"
           and p0_bits(op) == [False, True]
           and not any(a[0].startswith("r") for a in op.pre)]
    assert off and all(strs(op.effects()[0]) == ["r1 ?o0 ?o1", "r2 ?o1 ?o0"] for op in off)
    assert {op.grasp for op in off} == {"left", "center", "right"}
    assert any(op.outcomes == 2 and op.effect_count < op.count for op in off)
