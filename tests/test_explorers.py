"""The active explorer's choices with known answers: babbled goals valued by how the
operators reach them, ensemble disagreement, and the rounds' arithmetic."""

import numpy as np
import pytest
import torch

from drake_symplan.abstraction.continuous import Boxes, ContinuousModel
from drake_symplan.actions import EFFECT_DIM, IS_SOURCE, Action
from drake_symplan.explorers.active import (
    ActiveConfig,
    all_actions,
    babble_goals,
    goal_values,
    ground_steps,
    pursue,
)
from drake_symplan.symbolic.structs import Atom, LiftedOperator


def operator(index, pre, add, delete=(), applicable=20, succeeded=20, n_params=2,
             grasp="center", release="center"):
    return LiftedOperator(index, grasp, release, n_params, pre, add, delete, count=applicable,
                          applicable=applicable, succeeded=succeeded)


# Two boxes a, b apart on the table (touching0 each). Stacking one on the other (r0) is
# reliable; making one "p1" is unreliable (3 of 10); nothing makes "p0".
STATE = frozenset({Atom("touching0", "a"), Atom("touching0", "b"), Atom("not_p0", "a"),
                   Atom("not_p0", "b"), Atom("not_p1", "a"), Atom("not_p1", "b")})
STACK = operator(0, [("touching0", 0), ("touching0", 1)],
                 [("r0", 0, 1), ("touching1", 0), ("touching1", 1)],
                 [("touching0", 0), ("touching0", 1)], applicable=20, succeeded=19)
FLIP = operator(1, [("not_p1", 0)], [("p1", 0)], [("not_p1", 0)], applicable=10,
                succeeded=3, grasp="left")


def test_steps_are_the_operators_whose_preconditions_hold_for_distinct_objects():
    steps = ground_steps([STACK, FLIP], STATE, ("a", "b"))
    assert sorted(str(s) for s in steps) == [
        "(pick_center_place_center_n20_op0 a b)", "(pick_center_place_center_n20_op0 b a)",
        "(pick_left_place_center_n10_op1 a b)", "(pick_left_place_center_n10_op1 b a)"]
    assert ground_steps([STACK], STATE - {Atom("touching0", "b")}, ("a", "b")) == []


def test_a_goal_the_operators_cannot_reach_is_chosen_over_one_they_reach_reliably():
    steps = ground_steps([STACK, FLIP], STATE, ("a", "b"))
    reliable, unreachable = frozenset({Atom("r0", "a", "b")}), frozenset({Atom("p0", "a")})
    assert goal_values([reliable, unreachable], steps, STATE) == pytest.approx([0.05, 1.0])
    goal, step = pursue([reliable, unreachable], steps, STATE)
    assert goal == unreachable and step is None


def test_a_goal_reached_unreliably_is_pursued_with_the_step_that_reaches_it():
    steps = ground_steps([STACK, FLIP], STATE, ("a", "b"))
    unreliable = frozenset({Atom("p1", "b")})
    goal, step = pursue([frozenset({Atom("r0", "b", "a")}), unreliable], steps, STATE)
    assert goal == unreliable
    assert step.action == Action("b", "left", "a", "center")


def test_babbled_goals_ask_for_what_does_not_hold_and_never_contradict_themselves():
    rng = np.random.default_rng(0)
    goals = babble_goals(rng, STATE, ("a", "b"), [("p1", 1), ("not_p1", 1), ("r0", 2)], 200)
    assert goals and all(1 <= len(g) <= 2 for g in goals)
    atoms = set().union(*goals)
    assert atoms == {Atom("p1", "a"), Atom("p1", "b"), Atom("r0", "a", "b"),
                     Atom("r0", "b", "a")}  # not_p1 holds already for both
    assert babble_goals(rng, STATE, ("a", "b"), [("not_p1", 1)], 5) == []


class Shifts(torch.nn.Module):
    """A hand-written effect model: the source rises 10 cm with the hand and comes down 5
    cm onto the target's top (a placement; cubes of 5 cm), and moves `shift` m along x
    after the release when it is grasped at its left end."""

    def __init__(self, shift: float):
        super().__init__()
        self.shift = shift

    def forward(self, state, action, mask):
        effect = torch.zeros(*state.shape[:2], EFFECT_DIM)
        effect[..., 2] = 0.1 * action[..., IS_SOURCE]
        effect[..., 5] = -0.05 * action[..., IS_SOURCE]
        effect[..., 3] = self.shift * action[..., IS_SOURCE + 1]  # grasp = left
        return effect


def test_ensemble_disagreement_ranks_the_action_the_members_dispute_first():
    features = np.zeros((2, 9), np.float32)
    features[:, 3] = features[:, 7] = 1.0  # upright cubes
    features[1, 0] = 0.3
    boxes = Boxes(("a", "b"), features, frozenset())
    actions = all_actions(("a", "b"))
    model = ContinuousModel([Shifts(0.0), Shifts(0.04)], snap=0.0)  # as the explorer asks
    scores = model.disagreement(boxes, actions)
    ranked = [actions[i] for i in np.argsort(-scores, kind="stable")]
    assert {a.grasp for a in ranked[:6]} == {"left"}  # each member 2 cm from their mean
    assert scores.max() == pytest.approx(0.02)
    assert sorted(scores)[:12] == pytest.approx([0.0] * 12)
    assert ContinuousModel([Shifts(0.04)]).disagreement(boxes, actions).max() == 0.0


def test_rounds_split_the_transitions_and_train_fewer_epochs_as_data_grows():
    c = ActiveConfig(warmup=1000, round_size=500, epochs=30)
    assert [c.round_end(r) for r in range(3)] == [1000, 1500, 2000]
    assert c.epochs_for(1000) == 30  # round 1 learns the warm-up from scratch
    assert c.epochs_for(5000) == 3 and c.epochs_for(2000) == 8
    with pytest.raises(ValueError, match="at least 2"):
        ActiveConfig(members=1)
    with pytest.raises(ValueError, match="p_random"):
        ActiveConfig(p_random=0.7, p_goal=0.5)


def _active_cmd(out, n):
    import sys

    return [sys.executable, "-m", "drake_symplan.cli.main", "collect", "--backend", "hand",
            "--explorer", "active", "--transitions", str(n), "--warmup", "12",
            "--round-size", "8", "--chunk-size", "4", "--episode-length", "2",
            "--round-epochs", "3", "--members", "2", "--workers", "1", "--out", str(out),
            "--seed", "5", "--objects", "2-3", "--no-progress", "--json"]


@pytest.mark.slow
def test_an_active_collection_resumed_after_a_kill_holds_the_same_data(tmp_path):
    import json
    import os
    import signal
    import subprocess
    import time

    from drake_symplan.data.storage import existing_shards

    n = 28  # the random warm-up (12), then rounds 1 and 2 (8 each)
    straight, killed = tmp_path / "straight", tmp_path / "killed"
    subprocess.run(_active_cmd(straight, n), check=True, capture_output=True, timeout=600)
    proc = subprocess.Popen(_active_cmd(killed, n), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 300
    while time.time() < deadline and not (killed / "active/round-002/runs").exists():
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)  # while round 2's explorer is being learned
    proc.wait()
    assert 3 <= len(existing_shards(killed)) < 7, "the kill missed round 2's learning"
    subprocess.run(_active_cmd(killed, n), check=True, capture_output=True, timeout=600)
    shards = existing_shards(straight)
    assert sorted(shards) == sorted(existing_shards(killed)) == list(range(7))
    for c, path in shards.items():
        with np.load(path) as a, np.load(existing_shards(killed)[c]) as b:
            assert sorted(a.files) == sorted(b.files)
            for key in set(a.files) - {"info"}:  # info holds timings
                assert np.array_equal(a[key], b[key]), (c, key)
            if c >= 3:  # rounds 1 and 2 chose with their explorers, not only at random
                assert set(np.unique(a["explore_mode"])) - {0}
    manifest = json.loads((killed / "manifest.json").read_text())
    rounds = manifest["active_rounds"]
    assert [r["round"] for r in rounds] == [1, 2] and rounds[1]["transitions"] == 20
    assert manifest["config"]["explorer"] == "active" and manifest["status"] == "complete"
