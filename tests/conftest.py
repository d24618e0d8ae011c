"""Shared fixtures: one station diagram and one IK planner per test session (building is slow)."""

import pytest


@pytest.fixture(scope="session")
def station():
    from drake_symplan.world.station import Station

    return Station()


@pytest.fixture(scope="session")
def planner():
    from drake_symplan.skills.pick_place import PickPlacePlanner

    return PickPlacePlanner()
