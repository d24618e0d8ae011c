"""The package's layers: no module imports a layer above its own, and learning, symbolic,
planning, abstraction and the symbolic-level evaluations import without pydrake and without the collection code."""

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "drake_symplan"

# Lowest first (docs/layout.md). A module may import its own layer and the ones before it.
LAYERS = (
    ("drake_symplan", "actions", "datasets", "boxes", "relations", "features", "atomic",
     "typed_yaml", "json_files", "shards", "cluster"),
    ("world",), ("perception",), ("skills",), ("robot",), ("data",), ("learning",),
    ("symbolic",), ("planning",), ("abstraction",), ("explorers",), ("agent",), ("goals",), ("evaluation",),
    ("pipelines",), ("cli",),
)
RANK = {name: i for i, names in enumerate(LAYERS) for name in names}


def layer_of(module: str) -> str:
    """drake_symplan.symbolic.bundle -> symbolic; drake_symplan -> drake_symplan."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def imports(path: Path) -> set[str]:
    """The drake_symplan modules `path` imports anywhere (function-local imports too)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("drake_symplan"):
            out.add(node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("drake_symplan")}
    return out


def test_no_module_imports_a_layer_above_its_own():
    upward = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        own = layer_of(module.removesuffix(".__init__"))
        assert own in RANK, f"{module}: layer {own!r} is not in LAYERS"
        upward += [f"{module} imports {m}" for m in imports(path)
                   if RANK[layer_of(m)] > RANK[own]]
    assert upward == []


def test_the_layer_check_sees_an_upward_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from drake_symplan.agent.solve import Agent\n")
    assert imports(bad) == {"drake_symplan.agent.solve"}
    assert RANK[layer_of("drake_symplan.agent.solve")] > RANK["symbolic"]

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
names = ["drake_symplan.actions", "drake_symplan.datasets", "drake_symplan.shards", "drake_symplan.atomic",
         "drake_symplan.typed_yaml", "drake_symplan.json_files", "drake_symplan.features", "drake_symplan.boxes",
         "drake_symplan.relations"]
names += ["drake_symplan.evaluation.effects", "drake_symplan.evaluation.operators",
          "drake_symplan.evaluation.rollouts"]  # the Drake-free measurements
for package in ("learning", "symbolic", "planning", "abstraction"):
    pkg = importlib.import_module(f"drake_symplan.{package}")
    names += [f"drake_symplan.{package}.{m.name}" for m in pkgutil.iter_modules(pkg.__path__)]
for name in names:
    importlib.import_module(name)
leaked = sorted(m for m in sys.modules if m.split(".")[0] == "pydrake" or m.split(".")[:2] in
    (["drake_symplan", p] for p in ("data", "world", "skills", "perception")))
assert not leaked, f"importing {names} imported {leaked}"
importlib.import_module("drake_symplan.data.storage")
assert "pydrake" not in sys.modules
print(len(names))
"""


def test_learning_symbolic_planning_abstraction_import_without_drake():
    proc = subprocess.run([sys.executable, "-c", CHECK], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert int(proc.stdout) >= 15  # every module of the three packages was imported
