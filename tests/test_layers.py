"""The package's shape: modules import only from the layers before them (road →
sensor → osi → scenario → envs → agents → training → function → harness → cli), and no
modules import each other in a cycle (function-level imports included; ``TYPE_CHECKING``
ones are typing only)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "aldm_gym"
LAYERS = (
    "errors",
    "xmlfile",
    "types",
    "_numba",
    "config",
    "roads",
    "sensor",
    "osi",
    "scenario",
    "envs",
    "agents",
    "training",
    "function",
    "harness",
    "cli",
    "warmup",
    "__main__",
)
"""aldm_gym's top-level modules and subpackages, lowest first."""


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


class _Imports(ast.NodeVisitor):
    """The aldm_gym modules a module imports, anywhere but under ``if TYPE_CHECKING``."""

    def __init__(self, known: dict[str, Path]) -> None:
        self.known = known
        self.found: set[str] = set()

    def visit_If(self, node: ast.If) -> None:
        if "TYPE_CHECKING" in ast.dump(node.test):
            for child in node.orelse:
                self.visit(child)
            return
        self.generic_visit(node)

    def visit_Import(self, node: ast.Import) -> None:
        self.found |= {a.name for a in node.names if a.name in self.known}

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        if node.module and node.module.startswith("aldm_gym"):
            for alias in node.names:
                full = f"{node.module}.{alias.name}"
                self.found.add(full if full in self.known else node.module)


def _graph() -> dict[str, set[str]]:
    known = _modules()
    graph = {}
    for name, path in known.items():
        visitor = _Imports(known)
        visitor.visit(ast.parse(path.read_text(), str(path)))
        graph[name] = {m for m in visitor.found if m in known and m != name}
    return graph


def _layer(module: str) -> int:
    parts = module.split(".")
    return -1 if len(parts) == 1 else LAYERS.index(parts[1])


def test_every_module_belongs_to_a_layer() -> None:
    assert {m.split(".")[1] for m in _graph() if "." in m} <= set(LAYERS)


def test_modules_import_only_from_earlier_layers() -> None:
    graph = _graph()
    upward = sorted((a, b) for a, deps in graph.items() for b in deps if _layer(b) > _layer(a) >= 0)
    assert upward == []


def test_no_import_cycles() -> None:
    graph = _graph()
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert cycles == []
