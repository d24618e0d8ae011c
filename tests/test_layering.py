"""learning, symbolic and planning import without pydrake and without the collection code."""

import subprocess
import sys

# Runs in a fresh interpreter where `import pydrake` fails (a meta-path finder refuses
# it), so a module that needs Drake at import time fails loudly instead of passing
# because Drake happens to be installed here.
CHECK = """
import importlib, pkgutil, sys

class NoDrake:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] == "pydrake":
            raise ImportError(f"{name} is blocked: this import must not need Drake")

sys.meta_path.insert(0, NoDrake())
names = ["drake_symplan.structs", "drake_symplan.shards", "drake_symplan.atomic",
         "drake_symplan.typed_yaml"]
for package in ("learning", "symbolic", "planning"):
    pkg = importlib.import_module(f"drake_symplan.{package}")
    names += [f"drake_symplan.{package}.{m.name}" for m in pkgutil.iter_modules(pkg.__path__)]
for name in names:
    importlib.import_module(name)
leaked = sorted(m for m in sys.modules if m.startswith(("pydrake", "drake_symplan.data",
    "drake_symplan.world", "drake_symplan.skills", "drake_symplan.perception")))
assert not leaked, f"importing {names} imported {leaked}"
importlib.import_module("drake_symplan.data.storage")
assert "pydrake" not in sys.modules
print(len(names))
"""


def test_learning_symbolic_planning_import_without_drake():
    proc = subprocess.run([sys.executable, "-c", CHECK], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert int(proc.stdout) >= 15  # every module of the three packages was imported
