"""The robot layer: what acts on the table and sees it, above world, skills and perception.

`backends.make_backend("arm" | "hand")` builds a station with cameras and a robot: `reset`
puts a scene on the table, `perceive` returns a PerceivedScene, `execute(action, before)`
runs a pick/place on the perceived objects. Data collection explores with it (data/) and
the agent executes plans with it (agent/).
"""
