"""Beliefs: perceived scenes under the scene files' object names, followed across actions.

The perceiver names the boxes it sees p0, p1, ... by position, afresh in every scene. The
agent speaks the scene files' names instead (they are the PDDL objects and the keys of the
result), so:

- `name_by_file`: a perceived box takes the name of the scene-file object nearest to it
  (perception/matching.match_by_position, one-to-one, within MATCH_RADIUS). Nothing else is
  read from the file: positions, orientations, contacts and symbols are all perceived.
  A goal seen in frames on disk has no file: `name_by_type` names its boxes after the
  start's objects of their type, moving the boxes least.
- `follow`: after an action, perception's association (the grasp hypotheses of
  perception/association.associate) says which box seen after it is which object before
  it, and the scene seen after is renamed accordingly.

Objects that find no box are *lost*; boxes that find no object are *extra* and left out of
the renamed scene (the planner only knows the named objects).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from drake_symplan.perception.matching import match_by_position
from drake_symplan.perception.perceive import associate
from drake_symplan.symbolic.states import check_name

MATCH_RADIUS = 0.10  # m: a perceived box this far from every scene-file object is unnamed


@dc.dataclass(frozen=True)
class Frames:
    """Frames on disk (perception.perceive.DepthViews) perceived in place of the cameras'
    (`symplan solve --start-frames/--goal-frames`): the start's first look, its world still
    from its scene file, and the goal's, which has no scene file (`name_by_type`)."""

    start: object = None
    goal: object = None


NO_FRAMES = Frames()  # the cameras' perceptions only


class ScenePairError(ValueError):
    """A start and goal scene that do not describe the same objects (bad input)."""


@dc.dataclass
class Named:
    """A perceived scene renamed, with the objects it lost and the boxes it could not name."""

    scene: object  # perception.perceive.PerceivedScene under the new names
    lost: list[str]
    extra: list[str]


def rename(scene, mapping: dict[str, str]):
    """The perceived `scene` with its objects renamed by `mapping` (old -> new name); objects
    not in `mapping` are left out, and so are their contacts."""
    objects = [dc.replace(o, name=mapping[o.name]) for o in scene.objects if o.name in mapping]
    contacts = {tuple(sorted((mapping[a], mapping[b]))) for a, b in scene.contacts
                if a in mapping and b in mapping}
    return type(scene)(objects, contacts)


def name_by_file(perceived, spec) -> Named:
    """Names the boxes of `perceived` after the objects of the scene file `spec`
    (world.scenes.Scene), by position."""
    file = {o.name: np.asarray(o.position, float) for o in spec.objects}
    seen = {o.name: o.position for o in perceived.objects}
    match = match_by_position(file, seen, MATCH_RADIUS)
    mapping = {box: name for name, box in match.items()}
    return Named(rename(perceived, mapping), [n for n in file if n not in match],
                 [n for n in seen if n not in mapping])


def name_by_type(perceived, spec) -> Named:
    """Names the boxes of `perceived` (a goal seen in frames on disk, which no scene file
    names) after the objects of `spec`, the start's scene file: per type, by the one-to-one
    assignment that moves the boxes least. Boxes of a type are alike, so every such naming
    asks for the same arrangement."""
    named = Named(type(perceived)([], set()), [], [])
    mapping = {}
    for kind in sorted({o.type for o in spec.objects} | {o.type for o in perceived.objects}):
        file = {o.name: np.asarray(o.position, float) for o in spec.objects if o.type == kind}
        seen = {o.name: o.position for o in perceived.objects if o.type == kind}
        match = match_by_position(file, seen)
        mapping.update({box: name for name, box in match.items()})
        named.lost += [n for n in file if n not in match]
        named.extra += [n for n in seen if n not in match.values()]
    named.scene = rename(perceived, mapping)
    return named


def follow(before, after, action) -> Named:
    """`after` (seen after `action`, perceiver's names) under `before`'s names."""
    mapping = {new: old for old, new in associate(before, after, action).items()}
    return Named(rename(after, mapping), [n for n in before.names if n not in mapping.values()],
                 [n for n in after.names if n not in mapping])


def positions(scene) -> dict[str, np.ndarray]:
    return {o.name: np.asarray(o.position, float) for o in scene.objects}


def check_scene_pair(start, goal) -> None:
    """ScenePairError, one line, unless `start` and `goal` (world.scenes.Scene) hold the same
    objects, by name and type, with names a planner can use."""
    start_types = {o.name: o.type for o in start.objects}
    goal_types = {o.name: o.type for o in goal.objects}
    unknown = sorted(set(goal_types) - set(start_types))
    if unknown:
        raise ScenePairError(f"unknown objects in the goal: {unknown} (the start has "
                             f"{sorted(start_types)})")
    missing = sorted(set(start_types) - set(goal_types))
    if missing:
        raise ScenePairError(f"the goal lacks start objects {missing}: start and goal must "
                             "hold the same objects")
    changed = [f"{n} ({start_types[n]} -> {goal_types[n]})" for n in sorted(start_types)
               if start_types[n] != goal_types[n]]
    if changed:
        raise ScenePairError(f"objects change type between start and goal: {', '.join(changed)}")
    for name in start_types:
        try:
            check_name(name)
        except ValueError as e:
            raise ScenePairError(f"object name {name!r} cannot be planned with: {e}") from None


def goal_report(goal: dict[str, np.ndarray], final: dict[str, np.ndarray],
                truth: dict[str, np.ndarray]) -> dict[str, dict]:
    """Per goal object: goal, final (perceived; None if lost), final_true (simulator) as xyz
    lists in metres, and error_cm (perceived final to goal; None if lost)."""
    out = {}
    for name, g in goal.items():
        f, t = final.get(name), truth.get(name)
        out[name] = {
            "goal": _xyz(g),
            "final": None if f is None else _xyz(f),
            "final_true": None if t is None else _xyz(t),
            "error_cm": None if f is None else round(float(np.linalg.norm(f - g)) * 100, 2),
        }
    return out


def _xyz(p) -> list[float]:
    return [round(float(v), 4) for v in p]
