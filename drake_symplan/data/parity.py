"""Back-end parity: the same (scene, action) pairs on the `hand` and the `arm` back-ends.

For each pair both back-ends reset to the scene and perceive it; the action is drawn over
the hand's perceived names and mapped to the arm's by nearest perceived position. Both
execute it; we compare the outcome classes (exploration.classify) and the effect vectors
of the relevant objects (exploration.effects; per object the norm of the 6-d difference).
Pairs the arm cannot reach, or whose scene either perception miscounts, are skipped and
counted. Agreement is also reported apart for the pairs whose source carries something
(the hand's perceived scene has a box resting on it: skills/carry.riders) and the rest.
Scenes come from `scenes.sample_scene` or, when given, a fixed list; `played=True` takes
instead the states random play reaches (leaning blocks, stacks, what lies where the last
actions dropped it: `played_states`), put on both stations as simulated. A measurement for
tools/bench_collect.py (`--parity-pairs`) and test_data_collect; the pipeline does not use it.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
from tqdm import tqdm

from drake_symplan.actions import Action, relevant_objects
from drake_symplan.data.exploration import classify, effects, random_action
from drake_symplan.perception.matching import match_by_position
from drake_symplan.perception.perceive import associate
from drake_symplan.relations import riders
from drake_symplan.robot.backends import make_backend
from drake_symplan.skills.geometry import action_geometry
from drake_symplan.world.scenes import Scene, sample_scene, sample_structured_scene

PLAY_LENGTH = 6  # random actions per played episode in `played_states`


def _map_names(src_scene, dst_scene) -> dict[str, str]:
    return match_by_position({o.name: o.position for o in src_scene.objects},
                             {o.name: o.position for o in dst_scene.objects})


def compare_pair(hand, arm, scene, action: Action | None, rng) -> dict:
    """One pair: {'status', 'hand', 'arm', 'effect_diff'} (classes and per-object diffs)."""
    out, results = {}, {}
    for backend in (hand, arm):
        if isinstance(scene, Scene):
            backend.reset(scene)
        else:  # a played state: (types, poses) as simulated
            backend.mirror(*scene)
    hb, ab = hand.perceive(), arm.perceive()
    n = len(scene.objects) if isinstance(scene, Scene) else len(scene[0])
    if len(hb.objects) != n or len(ab.objects) != n:
        return {"status": "perception_count_mismatch"}
    if action is None:
        action = random_action(rng, hb.names)
    to_arm = _map_names(hb, ab)
    actions = {"hand": action, "arm": Action(to_arm[action.source], action.grasp,
                                             to_arm[action.target], action.release)}
    for name, backend, before in (("hand", hand, hb), ("arm", arm, ab)):
        a = actions[name]
        r = backend.execute(a, before)
        if r.status != "ok":
            return {"status": f"{name}_{r.status}", "message": r.message}
        after_map = associate(before, r.after, a)
        lift_map = associate(before, r.lift, a) if r.lift is not before else \
            {k: k for k in before.names}
        if len(after_map) < n or len(lift_map) < n:
            return {"status": f"{name}_lost_object"}
        names = relevant_objects(before, a)
        carry = action_geometry(a, before.object_states()).carry_xy
        results[name] = (
            classify(before, r.lift, r.after, lift_map, after_map),
            effects(before, r.lift, r.after, lift_map, after_map, names, carry), names)
    out["status"] = "ok"
    out["action"] = str(action)
    out["carries"] = bool(riders(action.source, hb.object_states()))
    out["hand"], out["arm"] = results["hand"][0], results["arm"][0]
    # Compare effects object by object (hand names mapped to the arm's).
    e_hand = dict(zip(results["hand"][2], results["hand"][1], strict=True))
    e_arm = dict(zip(results["arm"][2], results["arm"][1], strict=True))
    out["effect_diff"] = [float(np.linalg.norm(e - e_arm[to_arm[k]]))
                          for k, e in e_hand.items() if to_arm[k] in e_arm]
    return out


def played_states(hand, count: int, rng, objects: tuple[int, int]) -> list[tuple[dict, dict]]:
    """`count` states (types, poses: simulator truth, as a scene file holds it) that random
    play on the `hand` back-end reaches, PLAY_LENGTH actions per episode from sampled scenes;
    each the state before one of the episode's actions."""
    states = []
    while len(states) < count:
        hand.reset(sample_scene(rng, int(rng.integers(objects[0], objects[1] + 1))))
        for _ in range(PLAY_LENGTH):
            poses, types = hand.ground_truth_poses()
            states.append((types, poses))
            before = hand.perceive()
            if len(before.names) < 2 or len(states) >= count:
                break
            if hand.execute(random_action(rng, before.names), before, lift=False).status \
                    == "sim_failure":
                break
    return states


def measure_parity(pairs: int, seed: int = 0, objects: tuple[int, int] = (2, 4),
                   scenes_actions: list | None = None, progress: bool = False,
                   structured: bool = False, played: bool = False,
                   arm_twin: bool = True) -> dict:
    """Runs `pairs` random pairs (or the given (scene, action) list); the parity report.
    `structured`: the scenes are stacks, bridges and touching pairs (sample_structured_scene),
    where sources carry something, rather than boxes apart (sample_scene); `played`: the
    states random play reaches (`played_states`, played by the hand without its twin).
    `arm_twin=False`: the hand measured without its
    arm twin (skills/arm_twin.py), as it was before it."""
    hand, arm = make_backend("hand", arm_twin=arm_twin), make_backend("arm")
    rng = np.random.default_rng(seed)
    if scenes_actions is None and played:
        # Played by the hand without its twin whatever is measured: one seed, one set of
        # states and actions, so runs with and without the twin compare pair by pair.
        player = make_backend("hand", arm_twin=False)
        scenes_actions = [(s, None) for s in played_states(player, pairs, rng, objects)]
    if scenes_actions is None:
        sample = sample_structured_scene if structured else sample_scene
        scenes_actions = [(sample(rng, int(rng.integers(objects[0], objects[1] + 1))), None)
                          for _ in range(pairs)]
    iterator = scenes_actions
    if progress:
        iterator = tqdm(scenes_actions, desc="parity", unit="pair")
    rows, skipped, confusion = [], Counter(), Counter()
    for scene, action in iterator:
        r = compare_pair(hand, arm, scene, action, rng)
        if r["status"] != "ok":
            skipped[r["status"]] += 1
            continue
        rows.append(r)
        confusion[f"{r['hand']}|{r['arm']}"] += 1
    diffs = np.array([d for r in rows for d in r["effect_diff"]])
    carrying = [r for r in rows if r["carries"]]
    return {
        "pairs": len(rows),
        "skipped": dict(skipped),
        "class_agreement": _agreement(rows),
        "carrying": {"pairs": len(carrying), "class_agreement": _agreement(carrying)},
        "not_carrying": {"pairs": len(rows) - len(carrying),
                         "class_agreement": _agreement([r for r in rows if not r["carries"]])},
        "effect_diff_median_m": round(float(np.median(diffs)), 5) if len(diffs) else None,
        "effect_diff_p90_m": round(float(np.percentile(diffs, 90)), 5) if len(diffs) else None,
        "confusion": dict(sorted(confusion.items())),
        "rows": rows,
    }


def _agreement(rows: list[dict]) -> float | None:
    """The share of `rows` whose hand and arm outcome classes agree (None: no rows)."""
    return round(sum(r["hand"] == r["arm"] for r in rows) / len(rows), 4) if rows else None
