"""Systems test: the closed loop in full physics with the UR10 and a model bundle: put one
cube onto another and check it within 5 cm. The bundle is the shipped default
(models/learned/), or the directory in $SYMPLAN_TEST_BUNDLE. About a minute."""

from __future__ import annotations

import os

import pytest

from drake_symplan.world.scenes import ObjectSpec, Scene


@pytest.mark.slow
def test_solves_a_cube_onto_cube_goal_with_the_arm():
    from drake_symplan.abstraction.abstraction import Abstraction
    from drake_symplan.agent.config import SolveConfig
    from drake_symplan.agent.solve import solve
    from drake_symplan.symbolic.bundle import ModelBundle, default_bundle_dir

    path = os.environ.get("SYMPLAN_TEST_BUNDLE") or default_bundle_dir()
    if not os.path.isdir(path):
        pytest.skip(f"no model bundle at {path} (set SYMPLAN_TEST_BUNDLE to one)")
    bundle = ModelBundle.load(path)
    start = Scene([ObjectSpec("o0", "cube", [0.60, -0.15, 0.025]),
                   ObjectSpec("o1", "cube", [0.80, 0.10, 0.025])])
    goal = Scene([ObjectSpec("o0", "cube", [0.80, 0.10, 0.075]),
                  ObjectSpec("o1", "cube", [0.80, 0.10, 0.025])])
    result = solve(start, goal, Abstraction(bundle), SolveConfig("fd", cpu_seconds=30.0))
    out = result.to_json()
    assert result.status == "success", out
    assert result.executed, out
    for name, z in {"o0": 0.075, "o1": 0.025}.items():  # o0 rests on o1 in the simulator too
        assert out["objects"][name]["error_cm"] <= 5.0, out
        assert out["objects"][name]["final_true"][2] == pytest.approx(z, abs=0.01), out
