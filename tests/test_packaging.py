"""Packaging: every subpackage and the robot/box models ship in the installed package."""

from __future__ import annotations

import re
from pathlib import Path

from drake_symplan.world.station import models_dir

REPO = Path(__file__).resolve().parents[1]


def _declared_packages() -> set[str]:
    text = (REPO / "pyproject.toml").read_text()
    block = re.search(r"^packages = \[(.*?)\]", text, re.S | re.M).group(1)
    return set(re.findall(r'"([\w.]+)"', block))


def test_every_subpackage_is_declared():
    found = {".".join(p.parent.relative_to(REPO).parts)
             for p in (REPO / "drake_symplan").rglob("__init__.py")}
    assert found - _declared_packages() == set()
    assert "drake_symplan_models" in _declared_packages()


def test_models_are_found_through_the_installed_package():
    root = models_dir()
    for rel in ("package.xml", "ur10/ur10.urdf", "table/table.sdf", "objects/cube.sdf",
                "objects/long_block.sdf"):
        assert (root / rel).is_file(), rel
    assert "<name>drake_symplan_models</name>" in (root / "package.xml").read_text()
