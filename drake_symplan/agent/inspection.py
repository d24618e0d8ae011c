"""Seeing the symbols: a perceived scene's learned symbols and a plan, drawn in Meshcat.

`inspect(start, bundle, goal=...)` puts the scene on the table, perceives it (boxes named
after the scene file, agent/beliefs.py), reads its symbols with the model bundle and
draws, under `/symplan` in Meshcat:

- `/symplan/start/boxes/<name>`: each perceived box, coloured by its unary bit pattern
  (`PALETTE[int(bits)]`; a pattern with an uncertain bit, `?`, is grey);
- `/symplan/start/relations/r<k>/<x>_<y>`: relation r_k(x, y) as a bracket of thin rods in
  r_k's colour from x's centre to y's, a ball at y's end; only certain bits that are set,
  only between objects perceived in contact (what the planner reads);
- with a goal scene: `/symplan/goal/...` the same for the perceived goal, translucent, and
  `/symplan/plan/step<i>`: an arc from step i's source to its target;
- with `clouds`: `/symplan/start/clouds/camera<i>`: what each camera's sensor gave for the
  start scene (one frame, world frame as perception believes the camera is, with the
  sensor model's noise, holes and flying pixels), before perception filters it.

Meshcat draws no text, so the legend (bit pattern -> colour, relation -> colour), the
objects' symbols and the plan step by step (operator, preconditions, effects) go into
a panel added to the recording's HTML (`panel_html`, `annotate_html`) and to the JSON.
The drawing is agent/inspection_draw.py.
"""

from __future__ import annotations

import html as _html
from pathlib import Path

from drake_symplan.abstraction.abstraction import Abstraction, Observation, reliability
from drake_symplan.abstraction.continuous import Boxes, goal_errors
from drake_symplan.abstraction.diagnosis import diagnose
from drake_symplan.abstraction.relation_goal import relation_goal
from drake_symplan.agent.config import DEFAULT_SOLVE, SolveConfig
from drake_symplan.agent.inspection_draw import PREFIX as PREFIX
from drake_symplan.agent.inspection_draw import (
    STEP_COLOURS,
    draw_clouds,
    draw_plan,
    draw_view,
    look_at,
)
from drake_symplan.agent.inspection_draw import draw_goal_scene as draw_goal_scene
from drake_symplan.agent.planning_modes import make_planner
from drake_symplan.agent.solve import Agent
from drake_symplan.symbolic.structs import PlanStep, Reposition, Step, goal_of, other_outcomes

CLOUD_Z_MIN = 0.003  # m: points at the table's height and below are not drawn
PALETTE = ("#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#b07aa1", "#edc948", "#76b7b2",
           "#ff9da7", "#9c755f", "#86bcb6", "#d4a6c8", "#8cd17d", "#f1ce63", "#a0cbe8",
           "#ffbe7d", "#d37295")
UNCERTAIN = "#9a9a9a"
RELATION_COLOURS = ("#111111", "#d62728", "#7b2fbe", "#1a7f37", "#0b3d91", "#c2185b",
                    "#8a5a00", "#008b8b")
GRASP = {"center": "at its centre", "left": "at its left end", "right": "at its right end"}
RELEASE = {"center": "centre", "left": "left", "right": "right"}
OUTCOMES_SHOWN = 3  # a step's other outcomes in the text and the panel (the JSON has all)


def readable_step(step: PlanStep) -> str:
    """(pick_center_place_left_n86_op2 o3 o1) -> 'pick o3 at its centre, release on o1's
    left'; a repositioning (agent/reposition.py) says so."""
    a = step.action
    text = f"pick {a.source} {GRASP[a.grasp]}, release on {a.target}'s {RELEASE[a.release]}"
    if isinstance(step, Reposition):
        return f"{text} ({'repositioning' if step.kind == 'reposition' else 'continuous'})"
    return text


def plan_quality(plan, goal_seen) -> str:
    """What speaks for a plan: its operators' reliability (symbolic steps) and, for a
    plan checked in continuous space, how near its goal every box is predicted to end."""
    parts = []
    if any(isinstance(s, Step) for s in plan.steps):
        parts.append(f"reliability {reliability(plan.steps):.0%}")
    if plan.predicted:
        far = max(goal_errors(plan.predicted[-1], Boxes.of(goal_seen.scene).where()).values())
        parts.append(f"every box predicted within {100 * far:.1f} cm of its goal")
    return ", ".join(parts)


def pattern(bits, uncertain) -> str:
    """'10?' from unary bits and their uncertain flags (p0 first)."""
    return "".join("?" if u else str(int(b)) for b, u in zip(bits, uncertain, strict=True))


def bits_text(pat: str) -> str:
    """'p0=1 p1=0 p2=?' for the pattern '10?'."""
    return " ".join(f"p{j}={c}" for j, c in enumerate(pat))


def colour(pat: str) -> str:
    return UNCERTAIN if "?" in pat else PALETTE[int(pat[::-1] or "0", 2) % len(PALETTE)]


def symbol_view(named_scene, reading) -> dict:
    """The symbols of a perceived scene (beliefs.Named.scene) and its bundle reading:
    objects with their bits and colours, the drawn relations, the legend."""
    s = reading.state
    index = {n: i for i, n in enumerate(s.objects)}
    objects = []
    for o in named_scene.objects:
        i = index[o.name]
        pat = pattern(s.unary[i], reading.unary_uncertain[i])
        objects.append({
            "name": o.name, "type": o.type, "position": [round(float(v), 4) for v in o.position],
            "unary": {f"p{j}": None if "?" == c else int(c) for j, c in enumerate(pat)},
            "pattern": pat, "colour": colour(pat)})
    relations = []
    for a, b in sorted(reading.contacts):
        for x, y in ((a, b), (b, a)):
            for k in range(s.relational.shape[0]):
                i, j = index[x], index[y]
                if s.relational[k, i, j] and not reading.relational_uncertain[k, i, j]:
                    relations.append({"relation": f"r{k}", "x": x, "y": y,
                                      "colour": RELATION_COLOURS[k % len(RELATION_COLOURS)]})
    legend = {"unary": {o["pattern"]: o["colour"] for o in objects},
              "relations": {f"r{k}": RELATION_COLOURS[k % len(RELATION_COLOURS)]
                            for k in range(s.relational.shape[0])}}
    return {"objects": objects, "relations": relations,
            "contacts": [list(p) for p in sorted(reading.contacts)], "legend": legend}


def plan_view(steps: list[PlanStep], init=None, operators=()) -> list[dict]:
    """Each plan step: its readable form, roles, operator, reliability and the grounded
    preconditions and effects (none for a move no operator names); with the plan's
    initial atoms `init` and the bundle's `operators`, each step's `other_outcomes` too
    (symbolic.structs.other_outcomes: where the action's outcome branches)."""
    def texts(atoms):
        return [a.text() for a in sorted(atoms)]

    def view(step):
        if isinstance(step, Reposition):
            return {"operator": None, "reliability": None, "preconditions": [], "add": [],
                    "delete": []}
        return {"operator": step.operator.name,
                "reliability": round(step.operator.reliability, 3),
                "preconditions": texts(step.pre), "add": texts(step.add),
                "delete": texts(step.delete)}

    rows = [{"step": str(step), "readable": readable_step(step), "source": step.action.source,
             "target": step.action.target, **view(step)} for step in steps]
    if init is not None:
        for row, others in zip(rows, other_outcomes(steps, init, operators), strict=True):
            row["other_outcomes"] = [{"operator": o.operator.name,
                                      "reliability": round(o.operator.reliability, 3),
                                      "add": texts(o.add), "delete": texts(o.delete)}
                                     for o in others]
    return rows


def outcome_text(o: dict) -> str:
    """One other outcome of a step, for people: '4% add r1(o1, o3); del -'."""
    return (f"{o['reliability']:.0%} add {', '.join(o['add']) or '-'}; "
            f"del {', '.join(o['delete']) or '-'}")


# --- the HTML panel -----------------------------------------------------------------

PANEL_STYLE = ("position:fixed;top:0;left:0;max-width:380px;max-height:100vh;overflow:auto;"
               "background:rgba(255,255,255,0.92);font:12px/1.35 sans-serif;padding:8px 10px;"
               "z-index:10;border-right:1px solid #ccc")


def _swatch(c: str) -> str:
    return (f'<span style="display:inline-block;width:11px;height:11px;background:{c};'
            'border:1px solid #555;vertical-align:middle;margin-right:4px"></span>')


def _objects_html(view: dict) -> str:
    rows = []
    for o in view["objects"]:
        rel = [f"{r['relation']}({r['x']}, {r['y']})" for r in view["relations"]
               if o["name"] == r["x"]]
        rows.append(f"<li>{_swatch(o['colour'])}<b>{o['name']}</b> {o['type']} "
                    f"({o['position'][0]:.2f}, {o['position'][1]:.2f}, {o['position'][2]:.2f}) "
                    f"p={o['pattern']}{'; ' + ', '.join(rel) if rel else ''}</li>")
    return "<ul style='padding-left:16px;margin:2px 0'>" + "".join(rows) + "</ul>"


def panel_html(title: str, sections: list[tuple[str, str]]) -> str:
    """A fixed panel: a title and (heading, inner HTML) sections."""
    body = "".join(f"<h4 style='margin:8px 0 2px'>{_html.escape(h)}</h4>{inner}"
                   for h, inner in sections)
    return (f'<div id="symplan-panel" style="{PANEL_STYLE}"><h3 style="margin:0 0 4px">'
            f"{_html.escape(title)}</h3>{body}</div>")


def inspection_sections(result: dict) -> list[tuple[str, str]]:
    """The panel's sections for an inspection result (see `inspect`)."""
    start = result["start"]
    legend = "".join(f"<div>{_swatch(c)}{bits_text(p)}</div>"
                     for p, c in sorted(start["legend"]["unary"].items()))
    rels = "".join(f"<div>{_swatch(c)}{k}(x, y): rod x &rarr; y, ball at y</div>"
                   for k, c in start["legend"]["relations"].items())
    sections = [("Unary symbols (box colour; ? uncertain = grey)", legend),
                ("Relations (only between objects in contact)", rels),
                ("Start (perceived)", _objects_html(start))]
    if result.get("goal"):
        sections.append(("Goal (translucent)", _objects_html(result["goal"]) + "<div>atoms: "
                         + _html.escape(", ".join(result["goal"]["atoms"])) + "</div>"))
        steps = "".join(f"<li>{_swatch(STEP_COLOURS[i % len(STEP_COLOURS)])}{_step_html(s)}</li>"
                        for i, s in enumerate(result["plan"]))
        sections.append((f"Plan ({result['plan_status']}, {len(result['plan'])} steps)",
                         f"<ol style='padding-left:18px;margin:2px 0'>{steps}</ol>"))
        for text in subgoal_texts(result):
            sections.append(("Subgoal (then a new plan from what is seen)", _html.escape(text)))
        if result.get("stages"):
            sections.append(("The goal's stages on the symbols alone", "".join(
                f"<div>{_html.escape(line)}</div>" for line in stage_lines(result["stages"]))))
        rejected = [c for c in result.get("candidates", []) if not c["accepted"]]
        if rejected:
            sections.append(("Rejected candidate plans", "".join(
                f"<div>{_html.escape(c['source'])}: {_html.escape(' '.join(c['steps']))}"
                f"<br><i>{_html.escape(c['why'])}</i></div>" for c in rejected)))
    return sections


def stage_lines(stages: list[dict]) -> list[str]:
    """The symbols' stages of a goal of relations (abstraction/diagnosis.py) as text, with
    the nearest steps of a stage that found no plan."""
    lines = []
    for i, s in enumerate(stages, 1):
        lines.append(f"stage {i} ({', '.join(s['relations'])}): {s['status']} in "
                     f"{s['seconds']:.1f} s: {' '.join(s['steps']) or 'no steps'}")
        lines.append(f"  atoms: {', '.join(s['atoms'])}")
        lines += [f"  nearest {n['step']}: lacks pre {', '.join(n['missing_pre']) or '-'}; "
                  f"leaves {', '.join(n['missing_goal']) or '-'}" for n in s["nearest"]]
    return lines


def subgoal_texts(result: dict) -> list[str]:
    """A receding plan's subgoal (the accepted candidate that stops short of the goal):
    where it stops, how far each box is predicted from its goal there, what comes next."""
    out = []
    for c in result.get("candidates", []):
        if c["accepted"] and c.get("rest"):
            far = {n: e for n, e in c["errors_cm"].items() if e > 0}
            out.append(f"{c['why']}; predicted cm from the goal there: {far}; the skeleton "
                       f"goes on: {' '.join(c['rest'])}")
    return out


def _step_html(s: dict) -> str:
    text = f"<b>{_html.escape(s['readable'])}</b>"
    if s["operator"] is None:  # a move no operator names
        return text
    return (f"{text}<br><code>{_html.escape(s['operator'])}</code> reliability "
            f"{s['reliability']:.0%}<br>pre: {_html.escape(', '.join(s['preconditions']))}"
            f"<br>add: {_html.escape(', '.join(s['add']) or '-')}<br>del: "
            f"{_html.escape(', '.join(s['delete']) or '-')}"
            + "".join(f"<br>or: {_html.escape(outcome_text(o))}"
                      for o in s.get("other_outcomes", [])[:OUTCOMES_SHOWN]))


def annotate_html(page: str, panel: str) -> str:
    """The Meshcat page with `panel` added before </body>."""
    at = page.rfind("</body>")
    return page[:at] + panel + page[at:] if at >= 0 else page + panel


def write_recording(meshcat, path: str | Path, panel: str) -> Path:
    """Meshcat's static page with the panel, written to `path`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(annotate_html(meshcat.StaticHtml(), panel))
    return path


# --- the command's work -------------------------------------------------------------


def inspect(start_scene, abstraction: Abstraction, goal_scene=None, meshcat=None, record=None,
            config: SolveConfig = DEFAULT_SOLVE, robot: str = "arm",
            title: str = "symplan inspect", camera_noise: str = "none",
            clouds: bool = False, relations=(), stages: bool = False) -> dict:
    """Perceives `start_scene` (and `goal_scene`) with cameras of the sensor model
    `camera_noise`, reads and draws their symbols, plans from start to goal (config's
    planner and timeout; with `relations`, to the goal of relations `goal_scene` is an
    example of); with `clouds`, also the start scene's raw point clouds (their sizes in
    the result); with `stages` and `relations`, the symbols' stages (diagnosis.py);
    returns the JSON result and writes the recording to `record`."""
    agent = Agent(robot, meshcat=meshcat, camera_noise=camera_noise)
    goal = agent.look(goal_scene) if goal_scene is not None else None
    start = agent.look(start_scene)  # the table stays in the start scene
    lost = start.lost + (goal.lost if goal is not None else [])
    if lost:
        raise RuntimeError(f"perception lost {', '.join(lost)}")
    start_reading = abstraction.read_scene(start.scene)
    result = {"model": str(abstraction.bundle.path),
              "start": symbol_view(start.scene, start_reading)}
    result["start"]["atoms"] = sorted(a.text() for a in abstraction.atoms(start_reading)[0])
    raw = agent.robot.station.point_clouds(z_min=CLOUD_Z_MIN) if clouds else []
    if clouds:
        result["start"]["cloud_points"] = [len(c) for c in raw]
    if goal is not None:
        wanted = Observation(goal.scene, abstraction.read_scene(goal.scene), Boxes.of(goal.scene))
        if relations:
            wanted = relation_goal(wanted, relations)
        result["goal"] = symbol_view(goal.scene, wanted.reading)
        result["goal"]["atoms"] = goal_of(abstraction.goal_atoms(wanted.reading)).describe()
        found = make_planner(abstraction, config).plan(
            Observation(start.scene, start_reading, Boxes.of(start.scene)), wanted)
        result["plan_status"], result["plan_level"] = found.status, found.level
        result["plan"] = plan_view(found.steps, abstraction.believed(start_reading),
                                   abstraction.bundle.operators)
        result["candidates"] = [c.to_json() for c in found.candidates]
        if stages and relations:
            result["stages"] = [r.to_json() for r in diagnose(
                abstraction, start_reading, wanted, config.planner, config.cpu_seconds)]
    if meshcat is not None:
        draw_view(meshcat, start.scene, result["start"])
        draw_clouds(meshcat, raw)
        look_at(meshcat, [o["position"] for o in result["start"]["objects"]])
        if goal is not None:
            draw_view(meshcat, goal.scene, result["goal"], "goal", alpha=0.3)
            draw_plan(meshcat, result["start"], result["plan"])
        if record is not None:
            write_recording(meshcat, record, panel_html(title, inspection_sections(result)))
            result["recording"] = str(record)
    return result
