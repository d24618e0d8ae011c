"""The continuous model (abstraction/continuous.py): where its effect models put the boxes."""

from __future__ import annotations

import numpy as np
import torch
from bilevel_fixtures import START, Lifting, boxes

from drake_symplan.abstraction.continuous import ContinuousModel
from drake_symplan.actions import Action


def test_the_continuous_model_carries_a_lifted_box_to_the_release_point():
    model = ContinuousModel(Lifting())
    after = model.predict(START, [Action("a", "center", "c", "left")])[0].where()
    # a: up 10 cm, carried to c shifted 7.5 cm along -y, down 5 cm, its whole footprint
    # beside c's top: it falls to the table.
    assert np.allclose(after["a"], [0.7, -0.075, 0.025], atol=1e-6)
    assert np.allclose(after["c"], [0.7, 0.0, 0.025]) and np.allclose(after["b"], START.where()["b"])
    rolled = model.rollout(START, [Action("a", "center", "c", "center"),
                                   Action("b", "center", "a", "center")])
    # b is carried to where a was predicted to be; this model's heights ignore the target,
    # but b's centre is over a, so b comes to rest on a's top (continuous.rest).
    assert np.allclose(rolled[-1].where()["b"], [0.7, 0.0, 0.125], atol=1e-6)
    assert ("a", "c") in rolled[0].contacts  # contacts of the predicted scene


class Sliding(torch.nn.Module):
    """Lifting, with the source predicted to come down `dy` along y from the release and
    the target predicted to rise with it."""

    def __init__(self, dy: float):
        super().__init__()
        self.dy = dy

    def forward(self, state, action, mask):
        effect = torch.zeros(*state.shape[:2], 6)
        effect[action[:, :, 0] > 0.5] = torch.tensor([0.0, 0.0, 0.10, 0.0, self.dy, -0.05])
        effect[action[:, :, 1] > 0.5] = torch.tensor([0.0, 0.0, 0.10, 0.0, 0.0, -0.10])
        return effect


def test_a_carried_box_lands_at_its_release_unless_predicted_to_fall_off_it():
    def landed(dy):
        return ContinuousModel(Sliding(dy)).predict(
            START, [Action("a", "center", "c", "left")])[0].where()

    # measured (six boxes, 256 steps): the arm sets a box down 2 mm from its release
    # (median), the model's own guess 6 mm; a shift under SNAP is the regression's error
    assert np.allclose(landed(0.012)["a"][:2], [0.7, -0.075], atol=1e-6)
    assert np.allclose(landed(-0.08)["a"][:2], [0.7, -0.075], atol=1e-6)
    assert np.allclose(landed(0.15)["a"][:2], [0.7, 0.075], atol=1e-6)  # falls off: kept
    # the target, predicted to rise, is not carried: the hand holds the source only
    assert np.allclose(landed(0.0)["c"], [0.7, 0.0, 0.025], atol=1e-6)


class Jittering(Lifting):
    """Lifting, with every box the hand does not hold predicted 4 mm along x."""

    def forward(self, state, action, mask):
        effect = super().forward(state, action, mask)
        effect[action[:, :, 0] <= 0.5, 0] += 0.004
        return effect


def test_a_box_the_hand_leaves_stays_where_it_was():
    after = ContinuousModel(Jittering()).predict(START, [Action("a", "center", "c", "center")])
    assert np.allclose(after[0].where()["c"], START.where()["c"])  # the regression's jitter
    asked = ContinuousModel(Jittering(), snap=0.0).predict(
        START, [Action("a", "center", "c", "center")])  # as the explorer asks the members
    assert np.allclose(asked[0].where()["c"], START.where()["c"] + [0.004, 0.0, 0.0])


def test_a_box_over_no_box_rests_on_the_table_and_what_the_hand_carried_settles_last():
    from drake_symplan.abstraction.continuous import rest

    scene = boxes(a=(0.7, 0.0, 0.025), b=(0.7, 0.0, 0.09), c=(0.7, 0.2, 0.09))
    # c, released beside the stack and predicted 9 cm up, is over nothing: on the table
    out = rest(scene.positions.astype(float), scene, moved=[1, 2])
    assert np.allclose(out[:, 2], [0.025, 0.075, 0.025])
    # b carried onto a, a nudged by the model and predicted higher than b: a settles
    # first, b comes down on it
    nudged = boxes(a=(0.705, 0.0, 0.1), b=(0.7, 0.0, 0.06))
    out = rest(nudged.positions.astype(float), nudged, moved=[0, 1], carried={1})
    assert np.allclose(out[:, 2], [0.025, 0.075])


def test_a_box_predicted_over_another_rests_on_it_and_one_over_it_in_part_keeps_its_height():
    from drake_symplan.abstraction.continuous import rest

    scene = boxes(a=(0.7, 0.0, 0.025), b=(0.7, 0.0, 0.075), c=(0.7, 0.01, 0.089),
                  d=(0.5, 0.2, 0.04), e=(0.7, 0.04, 0.06))
    out = rest(scene.positions.astype(float), scene, moved=[2, 3, 4])
    # c, released over the tower a-b, predicted at a mean height no box rests at: on b.
    assert np.allclose(out[2], [0.7, 0.01, 0.125]) and np.allclose(out[:2], scene.positions[:2])
    assert np.allclose(out[3], [0.5, 0.2, 0.025])  # over nothing: on the table
    assert np.allclose(out[4], [0.7, 0.04, 0.06])  # its edge over a: it may lean, as predicted
    # The lowest moved box settles first: a tower predicted low all the way up stacks.
    low = boxes(a=(0.7, 0.0, 0.025), b=(0.7, 0.0, 0.06), c=(0.7, 0.0, 0.07))
    assert np.allclose(rest(low.positions.astype(float), low, [1, 2])[:, 2],
                       [0.025, 0.075, 0.125])


class Staying(torch.nn.Module):
    """An effect model that says: nothing moves (the grasp missed)."""

    def forward(self, state, action, mask):
        return torch.zeros(*state.shape[:2], 6)


def test_an_ensemble_predicts_its_members_mean_and_their_disagreement():
    model = ContinuousModel([Lifting(), Staying()])
    after = model.predict(START, [Action("a", "center", "c", "left")])[0]
    lifted, stayed = np.array([0.7, -0.075, 0.025]), np.array([0.5, 0.2, 0.025])
    assert np.allclose(after.where()["a"], (lifted + stayed) / 2, atol=1e-6)
    half = np.linalg.norm(lifted - stayed) / 2
    assert np.allclose(after.uncertainty(), [half, 0.0, 0.0], atol=1e-6)
    # Along a rollout the spreads add up as independent errors do.
    again = model.predict(after, [Action("a", "center", "c", "left")])[0]
    assert again.uncertainty()[0] > half
    assert ContinuousModel(Lifting()).predict(START, [Action("a", "center", "c", "left")]
                                              )[0].spread is None


def test_a_predicted_scene_keeps_each_box_type_and_yaw_and_takes_its_new_centre():
    from drake_symplan.abstraction.continuous import Boxes
    from drake_symplan.features import box_of, object_features

    yaw = np.pi / 6
    turn = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0],
                     [0.0, 0.0, 1.0]])
    scene = Boxes(("a", "b"), np.stack([
        object_features("long", np.array([0.7, 0.0, 0.025]), turn),
        object_features("cube", np.array([0.5, 0.1, 0.025]), np.eye(3))]), frozenset())
    assert scene.shapes[0][0] == "long"  # read before predicting from it, as the search does
    after = scene.moved(np.array([[0.6, 0.1, 0.075], [0.5, 0.1, 0.025]]))
    for (kind, centre, axes), (read_kind, read_centre, read_axes) in zip(
            after.shapes, map(box_of, after.features), strict=True):
        assert kind == read_kind and np.allclose(centre, read_centre)
        assert np.allclose(axes, read_axes)
    kind, centre, axes = after.shapes[0]
    assert kind == "long" and np.allclose(centre, [0.6, 0.1, 0.075])
    assert np.isclose(np.arctan2(axes[1, 0], axes[0, 0]), yaw)
    assert after.index == {"a": 0, "b": 1}
