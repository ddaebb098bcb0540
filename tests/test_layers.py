"""Layers import one way, read from the source: every import of every module of ``kgn_bench`` (module-level
and lazy ones inside functions, relative ones resolved) goes to its own layer or a lower one, the
subpackages' import graph has no cycle, and decoding, training and the dataset format load no simulator.

A unit is a subpackage (``kgn_bench.bench``), a root module (``kgn_bench.cli``, ``kgn_bench.camera``) or the
root package itself (``kgn_bench``); ``LAYERS`` puts every unit on one layer, lowest first.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "kgn_bench"

LAYERS: tuple[tuple[str, ...], ...] = (
    # 0 foundation (numpy only)
    ("kgn_bench", "errors", "io", "geometry", "grasp", "gripper", "resources", "environment", "kernels", "lifecycle",
     "threads", "progress", "pool", "cluster", "camera", "execution", "tsdf", "protocols", "giga"),
    ("types",),
    ("shapes",),
    ("config",),
    ("model",),  # torch, no MuJoCo
    ("sim",),  # MuJoCo
    ("data",),
    ("training",),
    ("detectors",),
    ("viz",),
    ("objects",),
    ("bench",),
    ("eval",),
    ("cli",),
)
"""Every unit's layer, lowest first: a module may import its own layer and the ones before it."""

LAYER = {unit: i for i, units in enumerate(LAYERS) for unit in units}


@dataclass(frozen=True)
class Import:
    """One import statement's target inside ``kgn_bench``: ``source`` imports ``target`` at ``line``."""

    source: str
    target: str
    line: int

    def __str__(self) -> str:
        return f"{self.source} (line {self.line}) imports {self.target}"


def module_names(package: Path = PACKAGE) -> dict[str, Path]:
    """Dotted name → file of every module of the package (``__init__.py`` is the package's own name)."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = [package.name, *path.relative_to(package).with_suffix("").parts]
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The module ``name`` is, or lives in (``kgn_bench.shapes.Cuboid`` → ``kgn_bench.shapes``); None outside."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def imports_of(module: str, path: Path, modules: dict[str, Path]) -> Iterator[Import]:
    """Every import of ``module`` that lands in the package, wherever it stands (functions included)."""
    is_package = path.name == "__init__.py"
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = module.split(".")[: len(module.split(".")) - (node.level - (1 if is_package else 0))]
                base = ".".join([*anchor, *([node.module] if node.module else [])])
            # ``from a import b``: b is a module of a, or a name a defines
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        else:
            continue
        for name in dict.fromkeys(names):  # ``from a import x, y`` is one import of a
            target = _resolve(name, modules) if name.split(".")[0] == "kgn_bench" else None
            if target is not None and target != module:
                yield Import(module, target, node.lineno)


def unit(module: str) -> str:
    """The unit a module belongs to: its subpackage, or itself for a root module, or ``kgn_bench``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def all_imports(package: Path = PACKAGE) -> list[Import]:
    modules = module_names(package)
    return [imp for module, path in modules.items() for imp in imports_of(module, path, modules)]


def upward(imports: list[Import]) -> list[str]:
    """The imports that go to a higher layer than their module's (a unit missing from ``LAYERS`` is one too)."""
    bad = []
    for imp in imports:
        src, dst = unit(imp.source), unit(imp.target)
        if src not in LAYER or dst not in LAYER:
            bad.append(f"{imp}: {src if src not in LAYER else dst} has no layer in LAYERS")
        elif LAYER[dst] > LAYER[src]:
            bad.append(f"{imp}: layer {LAYER[src]} ({src}) imports layer {LAYER[dst]} ({dst})")
    return bad


def unit_graph(imports: list[Import]) -> dict[str, set[str]]:
    """Unit → the other units it imports."""
    graph: dict[str, set[str]] = {}
    for imp in imports:
        src, dst = unit(imp.source), unit(imp.target)
        graph.setdefault(src, set())
        if src != dst:
            graph[src].add(dst)
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph as a path that ends where it starts, or None (depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt):], nxt]
            if nxt not in state and (found := visit(nxt)) is not None:
                return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)) is not None:
            return found
    return None


def test_every_import_stays_in_its_layer_or_below():
    imports = all_imports()
    assert len(imports) > 300  # the walk saw the package's imports (lazy ones included)
    assert not (bad := upward(imports)), "imports up the layers:\n" + "\n".join(bad)


def test_the_subpackage_import_graph_has_no_cycle():
    graph = unit_graph(all_imports())
    assert {"bench", "cli", "training", "camera", "kgn_bench"} <= set(graph)
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph) or [])


def test_no_module_imports_itself_back():
    """No cycle between modules either (``shapes.library`` and ``shapes.mesh_object`` were one)."""
    graph: dict[str, set[str]] = {}
    for imp in all_imports():
        graph.setdefault(imp.source, set()).add(imp.target)
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph) or [])


def _plant(tmp_path: Path, files: dict[str, str]) -> Path:
    root = tmp_path / "kgn_bench"
    for rel, text in {"__init__.py": "", **files}.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return root


def test_the_checker_catches_a_planted_upward_import(tmp_path):
    """A lazy relative import of the eval layer from the model layer, and a cycle between two subpackages."""
    root = _plant(tmp_path, {
        "model/__init__.py": "",
        "model/net.py": "import numpy\n\n\ndef f():\n    from ..eval.vision import evaluate_dataset\n",
        "eval/__init__.py": "",
        "eval/vision.py": "from kgn_bench.model import net\nfrom . import errors\n",
        "eval/errors.py": "",
        "sim/__init__.py": "from kgn_bench.data import format\n",
        "data/__init__.py": "",
        "data/format.py": "from kgn_bench.sim import scene\n",
        "sim/scene.py": "",
    })
    imports = all_imports(root)
    assert {str(i) for i in imports} == {
        "kgn_bench.model.net (line 5) imports kgn_bench.eval.vision",
        "kgn_bench.eval.vision (line 1) imports kgn_bench.model.net",
        "kgn_bench.eval.vision (line 2) imports kgn_bench.eval.errors",
        "kgn_bench.sim (line 1) imports kgn_bench.data.format",
        "kgn_bench.data.format (line 1) imports kgn_bench.sim.scene",
    }
    assert upward(imports) == ["kgn_bench.model.net (line 5) imports kgn_bench.eval.vision: layer 4 (model) imports "
                               "layer 12 (eval)", "kgn_bench.sim (line 1) imports kgn_bench.data.format: layer 5 "
                               "(sim) imports layer 6 (data)"]
    assert find_cycle(unit_graph(imports)) in (["data", "sim", "data"], ["eval", "model", "eval"])


def test_a_unit_without_a_layer_is_reported(tmp_path):
    root = _plant(tmp_path, {"plugins.py": "from kgn_bench import errors\n", "errors.py": ""})
    assert upward(all_imports(root)) == ["kgn_bench.plugins (line 1) imports kgn_bench.errors: plugins has no layer "
                                         "in LAYERS"]


def test_every_unit_has_a_layer():
    units = {unit(m) for m in module_names()}
    assert units == set(LAYER), f"without a layer: {sorted(units - set(LAYER))}; gone: {sorted(set(LAYER) - units)}"


@pytest.mark.parametrize("module", ["kgn_bench.model.decode", "kgn_bench.training.train", "kgn_bench.data.format",
                                    "kgn_bench.training.vgn_train", "kgn_bench.data.vgn_format", "kgn_bench.types",
                                    "kgn_bench.camera"])
def test_module_loads_no_simulator(module):
    code = (f"import sys, {module}; "
            "print(','.join(m for m in ('mujoco', 'dm_control', 'mink', 'kgn_bench.sim.scene') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"{module} loads {out}"


def test_training_loads_no_detector_and_no_evaluation():
    code = ("import sys, kgn_bench.training.train; "
            "print(','.join(m for m in sys.modules if m.startswith(('kgn_bench.detectors', 'kgn_bench.eval', "
            "'kgn_bench.viz'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"kgn_bench.training.train loads {out}"
