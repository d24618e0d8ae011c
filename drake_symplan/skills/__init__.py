"""The skills layer: the pick/place action as motions, above the world.

`ik` (UR10 inverse kinematics), `pick_place` (grasp and release geometry from the perceived
objects, the IK-planned joint trajectory, its execution in full physics) and `hand_place`
(the same geometry for the collision-free hand). The robot layer runs them.
"""
