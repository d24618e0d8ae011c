"""The data layer: random exploration with the robot into (state, action, effect) shards.

robot (arm or hand) on sampled scenes -> `exploration` (random actions on the perceived
objects, effects, the relevant objects) -> `collect` (parallel, resumable chunks, local
workers or Ray) -> shards (`storage`; the format itself is drake_symplan/shards.py, which
learning reads without Drake) -> `stats` (outcomes, perception failures, timing); `parity`
checks that the hand back-end's transitions match the arm's.
"""
