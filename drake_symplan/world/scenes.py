"""Scenes as files and samples: YAML read (naming the first malformed field), written
atomically, a simulator's poses as a scene, and seeded random scenes.

What a scene is (ObjectSpec, Scene: frames, orientations) and when it is valid
(validate_scene) is world/scene_model.py; those names stay importable from here.
"""

from __future__ import annotations

import dataclasses as dc
import math
from pathlib import Path

import numpy as np

from drake_symplan.actions import OFFSET_METRES
from drake_symplan.atomic import write_atomic
from drake_symplan.boxes import HALF_EXTENTS, LONG, SIDE
from drake_symplan.world.scene_model import MAX_OBJECTS as MAX_OBJECTS
from drake_symplan.world.scene_model import POOL
from drake_symplan.world.scene_model import TILT_TOL as TILT_TOL
from drake_symplan.world.scene_model import WORKSPACE_X as WORKSPACE_X
from drake_symplan.world.scene_model import WORKSPACE_Y as WORKSPACE_Y
from drake_symplan.world.scene_model import ObjectSpec as ObjectSpec
from drake_symplan.world.scene_model import Scene as Scene
from drake_symplan.world.scene_model import SceneError as SceneError
from drake_symplan.world.scene_model import footprints_overlap as footprints_overlap
from drake_symplan.world.scene_model import validate_scene as validate_scene


def _shown(value) -> str:
    text = repr(value).replace("True", "true").replace("False", "false")
    return text if len(text) <= 40 else text[:40] + "..."


def _number(value, field: str) -> float:
    """`value` of the scene field `field` as a finite float; ValueError naming the field
    when it is none (a bool, text, nan, inf, an integer too large for a float)."""
    from drake_symplan.typed_yaml import number

    converted = number(value)
    if converted is None:
        raise ValueError(f"{field} must be a finite number, got {_shown(value)}")
    return converted


def _numbers(value, field: str) -> list[float]:
    """`value` of the scene field `field` as 3 finite floats (position, rpy)."""
    if not isinstance(value, list) or len(value) != 3:
        what = " (roll, pitch, yaw)" if field == "rpy" else ""
        raise ValueError(f"{field} must be a list of 3 numbers{what}, got {_shown(value)}")
    return [_number(v, f"{field}[{k}]") for k, v in enumerate(value)]


def scene_from_dict(data: object, source: str = "scene") -> Scene:
    """Builds a Scene from parsed YAML, naming the first malformed field and its rule."""
    if not isinstance(data, dict) or not isinstance(data.get("objects"), list):
        raise SceneError(f"malformed {source}: expected a mapping with an 'objects' list")
    fields = {f.name for f in dc.fields(ObjectSpec)}
    objects = []
    for i, item in enumerate(data["objects"]):
        if not isinstance(item, dict):
            raise SceneError(f"malformed {source}: objects[{i}] is not a mapping")
        unknown = set(item) - fields
        if unknown:
            raise SceneError(f"malformed {source}: objects[{i}] has unknown keys "
                             f"{sorted(map(str, unknown))}")
        try:
            for key in ("name", "position"):
                if key not in item:
                    raise ValueError(f"no {key}")
            if not isinstance(item["name"], (str, int)) or isinstance(item["name"], bool):
                raise ValueError(f"name must be text, got {_shown(item['name'])}")
            rpy = None if item.get("rpy") is None else _numbers(item["rpy"], "rpy")
            yaw = _number(item.get("yaw", 0.0), "yaw")
            if rpy is not None:
                if "yaw" in item and not math.isclose(yaw, rpy[2], abs_tol=1e-6):
                    raise ValueError(f"yaw {yaw} differs from rpy's yaw {rpy[2]}")
                yaw = rpy[2]
            objects.append(ObjectSpec(
                name=str(item["name"]), type=str(item.get("type", "cube")),
                position=_numbers(item["position"], "position"), yaw=yaw, rpy=rpy))
        except ValueError as e:
            named = f" ({item['name']})" if isinstance(item.get("name"), str) else ""
            raise SceneError(f"malformed {source}: objects[{i}]{named}: {e}") from e
    return Scene(objects)


def scene_from_yaml(text: str, source: str | None = None) -> Scene:
    """A validated Scene from YAML text; `source` (e.g. "scene file F") prefixes errors."""
    import yaml

    from drake_symplan.typed_yaml import parse_yaml

    where = source or "scene"
    try:
        data = parse_yaml(text)
    except yaml.YAMLError as e:
        raise SceneError(f"malformed {where}: {e}") from e
    scene = scene_from_dict(data, where)
    try:
        return validate_scene(scene)
    except SceneError as e:
        raise SceneError(f"{source}: {e}" if source else str(e)) from e


def load_scene(path: str | Path) -> Scene:
    """Loads and validates a scene YAML file."""
    from drake_symplan.typed_yaml import read_text

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"scene file {path} does not exist")
    try:
        text = read_text(path)
    except ValueError as e:
        raise SceneError(f"scene file {e}") from None
    return scene_from_yaml(text, f"scene file {path}")


def scene_from_poses(poses: dict, types: dict[str, str]):
    """A scene of bodies at `poses` (name -> RigidTransform; a simulator's, e.g.
    Station.object_poses): upright objects with their yaw, tilted ones with their full rpy."""
    from pydrake.math import RollPitchYaw

    objects = []
    for name, X in poses.items():
        R = X.rotation()
        rpy = RollPitchYaw(R).vector()
        upright = abs(R.matrix()[2, 2]) >= np.cos(TILT_TOL)
        objects.append(ObjectSpec(name, types[name], [float(v) for v in X.translation()],
                                  float(rpy[2]), None if upright else [float(v) for v in rpy]))
    return Scene(objects)


def scene_to_yaml(scene: Scene) -> str:
    lines = ["objects:"]
    for o in scene.objects:
        pos = ", ".join(f"{v:.4f}" for v in o.position)
        if o.rpy is not None:
            angles = ", ".join(f"{v:.4f}" for v in o.rpy)
            pose = f"rpy: [{angles}]"
        else:
            pose = f"yaw: {o.yaw:.4f}"
        lines.append(f"  - {{name: {o.name}, type: {o.type}, position: [{pos}], {pose}}}")
    return "\n".join(lines) + "\n"


def as_saved(scene: Scene) -> Scene:
    """`scene` as its file reads back (numbers rounded as written), validated: a scene
    valid in memory can overlap once rounded (SceneError)."""
    return scene_from_yaml(scene_to_yaml(scene))


def save_scene(scene: Scene, path: str | Path, header: str = "") -> None:
    """Writes `scene` as YAML to `path` (its folder made if need be), atomically; what is
    written must read back valid (`as_saved`). `header`: comment lines put first (e.g. the
    spec that made a goal)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "".join(f"# {line}\n" for line in header.splitlines()) + scene_to_yaml(scene)
    scene_from_yaml(text)
    write_atomic(path, text)


def sample_scene(
    rng: np.random.Generator,
    num_objects: int,
    long_fraction: float = 0.5,
    yaw_jitter: float = 0.0,
    min_gap: float = 0.02,
    max_tries: int = 1000,
) -> Scene:
    """A random valid scene: `num_objects` upright boxes on the table, long blocks along y,
    each a long block with probability `long_fraction` while the station's pool (POOL)
    has one left, else a cube.

    `yaw_jitter` (radians) perturbs each yaw uniformly; `min_gap` keeps footprints apart so
    that sampled objects start out not touching.
    """
    if not 1 <= num_objects <= MAX_OBJECTS:
        raise SceneError(f"num_objects must be in [1, {MAX_OBJECTS}], got {num_objects}")
    def kind(i: int) -> str:
        return "long" if rng.random() < long_fraction else "cube"

    return validate_scene(Scene(_scatter(rng, [], num_objects, kind, yaw_jitter, min_gap,
                                         max_tries)))


def _scatter(rng: np.random.Generator, objects: list[ObjectSpec], count: int,
             kind_of, yaw_jitter: float = 0.0, min_gap: float = 0.02, max_tries: int = 1000
             ) -> list[ObjectSpec]:
    """`objects` and `count` more boxes, the i-th of type `kind_of(i)` (the other type
    where the pool has none of it left), set down at random, upright, `min_gap` clear of
    every box before it."""
    objects = list(objects)
    for i in range(count):
        kind = kind_of(i)
        if sum(o.type == kind for o in objects) >= POOL[kind]:
            kind = "cube" if kind == "long" else "long"
        hx, hy, hz = HALF_EXTENTS[kind]
        for _ in range(max_tries):
            yaw = float(rng.uniform(-yaw_jitter, yaw_jitter)) if yaw_jitter > 0 else 0.0
            x = float(rng.uniform(WORKSPACE_X[0] + hx, WORKSPACE_X[1] - hx))
            y = float(rng.uniform(WORKSPACE_Y[0] + hy, WORKSPACE_Y[1] - hy))
            cand = ObjectSpec(f"o{len(objects)}", kind, [x, y, hz], yaw)
            if not any(footprints_overlap(cand, o, -min_gap) for o in objects):
                objects.append(cand)
                break
        else:
            raise SceneError(f"could not place {len(objects) + 1} objects without overlap")
    return objects


def _level(k: int) -> float:
    """Centre height of the k-th box (0: on the table) in a stack of boxes lying flat, to
    the micrometre (so that the presets below keep their exact decimal heights)."""
    return round(SIDE / 2 + k * SIDE, 6)


_END = LONG / 2 - SIDE / 2  # a cube centred over a long block's end, from the block's centre
_SIDE_BY_SIDE = OFFSET_METRES["right"]  # a release beside: a cube's centre to the next

# Arrangements for perception tests and benchmarks: (type, dx, dy, z) relative to a unit's
# origin. "tipped" puts a long block over a cube's edge so that physics tips it.
UNITS: dict[str, list[tuple[str, float, float, float]]] = {
    "cube": [("cube", 0, 0, _level(0))],
    "long": [("long", 0, 0, _level(0))],
    "tower2": [("cube", 0, 0, _level(0)), ("cube", 0, 0, _level(1))],
    "tower3": [("cube", 0, 0, _level(0)), ("cube", 0, 0, _level(1)), ("cube", 0, 0, _level(2))],
    "cube_on_end": [("long", 0, 0, _level(0)), ("cube", 0, _END, _level(1))],
    "cubes_on_ends": [("long", 0, 0, _level(0)), ("cube", 0, -_END, _level(1)),
                      ("cube", 0, _END, _level(1))],
    "bridge": [("cube", 0, -_END, _level(0)), ("cube", 0, _END, _level(0)),
               ("long", 0, 0, _level(1))],
    # Two towers of two side by side along y, 7.5 cm apart (a release offset): a bridge's
    # supports as goals/compiler.py sets them, a gap of 2.5 cm (within boxes.VICINITY).
    "towers_side": [("cube", 0, 0, _level(0)), ("cube", 0, 0, _level(1)),
                    ("cube", 0, _SIDE_BY_SIDE, _level(0)), ("cube", 0, _SIDE_BY_SIDE, _level(1))],
    # Two cubes on the table side by side as towers_side's bottoms: a bridge's supports.
    "cubes_side": [("cube", 0, 0, _level(0)), ("cube", 0, _SIDE_BY_SIDE, _level(0))],
    "touching_x": [("cube", 0, 0, _level(0)), ("cube", SIDE, 0, _level(0))],
    "touching_y": [("cube", 0, 0, _level(0)), ("cube", 0, SIDE, _level(0))],
    # A cube against the block's side, 5 cm along it from the block's centre.
    "touching_long": [("long", 0, 0, _level(0)), ("cube", SIDE, 0.05, _level(0))],
    "tipped": [("cube", 0, -0.08, _level(0)), ("long", 0, 0.01, _level(1))],
}


def _unit_extent(parts) -> tuple[np.ndarray, np.ndarray]:
    lo = np.array([min(dx - HALF_EXTENTS[t][0] for t, dx, _, _ in parts),
                   min(dy - HALF_EXTENTS[t][1] for t, _, dy, _ in parts)])
    hi = np.array([max(dx + HALF_EXTENTS[t][0] for t, dx, _, _ in parts),
                   max(dy + HALF_EXTENTS[t][1] for t, _, dy, _ in parts)])
    return lo, hi


def sample_structured_scene(
    rng: np.random.Generator,
    num_objects: int,
    units: tuple[str, ...] = tuple(UNITS),
    gap: float = 0.03,
    max_tries: int = 2000,
) -> Scene:
    """A random scene of exactly `num_objects` made of arrangement units (stacks, bridges,
    touching pairs, blocks that will tip), placed apart from each other by `gap`."""
    placed: list[tuple[np.ndarray, np.ndarray]] = []
    objects: list[ObjectSpec] = []
    tries = 0
    while len(objects) < num_objects:
        tries += 1
        if tries > max_tries:
            raise SceneError(f"could not place {num_objects} objects in arrangement units")
        name = str(rng.choice(units))
        parts = UNITS[name]
        if len(objects) + len(parts) > num_objects:
            continue
        lo, hi = _unit_extent(parts)
        if name == "tipped":
            hi = hi + [0.0, 0.12]  # room for the block to fall towards +y
        ox = rng.uniform(WORKSPACE_X[0] - lo[0], WORKSPACE_X[1] - hi[0])
        oy = rng.uniform(WORKSPACE_Y[0] - lo[1], WORKSPACE_Y[1] - hi[1])
        box = (np.array([ox, oy]) + lo - gap, np.array([ox, oy]) + hi + gap)
        if any(np.all(box[0] < b[1]) and np.all(b[0] < box[1]) for b in placed):
            continue
        placed.append(box)
        yaw = float(rng.uniform(-0.25, 0.25)) if len(parts) == 1 else 0.0
        for t, dx, dy, z in parts:
            objects.append(ObjectSpec(f"o{len(objects)}", t, [ox + dx, oy + dy, z], yaw))
    return validate_scene(Scene(objects))


def _supports_scene(rng: np.random.Generator, num_objects: int, unit: str,
                    long_fraction: float) -> Scene:
    """A start with UNITS[unit] (a bridge's supports), a long block, and the rest scattered
    as sample_scene scatters them."""
    parts = len(UNITS[unit])
    if num_objects < parts + 1:
        raise SceneError(f"a start with {unit} needs {parts + 1} or more objects, got "
                         f"{num_objects}")

    def kind(i: int) -> str:
        return "long" if i == 0 or rng.random() < long_fraction else "cube"

    supports = sample_structured_scene(rng, parts, units=(unit,)).objects
    return validate_scene(Scene(_scatter(rng, supports, num_objects - parts, kind,
                                         min_gap=0.03)))


def sample_towers_scene(rng: np.random.Generator, num_objects: int,
                        long_fraction: float = 0.5) -> Scene:
    """A start with two towers of two cubes side by side (UNITS["towers_side"]), a long
    block, and the rest scattered: a scene in which one random action (the block onto a
    top) can build a bridge on towers, which scenes of scattered boxes almost never give."""
    return _supports_scene(rng, num_objects, "towers_side", long_fraction)


def sample_cubes_scene(rng: np.random.Generator, num_objects: int,
                       long_fraction: float = 0.5) -> Scene:
    """A start with two cubes side by side (UNITS["cubes_side"]), a long block, and the
    rest scattered: one random action (the block onto a cube, towards the other) builds a
    bridge over two cubes, which scattered starts give too rarely for an operator."""
    return _supports_scene(rng, num_objects, "cubes_side", long_fraction)


# The starts an exploration episode can be given (data/exploration.EpisodeConfig.start).
STARTS = {"random": sample_scene, "towers": sample_towers_scene,
          "cubes": sample_cubes_scene}
