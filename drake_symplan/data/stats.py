"""`data stats`: what a collected data set holds, from its shard files alone.

- transitions, episodes, shards;
- outcome_fractions: outcome classes of the stored transitions; executed_outcome_fractions
  also counts the actions that were executed but not stored (an object left the table);
- no_effect_fraction (the peer's random exploration wastes 44 % of its actions);
- objects_histogram: relevant objects per transition;
- dropped episodes (ended by a failure) and why, how every episode ended, skipped
  transitions and unreachable actions;
- perception_failures_per_action: executed actions whose resulting scene perception got
  wrong (a box too many or lost), which the episode skipped and recovered from;
  perception_unrecorded_per_action adds the actions run while track was lost: every
  executed action that perception kept out of the data set;
- worker_seconds and, for data collected since phases were timed, worker_seconds_by_phase:
  physics (simulating), perception (rendering included) and other (planning, features,
  bookkeeping).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from drake_symplan.data import storage
from drake_symplan.data.exploration import DROP_REASONS
from drake_symplan.datasets import OUTCOMES
from drake_symplan.json_files import parse_json

PERCEPTION_FAILURES = ("perception_count_mismatch", "perception_lost_object")


def _fractions(counts: Counter, keys) -> dict[str, float]:
    total = sum(counts.values())
    return {k: round(counts[k] / total, 4) if total else 0.0 for k in keys}


def dataset_stats(data_dir: str | Path) -> dict:
    data_dir = Path(data_dir)
    manifest = storage.read_manifest(data_dir)
    paths = storage.shard_paths(data_dir)
    outcomes, executed, ends, skipped, hist = Counter(), Counter(), Counter(), Counter(), Counter()
    episodes: set[int] = set()
    transitions, infeasible, seconds = 0, 0, 0.0
    phases, untimed, modes = Counter(), 0, Counter()
    for path in paths:
        z = storage.read_shard_arrays(path, ("mask", "episode", "outcome", "info"))
        transitions += len(z["episode"])
        episodes.update(int(e) for e in np.unique(z["episode"]))
        hist.update(int(k) for k in z["mask"].sum(axis=1))
        if "outcome" in z:
            outcomes.update(OUTCOMES[int(i)] for i in z["outcome"])
        if "info" in z:
            info = parse_json(str(z["info"]), f"shard {path}: its info")
            executed.update(info["executed_outcomes"])
            ends.update(info["episode_ends"])
            skipped.update(info["skipped_transitions"])
            infeasible += info["infeasible_actions"]
            seconds += info["seconds"]
            modes.update(info.get("explore_modes", {}))
            if "phase_seconds" in info:
                phases.update(info["phase_seconds"])
            else:
                untimed += 1
    num_episodes = sum(ends.values()) or len(episodes)
    dropped = {k: ends[k] for k in DROP_REASONS if ends[k]}
    failures = sum(skipped[k] for k in PERCEPTION_FAILURES)
    unrecorded = failures + skipped["perception_recovering"]
    actions = sum(executed.values()) + unrecorded
    return {
        "dir": str(data_dir),
        "config": manifest.get("config"),
        "transitions": transitions,
        "episodes": num_episodes,
        "episodes_with_transitions": len(episodes),
        "shards": len(paths),
        "outcome_fractions": _fractions(outcomes, OUTCOMES),
        "executed_outcome_fractions": _fractions(executed, OUTCOMES),
        "no_effect_fraction": _fractions(outcomes, OUTCOMES)["no_effect"],
        "outcome_classes_covered": sorted(k for k in OUTCOMES if outcomes[k]),
        "objects_histogram": {str(k): hist[k] for k in sorted(hist)},
        "dropped_episodes": sum(dropped.values()),
        "dropped_fraction": round(sum(dropped.values()) / num_episodes, 4) if num_episodes
        else 0.0,
        "dropped_reasons": dropped,
        "episode_ends": dict(sorted(ends.items())),
        "skipped_transitions": dict(skipped),
        "perception_failures_per_action": round(failures / actions, 4) if actions else 0.0,
        "perception_unrecorded_per_action": round(unrecorded / actions, 4) if actions else 0.0,
        "infeasible_actions": infeasible,
        "explore_modes": dict(sorted(modes.items())),  # how the recorded actions were chosen
        "worker_seconds": round(seconds, 1),
        "worker_seconds_by_phase": None if untimed or not phases else {
            "physics": round(phases["physics"], 1),
            "perception": round(phases["perception"], 1),
            "other": round(seconds - phases["physics"] - phases["perception"], 1)},
    }


def format_stats(stats: dict) -> str:
    lines = [f"{stats['dir']}: {stats['transitions']} transitions, {stats['episodes']} episodes, "
             f"{stats['shards']} shards",
             "outcomes: " + ", ".join(f"{k} {v:.1%}" for k, v in
                                      stats["outcome_fractions"].items()),
             "objects per transition: " + ", ".join(
                 f"{k}: {v}" for k, v in stats["objects_histogram"].items()),
             f"dropped episodes: {stats['dropped_episodes']} ({stats['dropped_fraction']:.2%}) "
             f"{stats['dropped_reasons']}",
             f"perception failures per action: {stats['perception_failures_per_action']:.2%} "
             f"(skipped, recovered); actions unrecorded because of perception: "
             f"{stats['perception_unrecorded_per_action']:.2%}"]
    if stats.get("explore_modes"):
        lines.append("actions chosen by: " + ", ".join(
            f"{k} {v}" for k, v in stats["explore_modes"].items()))
    phases = stats["worker_seconds_by_phase"]
    if phases:
        total = stats["worker_seconds"] or 1.0
        lines.append(f"worker time: {stats['worker_seconds']:.0f} s (" + ", ".join(
            f"{k} {v / total:.0%}" for k, v in phases.items()) + ")")
    return "\n".join(lines)
