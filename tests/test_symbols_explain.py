"""Symbol explanations (learning/explain.py): known answers on hand-made scenes and bits."""

from __future__ import annotations

import numpy as np
import pytest

from drake_symplan.learning.explain import (
    best_description,
    explain_scenes,
    explanation_line,
    plot_examples,
    unary_candidates,
)


def feat(kind, x, y, z, cos_tilt=1.0, up=0.0, yaw=0.0):
    k = 2 if kind == "long" else 4
    return [x, y, z, cos_tilt, up, np.cos(k * yaw), np.sin(k * yaw), kind == "cube",
            kind == "long"]


# Scenes of up to 3 objects: a cube stack, a long block on a cube, loose objects, a
# standing block, a tilted cube.
SCENES = [
    [feat("cube", 0.6, 0.0, 0.025), feat("cube", 0.6, 0.0, 0.075), feat("long", 0.8, 0.2, 0.025)],
    [feat("cube", 0.7, -0.2, 0.025), feat("long", 0.7, -0.2, 0.075, yaw=np.pi / 2)],
    [feat("long", 0.9, 0.1, 0.025), feat("cube", 0.5, -0.3, 0.025)],
    [feat("long", 0.8, -0.1, 0.125, up=1.0), feat("cube", 0.6, 0.3, 0.03, cos_tilt=0.8)],
]
CONTACTS = [[(0, 1)], [(0, 1)], [], []]


def arrays(scenes=SCENES, contacts=CONTACTS, m=3):
    t = len(scenes)
    F = np.zeros((t, m, 9), np.float32)
    mask = np.zeros((t, m), bool)
    C = np.zeros((t, m, m), bool)
    for i, (objs, pairs) in enumerate(zip(scenes, contacts, strict=True)):
        F[i, :len(objs)] = objs
        mask[i, :len(objs)] = True
        for a, b in pairs:
            C[i, a, b] = C[i, b, a] = True
    return F, mask, C


def explain(unary_bits, rel_bits=None, unary_unc=None):
    """explain_scenes with one unary bit ([T, M]) and one relation ([T, M, M])."""
    F, mask, C = arrays()
    u = np.asarray(unary_bits, np.uint8)[..., None]
    r = np.zeros((len(F), 1, 3, 3), np.uint8) if rel_bits is None else \
        np.asarray(rel_bits, np.uint8)[:, None]
    uu = np.zeros_like(u, bool) if unary_unc is None else np.asarray(unary_unc, bool)[..., None]
    return explain_scenes(F, mask, C, u, uu, r, np.zeros_like(r, bool))


def test_a_bit_that_is_the_object_type_reads_as_the_type():
    F, mask, _ = arrays()
    result = explain(F[..., 8] > 0.5)
    e = result["unary"][0]
    assert e["meaning"] == "is a long block" and e["agreement"] == 1.0
    assert e["metric"] == "accuracy" and e["reads"] == int(mask.sum()) == 9
    assert e["frequency"] == pytest.approx(4 / 9, abs=1e-3)
    assert explanation_line(e).startswith("p0(x): x is a long block, 100 % (accuracy; set in 44 %")


def test_a_bit_set_under_a_stacked_object_reads_as_has_something_on_top():
    bits = np.zeros((4, 3))
    bits[0, 0] = bits[1, 0] = 1  # the bottom cubes of the two stacks
    e = explain(bits)["unary"][0]
    assert e["meaning"] == "has an object on top" and e["agreement"] == 1.0


def test_a_relation_that_is_x_above_y_among_pairs_in_contact():
    r = np.zeros((4, 3, 3))
    r[0, 1, 0] = r[1, 1, 0] = 1  # upper object of each stack is x
    result = explain(np.zeros((4, 3)), r)
    e = result["relations"][0]
    assert result["pairs_in_contact"] == 4  # two contacts, both orders
    assert e["meaning"] == "x is above y" and e["agreement"] == 1.0
    assert e["frequency"] == 0.5 and e["reads"] == 4
    assert explanation_line(e).startswith("r0(x, y): x is above y, 100 %")


def test_uncertain_bits_are_left_out():
    F, _, _ = arrays()
    bits = F[..., 7] > 0.5  # the cubes
    unc = np.zeros((4, 3), bool)
    bits[3, 1], unc[3, 1] = False, True  # wrong but uncertain: not read
    e = explain(bits, unary_unc=unc)["unary"][0]
    assert e["meaning"] == "is a cube" and e["agreement"] == 1.0 and e["reads"] == 8
    assert e["uncertain"] == pytest.approx(1 / 9, abs=1e-3)


def test_a_rare_bit_is_scored_by_balanced_accuracy():
    # 100 objects, 5 with the bit; a candidate that is always 0 has 95 % accuracy but 50 %
    # balanced accuracy; the right candidate has 100 %.
    v = np.zeros(100, bool)
    v[:5] = True
    base = [("is it", "is not it", v), ("noise", "not noise", np.arange(100) % 2 == 0)]
    e = best_description(v, base)
    assert e["metric"] == "balanced accuracy" and e["meaning"] == "is it"
    assert e["agreement"] == 1.0 and e["frequency"] == 0.05
    near = v.copy()
    near[5] = True  # a candidate with one false positive
    e = best_description(v, [("close", "not close", near)])
    assert e["balanced_accuracy"] == pytest.approx(0.5 * (1 + 94 / 95), abs=1e-4)


def test_a_conjunction_wins_only_when_clearly_better():
    a = np.array([1, 1, 1, 1, 0, 0, 0, 0], bool)
    b = np.array([1, 1, 0, 0, 1, 1, 0, 0], bool)
    e = best_description(a & b, [("A", "not A", a), ("B", "not B", b)])
    assert e["meaning"] == "A and B" and e["agreement"] == 1.0
    e = best_description(a, [("A", "not A", a), ("B", "not B", b)])
    assert e["meaning"] == "A"


def test_constant_and_unread_bits():
    e = best_description(np.ones(5), [("A", "not A", np.ones(5, bool))])
    assert e["meaning"] == "constant (1)" and e["agreement"] is None
    e = best_description(np.zeros(0), [("A", "not A", np.zeros(0, bool))])
    assert e["meaning"] == "never read"


def test_unary_candidates_on_hand_made_poses():
    F, mask, C = arrays()
    c = {pos: v for pos, _, v in unary_candidates(F, C, mask)}
    assert c["is a long block standing on its end"][3, 0]
    assert not c["rests on a face (not tilted)"][3, 1]
    assert c["rests on something (bottom above the table)"][0, 1]
    assert not c["rests on something (bottom above the table)"][3, 0]  # standing, on the table
    assert c["has its long axis along world x"][1, 1] and c["has its long axis along world y"][0, 2]
    assert c["lies on another object"][1, 1] and not c["lies on another object"][1, 0]


def test_plot_of_examples(tmp_path):
    F, mask, C = arrays()
    r = np.zeros((4, 3, 3))
    r[0, 1, 0] = r[1, 1, 0] = 1
    u = (F[..., 8] > 0.5).astype(np.uint8)[..., None]
    rel = r.astype(np.uint8)[:, None]
    a = {"features": F, "mask": mask, "contacts": C, "unary": u,
         "unary_uncertain": np.zeros_like(u, bool), "relational": rel,
         "relational_uncertain": np.zeros_like(rel, bool)}
    result = explain_scenes(**a)
    path = plot_examples(result, a, tmp_path / "x.png", examples=2)
    assert path.stat().st_size > 10_000


def test_large_read_sets_are_scored_on_a_sample(monkeypatch):
    import drake_symplan.learning.explain as explain_module

    monkeypatch.setattr(explain_module, "MAX_READS", 50)
    v = np.arange(200) % 3 == 0
    e = best_description(v, [("every third", "not every third", v)])
    assert e["reads"] == 200 and e["meaning"] == "every third" and e["agreement"] == 1.0


def test_a_disjunction_is_a_candidate_too():
    a = np.array([1, 1, 0, 0, 0, 0, 0, 0], bool)
    b = np.array([0, 0, 1, 1, 0, 0, 0, 0], bool)
    e = best_description(a | b, [("A", "not A", a), ("B", "not B", b)])
    assert e["meaning"] == "A, or B" and e["agreement"] == 1.0
