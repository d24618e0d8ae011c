"""Random exploration: episodes of random actions, recorded as perceived transitions.

An episode puts a random scene on the table (scattered boxes, or with `start` "towers"
or "cubes" two towers or two cubes side by side among them: world/scenes.STARTS) and executes up to `length` actions chosen by
an explorer over the objects the robot perceives: by default random ones (source !=
target, grasp and release offsets uniform); `explorers/` has the active one. Each action is perceived before, at the end of the lift and after; the
'after' scene of one action is the 'before' of the next. A transition records the
*relevant* objects only (paper, Experiment Setup):

- Relevance: the action's arguments plus every object the perception finds in contact with
  either of them in the scene *before* the action. This is what the robot knows when it
  chooses the action, and what the planner can compute in a symbolic state; an object that
  comes into contact only as a result of the action is left out.
- State / next state: the perceived features of those objects before / after.
- Effect per object (metres, actions.EFFECT_DIM): e_lift = p_lift - p_before and
  e_release = p_after - p_lift - carry, where carry is the TCP's lateral travel (release
  point - grasp point, from the action and the beliefs) for objects that went up with the
  lift (e_lift z > LIFT_TOL) and 0 for the others.
- Outcome class (for statistics and back-end parity, from perceived scenes): see `classify`.
- The whole scene (for multi-step problems and contact-aware operators): every perceived
  object's features before and after, and the perceived contact pairs before and after,
  in slots that keep an object's identity through the episode (`SceneRecord`); `slots`
  says which scene slot each relevant object is. Identities follow perception's
  association from one action to the next; when the robot loses track the identities are
  renumbered and `chain` counts up, so steps t..t+k of one chain are one object set.

Perception failures: the robot knows how many boxes it put on the table. When the scene
perceived after an action holds more boxes, or loses one that did not leave the table, the
action is not recorded (`skipped`, by reason) and the robot has lost track: it goes on
acting on what it sees, perceiving each new scene from scratch (no prior), and records
again once it sees every box. Dropping the episode instead would lose the rest of it, and
bias the data against the cluttered, stacked scenes that late steps build.

Episodes end after `length` actions, when an object leaves the table (or the cameras'
workspace), or when something fails before that (the episode is then *dropped*: its
remaining actions are never run; transitions recorded before the failure are kept, each
having been checked on its own). An episode that runs all `length` actions but is still
lost at the end ends "length_unrecovered": it is not dropped, and the actions it could not
record are counted in `skipped` like those of an episode that recovered. Running out of
boxes to act on while lost (fewer than two seen) ends it early: "perception_unrecovered".
"""

from __future__ import annotations

import dataclasses as dc
from collections import Counter
from collections.abc import Callable

import numpy as np

from drake_symplan.actions import (
    EFFECT_DIM,
    LIFT_TOL,
    OFFSETS,
    Action,
    encode_action,
    relevant_objects,
)
from drake_symplan.boxes import CONTACT_TOLERANCE, neighbour_pairs
from drake_symplan.perception.perceive import associate
from drake_symplan.perception.segmentation import CROP_X, CROP_Y
from drake_symplan.robot.backends import PerceptionFailure
from drake_symplan.skills.geometry import action_geometry
from drake_symplan.world.scenes import STARTS

NO_EFFECT_TOL = 0.01  # m: nothing moved more than this
TIP_TOL = np.radians(15.0)  # tilt gained by an object that tipped over
# Ends of an episode; the DROP_REASONS ones are failures.
DROP_REASONS = ("sim_failure", "perception_initial_count", "perception_unrecovered",
                "perception_error", "too_many_infeasible")
TABLE_X, TABLE_Y = (-0.3, 1.3), (-0.7, 0.7)  # the table top (models/table/table.sdf)


@dc.dataclass
class EpisodeConfig:
    min_objects: int = 2
    max_objects: int = 4
    length: int = 10  # actions per episode before a new scene
    long_fraction: float = 0.5
    max_infeasible: int = 10  # unreachable actions in a row before giving up the episode
    # Relevance: contact (boxes.CONTACT_TOLERANCE) or vicinity (a wider radius, m); the
    # recorded scenes' "contacts" are this relevance graph (boxes.neighbour_pairs).
    relevance_radius: float = CONTACT_TOLERANCE
    start: str = "random"  # how an episode's scene is set (world/scenes.STARTS)


MAX_SCENE_OBJECTS = 8  # scene slots stored per transition (scenes hold 2-8 objects)


@dc.dataclass
class SceneRecord:
    """The whole perceived scene around one transition, in identity slots."""

    state: np.ndarray  # [MAX_SCENE_OBJECTS, d_o] features before (zeros where no object)
    next_state: np.ndarray  # [MAX_SCENE_OBJECTS, d_o] after
    mask: np.ndarray  # [MAX_SCENE_OBJECTS] bool
    contacts: np.ndarray  # [MAX_SCENE_OBJECTS, MAX_SCENE_OBJECTS] bool, before (symmetric)
    next_contacts: np.ndarray  # after
    slots: np.ndarray  # [k] scene slot of each relevant object
    chain: int  # identity chain within the episode (renumbered after lost tracking)


@dc.dataclass
class Transition:
    names: list[str]  # perceived names of the relevant objects, in slot order
    state: np.ndarray  # [k, d_o]
    action: np.ndarray  # [k, ACTION_DIM]
    effect: np.ndarray  # [k, EFFECT_DIM]
    next_state: np.ndarray  # [k, d_o]
    outcome: str
    episode: int
    step: int
    scene: SceneRecord | None = None
    mode: str = "random"  # how the explorer chose the action


@dc.dataclass
class EpisodeLog:
    transitions: list[Transition] = dc.field(default_factory=list)
    end: str = "length"  # "length" | "length_unrecovered" | "budget" | "left_table" | DROP_REASONS
    outcomes: Counter = dc.field(default_factory=Counter)  # every executed action
    infeasible: int = 0
    skipped: Counter = dc.field(default_factory=Counter)  # executed, not recorded: why
    error: str = ""  # what perception raised, when it ended the episode

    @property
    def dropped(self) -> bool:
        return self.end in DROP_REASONS


def random_action(rng: np.random.Generator, names: list[str]) -> Action:
    s, t = rng.choice(len(names), size=2, replace=False)
    return Action(names[s], OFFSETS[rng.integers(3)], names[t], OFFSETS[rng.integers(3)])


def random_choice(rng: np.random.Generator, scene) -> tuple[Action, str]:
    """The random explorer: a uniform action over the perceived objects. An explorer is a
    callable (rng, perceived scene) -> (action, how it was chosen)."""
    return random_action(rng, scene.names), "random"


def scene_record(before, after, after_map, ids: dict[str, int], names: list[str],
                 chain: int, radius: float = CONTACT_TOLERANCE) -> SceneRecord:
    """The scene before and after in identity slots `ids` (perceived name before -> slot),
    its pairs those of the relevance graph at `radius`."""
    d = before.objects[0].features.shape[0]
    m = MAX_SCENE_OBJECTS
    state, next_state = np.zeros((m, d), np.float32), np.zeros((m, d), np.float32)
    mask = np.zeros(m, bool)
    for name, i in ids.items():
        state[i] = before.object(name).features
        next_state[i] = after.object(after_map[name]).features
        mask[i] = True
    back = {v: k for k, v in after_map.items()}
    contacts, next_contacts = np.zeros((m, m), bool), np.zeros((m, m), bool)
    for a, b in neighbour_pairs(before, radius):
        contacts[ids[a], ids[b]] = contacts[ids[b], ids[a]] = True
    for a, b in neighbour_pairs(after, radius):
        if a in back and b in back:
            i, j = ids[back[a]], ids[back[b]]
            next_contacts[i, j] = next_contacts[j, i] = True
    return SceneRecord(state, next_state, mask, contacts, next_contacts,
                       np.array([ids[k] for k in names], np.int8), chain)


def effects(before, lift, after, lift_map, after_map, names, carry_xy) -> np.ndarray:
    """[len(names), EFFECT_DIM]: [p_lift - p_before ; p_after - p_lift - carry if lifted]."""
    out = np.zeros((len(names), EFFECT_DIM), np.float32)
    carry = np.array([carry_xy[0], carry_xy[1], 0.0])
    for i, n in enumerate(names):
        p0 = before.object(n).position
        p1 = lift.object(lift_map[n]).position
        p2 = after.object(after_map[n]).position
        e_lift = p1 - p0
        out[i, :3] = e_lift
        out[i, 3:] = p2 - p1 - (carry if e_lift[2] > LIFT_TOL else 0.0)
    return out


def classify(before, lift, after, lift_map, after_map, left_table: bool = False) -> str:
    """The outcome class of an action, from the perceived scenes (first match wins):

    fell_off (an object left the table), carried_along (two or more objects went up with
    the lift: a stacked object rode along), tipped (something went up and an object
    ended >= 15 deg more tilted), placed (something went up and came down upright),
    no_effect (nothing moved more than 1 cm), other (moved without a lift: pushed).
    """
    if left_table:
        return "fell_off"
    lifted = [n for n in before.names if n in lift_map
              and lift.object(lift_map[n]).position[2] - before.object(n).position[2] > LIFT_TOL]
    if len(lifted) >= 2:
        return "carried_along"
    if lifted:
        tipped = any(after.object(after_map[n]).tilt - before.object(n).tilt > TIP_TOL
                     for n in before.names if n in after_map)
        return "tipped" if tipped else "placed"
    moved = max((np.linalg.norm(after.object(after_map[n]).position - before.object(n).position)
                 for n in before.names if n in after_map), default=0.0)
    return "no_effect" if moved < NO_EFFECT_TOL else "other"


def left_workspace(truth: dict) -> bool:
    """Ground truth (bookkeeping): has an object left the table or the cameras' workspace?"""
    for s in truth.values():
        x, y, z = s.position
        if z < -0.01 or not (TABLE_X[0] < x < TABLE_X[1] and TABLE_Y[0] < y < TABLE_Y[1]):
            return True
        if not (CROP_X[0] < x < CROP_X[1] and CROP_Y[0] < y < CROP_Y[1]):
            return True
    return False


def run_episode(
    backend,
    rng: np.random.Generator,
    config: EpisodeConfig,
    episode: int,
    budget: int,
    on_transition: Callable[[], None] | None = None,
    choose: Callable = random_choice,
) -> EpisodeLog:
    """Runs one episode on `backend`, recording at most `budget` transitions; `choose` is
    the explorer (random_choice's contract).

    Perception raising on a scene (PerceptionFailure) ends the episode as dropped
    ("perception_error"); the transitions recorded before it are kept."""
    log = EpisodeLog()
    try:
        _act(backend, rng, config, episode, budget, on_transition, log, choose)
    except PerceptionFailure as e:
        log.end, log.error = "perception_error", str(e)
    return log


def _act(backend, rng, config: EpisodeConfig, episode: int, budget: int, on_transition,
         log: EpisodeLog, choose: Callable) -> None:
    """run_episode's actions: records into `log` and sets how the episode ended."""
    n = int(rng.integers(config.min_objects, config.max_objects + 1))
    backend.reset(STARTS[config.start](rng, n, long_fraction=config.long_fraction))
    before = backend.perceive()
    if len(before.objects) != n:
        log.end = "perception_initial_count"
        return
    step, lost = 0, False
    ids, chain = None, -1  # perceived name -> identity slot; None: renumber at next record
    while step < config.length:
        if len(log.transitions) >= budget:
            log.end = "budget"
            return
        if len(before.objects) < 2:  # lost track, and no action to try on what is seen
            log.end = "perception_unrecovered"
            return
        executed = _execute_chosen_action(backend, rng, config, before, log, choose)
        if executed is None:
            return
        action, result, mode = executed
        step += 1
        lift, after = result.lift, result.after
        if lost:
            after = backend.perceive()  # `before` is wrong: it must not anchor this one
        missing = len(after.objects) < n
        if missing and left_workspace(backend.ground_truth_states()):
            log.outcomes["fell_off"] += 1
            log.skipped["left_table"] += 1
            log.end = "left_table"
            return
        if lost or len(after.objects) != n:
            log.skipped["perception_recovering" if lost else "perception_lost_object"
                        if missing else "perception_count_mismatch"] += 1
            lost = len(after.objects) != n
            before, ids = after, None
            continue
        after_map = associate(before, after, action)
        if ids is None:
            ids, chain = {k: i for i, k in enumerate(before.names)}, chain + 1
        _record(log, action, before, lift, after, after_map, ids=ids, chain=chain,
                episode=episode, step=step - 1, mode=mode, on_transition=on_transition,
                radius=config.relevance_radius)
        ids = {after_map[k]: i for k, i in ids.items()}
        before = after
    if lost:
        log.end = "length_unrecovered"


def _execute_chosen_action(backend, rng, config: EpisodeConfig, before, log: EpisodeLog,
                           choose: Callable):
    """Executes the explorer's actions on the `before` scene until one is feasible; returns
    it, its result and how it was chosen, or None when the episode ends (too many
    infeasible in a row, or a sim failure)."""
    infeasible_run = 0
    while True:
        action, mode = choose(rng, before)
        result = backend.execute(action, before)
        if result.status != "infeasible":
            break
        log.infeasible += 1
        infeasible_run += 1
        if infeasible_run >= config.max_infeasible:
            log.end = "too_many_infeasible"
            return None
    if result.status != "ok":
        log.end = "sim_failure"
        return None
    return action, result, mode


def _record(log: EpisodeLog, action: Action, before, lift, after, after_map: dict, *,
            ids: dict[str, int], chain: int, episode: int, step: int, mode: str,
            on_transition, radius: float = CONTACT_TOLERANCE) -> None:
    """Counts the action's outcome and records its transition (unless the lift scene lost
    one of the relevant objects)."""
    lift_map = associate(before, lift, action) if lift is not before else \
        {k: k for k in before.names}
    outcome = classify(before, lift, after, lift_map, after_map)
    log.outcomes[outcome] += 1
    names = relevant_objects(before, action, neighbour_pairs(before, radius))
    if any(k not in lift_map for k in names):
        log.skipped["lift_unobserved"] += 1
        return
    carry_xy = action_geometry(action, before.object_states()).carry_xy
    log.transitions.append(Transition(
        names=names,
        state=np.stack([before.object(k).features for k in names]),
        action=encode_action(action, names),
        effect=effects(before, lift, after, lift_map, after_map, names, carry_xy),
        next_state=np.stack([after.object(after_map[k]).features for k in names]),
        outcome=outcome, episode=episode, step=step,
        scene=scene_record(before, after, after_map, ids, names, chain, radius), mode=mode,
    ))
    if on_transition:
        on_transition()
