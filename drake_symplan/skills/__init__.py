"""The skills layer: the pick/place action as motions, above the world.

`geometry` (grasp and release points from the perceived objects, and what the arm's own
rules refuse there), `ik` (UR10 inverse kinematics), `pick_place` (the IK-planned joint
trajectory and its execution in full physics) and `hand_place` (the same geometry for the
collision-free hand). The robot layer runs them.
"""
