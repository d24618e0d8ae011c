"""Every measurement of the method, one module per level: effects (Table I's effect error
of trained runs), operators (`symplan eval operators`: coverage, precision, symbolic
planning on held-out problems), rollouts (the continuous model's error after k actions),
planning (`symplan eval planning`: the arm on problem sets) and problems (the problem sets,
made by the robot and replayed), perception (perceived boxes against the simulator's
truth: the one place ground truth is read, to measure perception)."""
