"""The argument order of a relation, one known answer: o1 rests on o3, and the shipped
model's r0(x, y), which `symplan explain` describes as "x's centre is higher than y's",
must hold for (o1, o3) and not for (o3, o1), in the bits the planner reads, in the atoms
and in what `symplan inspect` prints. No Drake: the scene is perceived by hand."""

from __future__ import annotations

import numpy as np
from conftest import bundle_for_tests

from drake_symplan.abstraction.abstraction import Abstraction
from drake_symplan.agent.inspection import symbol_view
from drake_symplan.cli.inspect_cmds import summary_lines
from drake_symplan.features import object_features
from drake_symplan.learning.explain import explanation_line, relation_candidates
from drake_symplan.perception.perceive import PerceivedObject, PerceivedScene
from drake_symplan.symbolic.bundle import ModelBundle
from drake_symplan.world.scenes import ObjectSpec

# `symplan explain --data data_out/eval2k_s97` on the shipped model (the README's meanings).
R0 = "x's centre is higher than y's"

# o1 (a cube) rests centred on o3 (a long block); o0 and o2 stand apart on the table.
SCENE = [ObjectSpec("o0", "cube", [0.55, -0.25, 0.025]),
         ObjectSpec("o1", "cube", [0.70, 0.00, 0.075]),
         ObjectSpec("o2", "cube", [0.85, 0.25, 0.025]),
         ObjectSpec("o3", "long", [0.70, 0.00, 0.025])]


def perceived(specs, contacts) -> PerceivedScene:
    """What perception would report for upright boxes at the specs' poses."""
    objects = []
    for o in specs:
        c, s = np.cos(o.yaw), np.sin(o.yaw)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        position = np.array(o.position, float)
        objects.append(PerceivedObject(o.name, o.type, position, o.yaw, 0.0,
                                       object_features(o.type, position, R), False, R))
    return PerceivedScene(objects, set(contacts))


def described(meaning: str, fx: np.ndarray, fy: np.ndarray) -> bool:
    """Whether explain's candidate `meaning` holds for the ordered pair (x, y)."""
    literals = {}
    for pos, neg, v in relation_candidates(fx[None], fy[None]):
        literals[pos], literals[neg] = bool(v[0]), not bool(v[0])
    return literals[meaning]


def test_r0_of_the_upper_object_first_as_explain_inspect_and_the_atoms_say():
    abstraction = Abstraction(ModelBundle.load(bundle_for_tests()))
    scene = perceived(SCENE, [("o1", "o3")])
    reading = abstraction.read_scene(scene)
    i, j = scene.names.index("o1"), scene.names.index("o3")
    f = scene.features()
    # Explain's description, read with x = o1 and y = o3: o1's centre is the higher.
    assert described(R0, f[i], f[j]) and not described(R0, f[j], f[i])
    # The model reads r0(o1, o3) and not r0(o3, o1), both certainly.
    bits, unsure = reading.state.relational[0], reading.relational_uncertain[0]
    assert bits[i, j] and not bits[j, i] and not unsure[i, j] and not unsure[j, i]
    # The planner's atoms and inspect's relations name the arguments in the same order.
    atoms = {a.text() for a in abstraction.atoms(reading)[0]}
    assert "r0(o1, o3)" in atoms and "not_r0(o3, o1)" in atoms
    view = symbol_view(scene, reading)
    drawn = {(r["relation"], r["x"], r["y"]) for r in view["relations"]}
    assert ("r0", "o1", "o3") in drawn and ("r0", "o3", "o1") not in drawn
    line = next(s for s in summary_lines({"start": view}) if s.strip().startswith("o1 "))
    assert "r0(o1, o3)" in line
    # Explain prints its relations as r0(x, y): x first, as the atoms are.
    e = {"symbol": "r0", "arity": 2, "meaning": R0, "agreement": 0.93, "metric": "accuracy",
         "frequency": 0.51, "reads": 7004, "uncertain": 0.21}
    assert explanation_line(e).startswith("r0(x, y): x's centre is higher than y's, 93 %")
