"""The abstraction layer: what the robot learned, as the planner uses it; above learning,
symbolic and planning, below the agent; no Drake.

perceived scene (names, features, contacts) -> `abstraction.Abstraction.read` (learning's
read-out) -> atoms under the bundle's semantics -> `Task` -> `Abstraction.plan` (planning's
back-ends on the bundle's domain) -> typed `Step`s. `continuous` rolls the learned effect
model forward on positions (`stability`: whether a predicted box rests); `bilevel` checks
and completes symbolic plans with it and searches in continuous space. evaluation/operators.py and evaluation/rollouts.py
measure a bundle at this level on held-out episodes.
"""
