"""The arm standing in for the hand where the hand would not tell the truth about it.

The hand (world/hand.py) has no wrist and no fingers. Where the arm's wrist, coming down
to its grasp point, would strike a box (a tower on the source rising past the palm, a tall
stack beside the grasp: world/hand.wrist_strikes), or where its fingers would close on the
source and a rider at once (a load with no clear point to grasp: skills/carry.py), the
hand's weld would not behave as the arm does, and the action is run by a twin UR10 station in
full physics instead: the twin takes the hand station's poses and velocities (a scene
may still be settling), executes the arm's own
motion planned from the same beliefs, home to home, and the hand station takes the twin's
poses at the end of the lift (for the camera) and at the end (starting the arm above the
grasp instead saved no measurable time). So whatever the arm knocks over falls in
the data as well.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

from drake_symplan.actions import Action
from drake_symplan.datasets import ObjectState
from drake_symplan.skills.pick_place import PickPlaceMotions, run_motion
from drake_symplan.world.station import Station


def copy_poses(source: Station, target: Station) -> None:
    """Puts every object of `target` at its pose in `source`, at rest."""
    for name, X in source.object_poses().items():
        target.set_object_pose(name, X)


class ArmTwin:
    """A UR10 station built on first use with the hand station's physics settings."""

    def __init__(self):
        self._station: Station | None = None
        self._planner: PickPlaceMotions | None = None
        self.running = False  # the twin is executing an action now
        self.actions = 0  # actions it ran

    @property
    def physics_seconds(self) -> float:
        """Wall time the twin has spent simulating."""
        return self._station.physics_seconds if self._station is not None else 0.0

    def _arm(self, hand: Station) -> Station:
        if self._station is None:
            config = dc.replace(hand.config, robot="ur10", cameras=[], camera_noise="none")
            self._station, self._planner = Station(config), PickPlaceMotions()
        return self._station

    def run(self, hand: Station, action: Action, beliefs: dict[str, ObjectState],
            at_lift: Callable[[], object] | None = None) -> object:
        """Executes `action` on the twin from the hand station's scene, leaves the hand
        station in the twin's end state (at rest, nothing held) and returns `at_lift()`,
        called with the hand station showing the end of the twin's lift.

        Raises InfeasibleAction where the arm cannot reach a waypoint (nothing moved) and
        RuntimeError where its simulation fails."""
        arm = self._arm(hand)
        arm.mirror(dict(hand.types), hand.object_poses(), hand.object_velocities())
        motion = self._planner.plan(action, beliefs, lift_hold=at_lift is not None)

        def lifted():
            copy_poses(arm, hand)
            return at_lift() if at_lift else None

        self.running = True
        try:
            out = run_motion(arm, motion, lifted)
        finally:
            self.running = False
        copy_poses(arm, hand)
        self.actions += 1
        return out
