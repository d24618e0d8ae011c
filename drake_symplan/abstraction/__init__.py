"""The abstraction layer: a model bundle's view of perceived scenes, above learning, symbolic
and planning and below the agent; no Drake.

perceived scene (names, features, contacts) -> `Abstraction.read` (learning's read-out) ->
atoms under the bundle's semantics -> `Task` -> `Abstraction.plan` (planning's back-ends on
the bundle's domain) -> typed `Step`s. `operator_eval` measures a bundle at this level on
held-out episodes (`symplan eval operators`).
"""
