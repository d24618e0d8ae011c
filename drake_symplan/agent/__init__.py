"""The agent layer: the closed loop, at the top; it wires the layers below.

perceive the goal and the start scene (robot + perception; `beliefs` names the boxes after
the scene files) -> an `Abstraction` of a model bundle reads their symbols and plans
(abstraction/) -> each typed step runs with the robot on the perceived objects (robot/),
a plan on symbols completed as it runs (offsets: abstraction/offsets.py; repositionings)
-> after each step perceive again and compare the symbols
with the step's prediction, replanning on a mismatch -> every object within 5 cm of its
perceived goal position.

- `config`: `SolveConfig`, how a solve runs (planner, CPU seconds per plan, monitoring,
  replans, refine, planning mode).
- `planning_modes`: the planning modes (symbolic, bilevel, continuous, oracle), one class
  each, in the `PLANNING_MODES` registry.
- `solve`: `Agent.solve(start, goal, abstraction, config)` -> `SolveResult`.
- `reposition`: repositioning steps (a box put down at its goal spot).
- `problems`: random problem sets (a start scene, k random actions, the end state as goal).
- `evaluation`: success rates of model bundles on a problem set (`symplan eval planning`).
- `inspection`: a scene's symbols and a plan drawn in Meshcat (`symplan inspect`).
"""
