"""Goals a person writes: one-line specs compiled into the actions that build an example
(compiler), random goals of a kind (sampling), and problem sets made by the robot (problems).
The relations themselves, and their check, are relations.py's."""
