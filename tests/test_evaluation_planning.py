"""The planning evaluation's summary on hand-made records (rates by object count and k,
failure causes, plan length against k), its plot, and the simulator's check."""

from __future__ import annotations

import pytest

from drake_symplan.evaluation.planning import plot_planning, summarise, true_success
from drake_symplan.world.scenes import ObjectSpec, Scene


def record(run, monitor, n, k, status, cause=None, plan_length=1, replans=0, plan_s=0.2):
    return {"run": run, "monitor": monitor, "problem": f"p{n}{k}{status}", "n_objects": n,
            "k": k, "status": status, "failure_cause": cause, "success_true": status == "success",
            "symbolic_goal_reached": None if status == "success" else cause == "execution",
            "plan_length": plan_length, "executed": plan_length, "replans": replans,
            "seconds": {"plan": plan_s}, "error_cm": {}}


RECORDS = [
    record("rel", True, 2, 1, "success", plan_length=1, replans=1),
    record("rel", True, 2, 2, "success", plan_length=3),
    {**record("rel", True, 3, 1, "failure", "execution", plan_length=1, plan_s=0.4),
     "refusals": 2},
    record("rel", True, 3, 2, "no_plan", "no_plan", plan_length=0, plan_s=0.1),
    record("rel", False, 2, 1, "failure", "perception"),
]


def test_summary_by_object_count_and_k():
    s = summarise(RECORDS)
    mon, open_loop = s["rel"]["monitor"], s["rel"]["open_loop"]
    assert mon["problems"] == 4 and mon["success"] == 0.5
    assert mon["by_objects"] == {
        "2": {"problems": 2, "success": 1.0, "success_true": 1.0, "plan_length_mean": 2.0},
        "3": {"problems": 2, "success": 0.0, "success_true": 0.0, "plan_length_mean": 0.5}}
    assert mon["by_k"]["1"]["success"] == 0.5 and mon["by_k"]["2"]["plan_length_mean"] == 1.5
    assert mon["failure_causes"] == {"execution": 1, "no_plan": 1}
    assert mon["execution_failures"] == {"symbolic_goal_reached": 1, "symbolic_goal_missed": 0}
    # plan length - k over the solved problems: (1-1) + (3-2) + (1-1) over 3
    assert mon["plan_length_minus_k"] == pytest.approx(1 / 3, abs=1e-3)
    assert mon["plan_seconds"]["median"] == pytest.approx(0.2)
    assert mon["replans_mean"] == 0.25
    assert mon["refusals"] == 2 and open_loop["refusals"] == 0  # old records: none
    assert open_loop["success"] == 0.0 and open_loop["failure_causes"] == {"perception": 1}


def test_plot_is_written(tmp_path):
    plot_planning(summarise(RECORDS), tmp_path / "planning.png")
    assert (tmp_path / "planning.png").stat().st_size > 10_000


def test_true_success_reads_the_goal_file_and_the_simulator_positions():
    goal = Scene([ObjectSpec("a", "cube", [0.8, 0.1, 0.075]), ObjectSpec("b", "cube",
                                                                          [0.8, 0.1, 0.025])])
    near = {"a": {"final_true": [0.83, 0.12, 0.075]}, "b": {"final_true": [0.8, 0.1, 0.025]}}
    assert true_success(near, goal)
    far = {**near, "a": {"final_true": [0.86, 0.1, 0.075]}}
    assert not true_success(far, goal)
    assert not true_success({"a": near["a"]}, goal)
