"""The world layer: the Drake diagram, the bottom of the simulator's stack.

`station` (MultibodyPlant with the UR10 or the hand, table and boxes, SceneGraph, cameras,
Meshcat; reset, settle, step), `scenes` (the scene YAML format, sampling, validation),
`cameras` (depth cameras and noise), `hand` (the collision-free hand), `visualization`
(Meshcat and its HTML recordings).
"""
