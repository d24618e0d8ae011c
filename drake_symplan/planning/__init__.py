"""The planning layer: PDDL in, plan out, behind one registry of back-ends; no Drake.

`planners.PLANNERS` holds Fast Downward (its translator and search as subprocesses) and
pyperplan (in a forked child); `plan` / `plan_pddl` return a PlanResult (solved,
unsolvable, timeout, error) with the plan as PDDL step strings. `grounding` grounds a
task on lifted operators in process and hands it to FD's search binary as SAS+, without
FD's translator (what the agent's plans use). `nodes` tallies the search nodes expanded
(a solve's `nodes`). The abstraction layer above parses the
steps into typed steps of a model's operators.
"""
