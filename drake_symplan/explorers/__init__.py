"""Explorers: how collection chooses actions beyond random (active.py), in rounds that
learn from the data so far (rounds.py)."""
