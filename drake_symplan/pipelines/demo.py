"""The demo's episode (`symplan demo`, tools/run_demo.py): a problem (the shipped one, scene
files, or one sampled with a seed: k random arm actions make the goal), one plan printed
step by step, its execution by the UR10 in full physics with monitoring and replanning,
each object's distance to its goal and the verdict against 5 cm, and one HTML recording
with the plan and the verdict in a panel. With no plan it says why and stops."""

from __future__ import annotations

import contextlib
import dataclasses as dc
import html
import json
import sys
import time
from importlib import resources
from pathlib import Path

import numpy as np

MAX_ATTEMPTS = 12  # random problems tried before giving up (non-trivial, reproducible)

WHY = {True: "the goal's symbols hold in the final scene: the learned symbols do not tell "
             "the goal positions apart (they say what is on what, not where on the table)",
       False: "the goal's symbols do not hold in the final scene: an operator's prediction "
              "or the execution went wrong"}


def shipped_problem() -> Path:
    """The default problem's directory: start.yaml, goal.yaml, problem.json (models/demo/)."""
    return Path(str(resources.files("drake_symplan_models"))) / "demo"


def shown(path) -> str:
    """`path` as printed: relative to the working directory when it lies under it."""
    path = Path(path).resolve()
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return str(path)


@dc.dataclass
class DemoSettings:
    """What the episode is asked: a sampled problem (`seed`, `objects`, `k`; None: 2 or 3
    by the seed) or the scene files `start`/`goal` it was given; where to `record` (None:
    nowhere); `meshcat`: announce Meshcat's URL (the caller keeps it serving);
    `camera_noise`: the cameras' sensor model."""

    seed: int | None = None
    objects: int = 3
    k: int | None = None
    start: Path | None = None
    goal: Path | None = None
    record: Path | None = None
    meshcat: bool = False
    camera_noise: str = "none"
    goal_spec: list[str] | None = None  # a goal written in one line, built from the start


@dc.dataclass
class DemoOutcome:
    """The exit status (0 success, 1 otherwise), the result object of `symplan solve
    --json` plus "demo" (None when no solve ran), and the Meshcat of a finished episode."""

    code: int
    result: dict | None = None
    meshcat: object = None


def make_goal(agent, seed: int, objects: int, k: int | None, say):
    """(start, goal, info) of the first non-trivial reproducible random problem, or None."""
    from drake_symplan.goals.problems import make_problem, problem_seed

    k = k or int(np.random.default_rng(seed).integers(2, 4))
    for attempt in range(MAX_ATTEMPTS):
        pseed = problem_seed(seed, attempt)
        made = make_problem(agent, pseed, objects, k, reproducible=True)
        if not isinstance(made, str):
            start, goal, info = made
            return start, goal, {"seed": seed, "problem_seed": pseed, "k": k, **info}
        say(f"  attempt {attempt}: dropped ({made})")
    return None


def explain_no_plan(abstraction, plan, start, goal, timeout: float) -> str:
    """Why there is no plan, in words: the planner's status and the goal atoms that do
    not hold at the start."""
    task = abstraction.task(abstraction.read_scene(start.scene),
                            abstraction.read_scene(goal.scene))
    missing = ", ".join(a.text() for a in sorted(task.goal - task.init))
    if plan.status == "unsolvable":
        why = ("the learned domain cannot reach the goal's symbols from the start's (the "
               "planner proved it)")
    elif plan.status == "timeout":
        why = f"the planner found no plan within --timeout {timeout:g} s"
    else:
        why = f"the planner failed: {plan.message}"
    return f"no plan: {why}; goal atoms to reach: {missing or 'none'}"


def panel(result: dict, demo: dict) -> str:
    """The recording's panel: problem, plan, executed steps, distances, verdict."""
    from drake_symplan.agent.inspection import panel_html

    def items(lines):
        return "<ol style='padding-left:18px;margin:2px 0'>" + "".join(
            f"<li>{line}</li>" for line in lines) + "</ol>"

    errors = "".join(f"<div>{n}: {o['error_cm']} cm</div>" for n, o in result["objects"].items())
    if result.get("symbolic_goal_reached") is not None:
        errors += f"<div><i>{WHY[result['symbolic_goal_reached']]}</i></div>"
    rejected = [html.escape(f"{c['source']}: {' '.join(c['steps']) or 'no steps'}: {c['why']}")
                for c in result.get("candidates", []) if not c["accepted"]]
    sections = [("Goal", "<div>translucent green boxes; k = "
                 f"{demo.get('k', '-')} random actions from the start</div>"),
                ("Plan", items(demo["plan_readable"]) or "<div>none</div>"),
                *([("Rejected candidate plans", items(rejected))] if rejected else []),
                (f"Executed ({result['replans']} replan(s))",
                 items(demo["executed_readable"])),
                (f"Verdict: {result['status']}", errors)]
    return panel_html(f"symplan demo (seed {demo.get('seed', '-')})", sections)


def scattered_start(seed: int, objects: int):
    """A start scene of `objects` boxes standing apart on the table (sampled with `seed`)."""
    from drake_symplan.world.scenes import sample_scene

    return sample_scene(np.random.default_rng(seed), objects)


def build_spec_goal(agent, settings: DemoSettings, start, demo: dict, say):
    """(start, goal) with the goal built from `start` by the arm after settings.goal_spec
    (goals/compiler.py); None when it could not be built (told)."""
    from drake_symplan.goals.problems import build_goal
    from drake_symplan.relations import parse

    structures = parse(settings.goal_spec)
    say(f"building the goal {'; '.join(s.text() for s in structures)} with the UR10 ...")
    made = build_goal(agent, start, structures)
    if isinstance(made, str):
        say(f"the goal was not built: {made}; try another --seed")
        return None
    goal, info = made
    demo.update(goal_spec=[s.text() for s in structures], actions=info["actions"],
                k=len(info["actions"]))
    say(f"goal: {'; '.join(demo['goal_spec'])}, {demo['k']} designed actions away")
    return start, goal


def pose_problem(agent, settings: DemoSettings, start, goal, demo: dict, say):
    """(start, goal) of the episode, told and noted in `demo`; None when no goal came."""
    if settings.goal_spec:
        return build_spec_goal(agent, settings, start, demo, say)
    if start is None:
        say(f"making a goal: {settings.objects} objects, random actions by the UR10 ...")
        made = make_goal(agent, settings.seed, settings.objects, settings.k, say)
        if made is None:
            say(f"no non-trivial, reproducible goal in {MAX_ATTEMPTS} attempts; "
                "try another --seed")
            return None
        start, goal, info = made
        demo.update(info)
        say(f"goal: {info['k']} random actions away ({'; '.join(info['actions'])}), "
            f"farthest object moved {info['moved_cm']} cm")
        return start, goal
    info = settings.start.parent / "problem.json"  # beside a problem set's start.yaml
    if info.is_file():
        demo.update({k: v for k, v in json.loads(info.read_text()).items()
                     if k in ("k", "seed", "actions", "moved_cm")})
    demo["problem"] = {"start": shown(settings.start), "goal": shown(settings.goal)}
    say(f"problem: {shown(settings.start)} -> {shown(settings.goal)}"
        + (f" ({demo['k']} arm actions apart)" if "k" in demo else ""))
    return start, goal


def prepare_recording(meshcat, record: Path, start, goal, demo: dict) -> None:
    """Saves both scenes beside the recording and draws the goal into it."""
    from drake_symplan.agent.inspection import draw_goal_scene, look_at
    from drake_symplan.world.scenes import save_scene

    record.parent.mkdir(parents=True, exist_ok=True)
    stem = record.with_suffix("")
    demo["scenes"] = {"start": f"{stem}_start.yaml", "goal": f"{stem}_goal.yaml"}
    save_scene(start, demo["scenes"]["start"])
    save_scene(goal, demo["scenes"]["goal"])
    draw_goal_scene(meshcat, goal)
    look_at(meshcat, [o.position for o in start.objects + goal.objects])


def plan_teller(abstraction, timeout: float, demo: dict, say):
    """The solve's `on_plan`: tells the plan step by step (or why there is none)."""
    from drake_symplan.agent.inspection import plan_quality, readable_step

    def planned(plan, start_seen, goal_seen):
        demo["plan_readable"] = [readable_step(s) for s in plan.steps]
        for c in plan.candidates:
            if not c.accepted:
                say(f"rejected {c.source}: {' '.join(c.steps) or 'no steps'}: {c.why}")
        if not plan.solved:
            demo["no_plan"] = explain_no_plan(abstraction, plan, start_seen, goal_seen,
                                              timeout)
            say(demo["no_plan"])
            return
        if not plan.steps:
            say("plan: empty, the goal's symbols already hold in the start scene")
        else:
            say(f"plan ({len(plan.steps)} step(s), {plan_quality(plan, goal_seen)}, "
                f"{plan.seconds:.1f} s" + ("" if plan.symbolic
                                           else f", {plan.level}") + "):")
        if plan.message:
            say(f"  ({plan.message})")
        for i, step in enumerate(plan.steps, 1):
            say(f"  {i}. {readable_step(step)}    {step}")
        say("executing with the UR10 in full physics, perceiving after each step ...")

    return planned


def tell_verdict(result, out: dict, demo: dict, say) -> None:
    """The executed steps when they differ from the plan, each object's distance to its
    goal, the verdict and, when the symbols disagree with it, why."""
    from drake_symplan.boxes import GOAL_TOLERANCE

    if result.executed != result.plan:
        say("executed (repositionings and replans included): "
            + "; ".join(demo["executed_readable"]))
    if result.unmet is not None:  # a goal of relations
        check = f"the relations hold wherever they stand: {'no' if result.unmet else 'yes'}"
        for wrong in result.unmet:
            say(f"  not held: {wrong}")
    else:
        check = f"every object within {GOAL_TOLERANCE * 100:g} cm: " \
                f"{'yes' if result.success else 'no'}"
        for name, o in out["objects"].items():
            say(f"  {name}: {o['error_cm']} cm from its goal")
    say(f"verdict: {result.status} ({check}), {len(result.executed)} step(s), "
        f"{result.replans} replan(s)" + (f"; {result.failure_cause}: {result.message}"
                                       if result.message else ""))
    if result.symbolic_goal_reached is not None:
        say(WHY[result.symbolic_goal_reached])


def run_demo(bundle, settings: DemoSettings, config, start=None, goal=None, say=print,
             t0: float | None = None) -> DemoOutcome:
    """The episode with the model `bundle` and the SolveConfig `config`: on the scenes
    `start`/`goal` (loaded from settings.start/goal) or, when None, a problem sampled with
    settings.seed. `t0`: when the demo began (the recording's seconds count from it)."""
    from drake_symplan.abstraction.abstraction import Abstraction
    from drake_symplan.agent.inspection import annotate_html, readable_step
    from drake_symplan.agent.solve import Agent
    from drake_symplan.relations import parse
    from drake_symplan.world.visualization import StartMeshcat

    t0 = time.perf_counter() if t0 is None else t0
    meshcat, record = None, settings.record
    if settings.meshcat or record is not None:  # a recording is Meshcat's page
        with contextlib.redirect_stdout(sys.stderr):  # Meshcat's URL: not on stdout
            meshcat = StartMeshcat(announce=settings.meshcat)
    agent = Agent("arm", meshcat=meshcat, camera_noise=settings.camera_noise)
    abstraction = Abstraction(bundle)
    say(f"model {shown(bundle.path)}: {bundle.n_unary} unary symbol(s), "
        f"{bundle.n_relations} relations, {len(bundle.operators)} operators")
    demo = {"seed": settings.seed}
    if settings.camera_noise != "none":
        demo["camera_noise"] = settings.camera_noise
    posed = pose_problem(agent, settings, start, goal, demo, say)
    if posed is None:
        return DemoOutcome(1)
    start, goal = posed
    if record is not None:
        prepare_recording(meshcat, record, start, goal, demo)
    relations = parse(settings.goal_spec) if settings.goal_spec else ()
    result = agent.solve(start, goal, abstraction, config, record=record,
                         on_plan=plan_teller(abstraction, config.timeout, demo, say),
                         relations=relations)
    out = result.to_json()
    demo["executed_readable"] = [readable_step(s) for s in result.executed]
    demo["seconds"] = round(time.perf_counter() - t0, 1)
    out["demo"] = demo
    if result.status in ("no_plan", "timeout") and not result.executed:
        return DemoOutcome(1, out)
    tell_verdict(result, out, demo, say)
    if record is not None and record.is_file():
        record.write_text(annotate_html(record.read_text(), panel(out, demo)))
        out["recording"] = str(record)
        say(f"recording written to {shown(record)} ({demo['seconds']} s)")
    return DemoOutcome(0 if result.success else 1, out, meshcat)
