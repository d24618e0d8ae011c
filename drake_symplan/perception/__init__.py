"""The perception layer: depth images -> objects, below skills and everything that learns.

The station's depth cameras -> point clouds -> `segmentation` (table removed, clusters) ->
`box_fitting` (the known cube and long-block models fitted) -> `features` (the object
feature vector the models learn from) and the contact graph (boxes.py) ->
`perceive.PerceivedScene`; `tracking` / `association` follow identities across an action.
Nothing downstream reads the simulator's truth; `evaluation` compares with it for tests.
"""
