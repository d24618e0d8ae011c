"""`symplan reproduce`: the stages a scale runs, resuming, a failing stage's one line; and the
small scale end to end (slow): collect, train 3 models x 3 seeds, operators, the three
evaluations, then the closed loop with the model it learned: a cube put onto another in
the arm, checked within 5 cm."""

from __future__ import annotations

import json

import pytest

from drake_symplan.agent.config import SolveConfig
from drake_symplan.cli.main import main
from drake_symplan.pipelines.reproduce import Reproduction, Stage, StageFailed
from drake_symplan.world.scenes import ObjectSpec, Scene


def test_the_stages_of_a_scale(tmp_path):
    rep = Reproduction("small", tmp_path)
    s = rep.scale
    assert [st.name for st in rep.collect_stages()] == ["collect train", "collect held-out"]
    trains = rep.train_stages()
    assert len(trains) == 3 * len(s.seeds)  # Table I's three models
    assert {st.argv[2] for st in trains} == {"relational", "attentive", "deepsym"}
    bundles = rep.bundles()  # effect-first for both; the paper's learner on relational only
    assert sorted({(m, learner) for m, _, learner in bundles}) == [
        ("attentive", "effect"), ("relational", "effect"), ("relational", "paper")]
    for _, evaluate in rep.operator_stages():  # selective scores against its training data
        assert evaluate.argv[evaluate.argv.index("--familiar-data") + 1] == rep.train_data
    rollouts = rep.rollout_stages()  # the continuous model of every Relational bundle
    assert [st.name for st in rollouts] == [f"eval rollout relational_s{seed}"
                                            for seed in s.planning_seeds]
    assert all(st.argv[st.argv.index("--data") + 1] == rep.heldout_data for st in rollouts)
    planning = rep.planning_stage().argv
    runs = planning[planning.index("--runs") + 1:planning.index("--problems")]
    assert [r.parent.name for r in runs] == ["relational_s0", "attentive_s0"]
    assert "--ray" not in planning and planning[-2:] == ["--workers", rep.jobs]
    assert planning[planning.index("--monitor") + 1] == "on"
    assert planning[planning.index("--planning") + 1] == "bilevel"  # SolveConfig's flags
    bilevel = Reproduction("small", tmp_path, solve=SolveConfig(planning="symbolic",
                                                                 refine=False))
    argv = bilevel.planning_stage().argv
    assert argv[argv.index("--planning") + 1] == "symbolic" and "--no-refine" in argv
    assert "--alternatives" not in argv  # the default, 0
    argv = Reproduction("small", tmp_path, solve=SolveConfig(alternatives=3)).planning_stage().argv
    assert argv[argv.index("--alternatives") + 1] == "3"
    # The other planning modes on the same problems, seed 0's Relational bundle only; the
    # main mode's open-loop row last.
    modes = rep.mode_stages()
    assert [st.name for st in modes] == ["eval planning symbolic", "eval planning continuous",
                                         "eval planning oracle", "eval planning bilevel open loop"]
    for st, mode, monitor in zip(modes, ("symbolic", "continuous", "oracle", "bilevel"),
                                 ("on", "on", "off", "off"), strict=True):
        runs = st.argv[st.argv.index("--runs") + 1:st.argv.index("--problems")]
        assert [r.parent.name for r in runs] == ["relational_s0"]
        assert st.argv[st.argv.index("--planning") + 1] == mode
        assert st.argv[st.argv.index("--monitor") + 1] == monitor
    on_ray = Reproduction("small", tmp_path, ray="10.0.0.1:6379")
    assert on_ray.collect_stages()[0].argv[-2:] == ["--ray", "10.0.0.1:6379"]
    assert on_ray.planning_stage().argv[-2:] == ["--ray", "10.0.0.1:6379"]
    # Every stage that perceives runs with the sensor model asked for; none adds no flag.
    noisy = Reproduction("small", tmp_path, camera_noise="realsense")
    perceiving = [*noisy.collect_stages(), *noisy.problem_stages(), noisy.planning_stage(),
                  *noisy.mode_stages()]
    for st in perceiving:
        assert st.argv[st.argv.index("--camera-noise") + 1] == "realsense", st.name
    assert not any("--camera-noise" in st.argv for st in [
        *rep.collect_stages(), *rep.problem_stages(), rep.planning_stage(), *rep.mode_stages()])
    assert not any("--camera-noise" in st.argv for st in noisy.train_stages())


def test_finished_stages_are_skipped_and_partial_ones_resume(tmp_path):
    rep = Reproduction("small", tmp_path, say=lambda text: None)
    done = tmp_path / "done.txt"
    done.write_text("x")
    rep._run(Stage("finished", ["no-such-command"], done))
    assert rep.log == [{"stage": "finished", "command": "symplan no-such-command",
                        "skipped": True}]
    run = tmp_path / "run"
    run.mkdir()
    (run / "last.pt").write_text("")
    train = next(st for st in rep.train_stages() if st.name == "train relational_s0")
    train.done = tmp_path / "never"
    with pytest.raises(StageFailed, match="train relational_s0 failed \\(exit 2"):
        rep._run(train)  # the training data set is missing
    partial = Stage("partial", ["train", "--out", run], tmp_path / "never2", partial=run / "last.pt",
                    resume=("--resume",))
    with pytest.raises(StageFailed):
        rep._run(partial)
    assert rep.log[-1] == {"stage": "finished", "command": "symplan no-such-command",
                           "skipped": True}  # failed stages are not logged as done


def test_a_failing_stage_is_one_line_and_exit_1(tmp_path, capsys):
    (tmp_path / "data" / "train").mkdir(parents=True)
    (tmp_path / "data" / "train" / "manifest.json").write_text("{not json")
    assert main(["reproduce", "--scale", "small", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("symplan reproduce: collect train failed (exit 2; log ")
    assert main(["reproduce", "--scale", "huge", "--out", str(tmp_path)]) == 2


def test_an_unfinished_planning_evaluation_reports_its_whole_runs(tmp_path):
    from drake_symplan.pipelines.results_tables import (
        finished_planning,
        modes_planning,
        planning_markdown,
        summarise_planning,
    )

    rep = Reproduction("small", tmp_path)
    assert [r.parent.name for r in rep.planning_runs()] == ["relational_s0", "attentive_s0"]
    folders = []
    for name, k in (("p000", 1), ("p001", 4)):
        folder = tmp_path / "problems" / "o2" / name
        folder.mkdir(parents=True)
        (folder / "problem.json").write_text(json.dumps({"k": k, "n_objects": 2}))
        folders.append(str(folder))
    rep.results.mkdir()

    def record(run, monitor, problem, k, status):
        return {"run": f"{run}/bundle_effect", "monitor": monitor, "problem": problem,
                "n_objects": 2, "k": k, "status": status,
                "failure_cause": None if status == "success" else "execution",
                "success_true": status == "success", "symbolic_goal_reached": True,
                "plan_length": 1, "executed": 1, "replans": 0,
                "seconds": {"plan": 0.1}, "error_cm": {}}

    lines = [record("relational_s0", True, folders[0], 1, "success"),
             record("relational_s0", True, folders[1], 4, "failure"),
             record("attentive_s0", True, folders[0], 1, "success")]  # one of two
    (rep.results / "planning.jsonl").write_text("\n".join(json.dumps(x) for x in lines))
    result, note = finished_planning(rep)
    assert note.startswith("Unfinished: 3 of 4 solves done") and \
        "relational_s0/bundle_effect (monitor)." in note
    table = summarise_planning(result)
    assert list(table) == ["relational"] and list(table["relational"]) == ["monitor"]
    entry = table["relational"]["monitor"]
    assert entry["success"]["mean"] == 0.5
    assert entry["by_band"]["2-4 objects, k 1-3"]["mean"] == 1.0
    assert entry["by_band"]["2-4 objects, k 4-5"]["mean"] == 0.0
    text = planning_markdown(table)
    assert "| relational | monitor | 1 | 2 | 50 ± 0 | 100 ± 0 | 0 ± 0 |" in text
    assert text.endswith("| execution 1 (1 with the goal's symbols) |")
    # A finished mode stage makes the modes table: seed 0's main row beside it.
    assert modes_planning(rep, result) == {}
    oracle = next(st for st in rep.mode_stages() if st.name.endswith("oracle"))
    oracle.done.write_text(json.dumps({"runs": {"relational_s0/bundle_effect": {
        "open_loop": result["runs"]["relational_s0/bundle_effect"]["monitor"]}}}))
    modes = modes_planning(rep, result)
    assert list(modes) == [rep.solve.planning, "oracle"]
    assert list(modes["oracle"]) == ["open_loop"]
    assert modes["oracle"]["open_loop"]["success"]["mean"] == 0.5
    # The main mode's open-loop stage is a second row of its own mode.
    open_loop = rep.mode_stages()[-1]
    open_loop.done.write_text(oracle.done.read_text())
    modes = modes_planning(rep, result)
    assert list(modes[rep.solve.planning]) == ["monitor", "open_loop"]


@pytest.mark.slow
def test_small_scale_end_to_end_then_a_goal_in_the_arm(tmp_path):
    from drake_symplan.abstraction.abstraction import Abstraction
    from drake_symplan.agent.solve import solve
    from drake_symplan.symbolic.bundle import ModelBundle

    out = tmp_path / "small"
    assert main(["reproduce", "--scale", "small", "--out", str(out)]) == 0
    text = (out / "results" / "results.md").read_text()
    for heading in ("Effect prediction (Table I)", "Planning at the symbolic level",
                    "Planning in the arm"):
        assert heading in text
    for name in ("relational", "attentive", "deepsym"):
        assert f"| {name} |" in text
    assert "| relational/paper |" in text and "| attentive/effect |" in text
    for figure in ("effects.png", "planning.png"):
        assert (out / "results" / figure).stat().st_size > 10_000
    provenance = json.loads((out / "provenance.json").read_text())
    assert len(provenance["data"]["train"]["fingerprint"]) >= 8
    stages = provenance["sittings"][0]["stages"]
    assert sum(st["command"].startswith("symplan train") for st in stages) == 9
    # Re-running the same command resumes: nothing left to do.
    assert main(["reproduce", "--scale", "small", "--out", str(out)]) == 0
    again = json.loads((out / "provenance.json").read_text())["sittings"][1]["stages"]
    assert all(st.get("skipped") for st in again)

    bundle = ModelBundle.load(out / "runs" / "relational_s0" / "bundle_effect")
    start = Scene([ObjectSpec("o0", "cube", [0.60, -0.15, 0.025]),
                   ObjectSpec("o1", "cube", [0.80, 0.10, 0.025])])
    goal = Scene([ObjectSpec("o0", "cube", [0.80, 0.10, 0.075]),
                  ObjectSpec("o1", "cube", [0.80, 0.10, 0.025])])
    result = solve(start, goal, Abstraction(bundle), SolveConfig("fd", cpu_seconds=30.0))
    assert result.status == "success", result.to_json()
    assert all(o["error_cm"] <= 5.0 for o in result.objects.values())


def test_the_rollout_table_is_mean_and_spread_over_seeds():
    from drake_symplan.pipelines.results_tables import rollout_markdown

    def report(mean, within):
        return {"by_k": {"1": {"error_cm": {"mean": mean, "median": mean / 2},
                               "scenes_within_5cm": within}}}

    text = rollout_markdown([report(1.0, 0.8), report(3.0, 0.6)])
    assert text.splitlines()[-1] == "| 1 | 2.0 ± 1.0 | 1.0 ± 0.5 | 70 ± 10 |"
