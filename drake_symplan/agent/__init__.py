"""The closed loop, the top layer: it wires the layers below and adds nothing to them.

perceive the goal and the start scene (perception) -> read their symbols (a model bundle:
the trained model, its domain and operators) -> write the problem and plan (planning) ->
execute each step with the robot on the perceived objects (robot.backends: the arm or the
hand) -> after each step perceive again and compare the symbols with what the step's
operator predicted, replanning on a mismatch -> check every object within 5 cm of its
perceived goal position.

- `beliefs`: perceived scenes under the scene files' object names, followed across actions.
- `solve`: `solve(start, goal, bundle, ...)` -> `SolveResult`; `Agent` keeps one station
  for many solves.
- `problems`: random problem sets (a start scene, k random actions, the end state as goal).
- `evaluation`: success rates of model bundles on a problem set, with and without monitoring.
"""
