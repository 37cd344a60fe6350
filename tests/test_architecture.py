"""The package's layering (docs/concepts/diagrams.md): imports point down,
never in a circle; the Drake-side layers, the training configs and the command line's
modules load no torch; torch is imported by the learning layer only.

The import graph is built from the source with `ast`, counting every import, those inside
functions included: a function-level import still ties two modules together.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mca_drake"
# Bottom to top; the core is every module directly in mca_drake/.
LAYERS = (
    "core",
    "references",
    "perception",
    "platforms",
    "cueing",
    "learning",
    "systems",
    "simulation",
    "live",
    "studies",
    "app",
)


def _modules() -> dict[str, Path]:
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) >= 2 and parts[1] in LAYERS else "core"


def import_graph() -> dict[str, set[str]]:
    """module -> the package modules it imports (a `from package import name` counts as an
    import of the package and, where `name` is a submodule, of that submodule)."""
    modules = _modules()
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for module, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                pytest.fail(f"{module}: relative import (use absolute mca_drake imports)")
            graph[module] |= {t for t in targets if t in modules and t != module}
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as a list of modules, or None."""
    state: dict[str, int] = {}  # 1: on the stack, 2: done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_the_graph_sees_function_level_imports():
    """The oracle itself: a hand-made cycle is found, and an import inside a function (in
    a parsed snippet and in the package) is an edge of the graph."""
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}}
    assert _cycle(graph) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None
    snippet = "def f():\n    if True:\n        from mca_drake.cueing import nmpc\n"
    assert [m for m, _ in _function_level_imports(ast.parse(snippet))] == ["mca_drake.cueing"]
    assert "mca_drake.simulation.plots" in import_graph()["mca_drake.simulation.closed_loop"]


def _function_level_imports(tree: ast.AST) -> list[tuple[str, int]]:
    """(module, line) of every import inside a function body."""
    found = []
    for function in ast.walk(tree):
        if isinstance(function, ast.FunctionDef | ast.AsyncFunctionDef):
            for node in ast.walk(function):
                if isinstance(node, ast.ImportFrom):
                    found.append((node.module or "", node.lineno))
                elif isinstance(node, ast.Import):
                    found += [(alias.name, node.lineno) for alias in node.names]
    return found


def test_function_level_imports_say_why():
    """An import inside a function is for a heavy dependency the caller may not need; a
    comment on its line, or above its block of imports, must say which."""
    silent = []
    for module, path in _modules().items():
        lines = path.read_text().splitlines()
        for target, line in _function_level_imports(ast.parse("\n".join(lines))):
            row = line - 1
            while row > 0 and lines[row - 1].strip().startswith(("import ", "from ")):
                row -= 1
            if "#" not in lines[line - 1] and "#" not in lines[row - 1]:
                silent.append(f"{module}:{line} imports {target}")
    assert not silent, "function-level imports without a comment:\n" + "\n".join(silent)


def test_no_import_cycle():
    cycle = _cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_imports_point_down_the_layers():
    rank = {name: i for i, name in enumerate(LAYERS)}
    upward = [
        f"{module} ({_layer(module)}) imports {target} ({_layer(target)})"
        for module, targets in import_graph().items()
        for target in targets
        if rank[_layer(target)] > rank[_layer(module)]
    ]
    assert not upward, "imports pointing up the layers:\n" + "\n".join(upward)


@pytest.mark.parametrize(
    "modules",
    [
        "mca_drake.systems",
        "mca_drake.cueing",
        "mca_drake.simulation",
        "mca_drake.learning.configs",
        "mca_drake.app.cli",
        # every module of those layers, not just the packages
        ",".join(
            m for m in _modules() if _layer(m) in ("systems", "cueing", "simulation", "references")
        ),
    ],
)
def test_drake_layers_load_no_torch(modules):
    code = (
        "import importlib, sys\n"
        f"for name in {modules!r}.split(','): importlib.import_module(name)\n"
        "print('torch' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "False", f"importing {modules} loaded torch"


# Studies that train torch models themselves (Table II trains and times every plant-model
# candidate); everything else reaches torch through the learning layer.
TORCH_STUDIES = {"mca_drake.studies.table2"}


def test_only_the_learning_layer_imports_torch():
    """torch is a dependency of the learning layer (and of the studies that train): a module
    elsewhere reaches it through that layer's functions, never directly."""
    direct = []
    for module, path in _modules().items():
        if _layer(module) == "learning" or module in TORCH_STUDIES:
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            direct += [f"{module}:{node.lineno}" for n in names if n.split(".")[0] == "torch"]
    assert not direct, "torch imported outside mca_drake.learning:\n" + "\n".join(direct)
