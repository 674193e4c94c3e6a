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
    "fmi",
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


ENV_MODULE = "aldm_gym.envs.highway"
"""Where the registry string ``ALDMHighway-v0`` leads: ``gym.make`` of it imports the env."""


class _Imports(ast.NodeVisitor):
    """The aldm_gym modules a module imports, anywhere but under ``if TYPE_CHECKING``;
    a ``gym.make`` of the env's registry id (``"ALDMHighway-v0"`` or ``ENV_ID``)
    counts as an import of the env, which the registry string would hide."""

    def __init__(self, known: dict[str, Path]) -> None:
        self.known = known
        self.found: set[str] = set()

    def visit_If(self, node: ast.If) -> None:
        if "TYPE_CHECKING" in ast.dump(node.test):
            for child in node.orelse:
                self.visit(child)
            return
        self.generic_visit(node)

    def visit_Call(self, node: ast.Call) -> None:
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
        if name == "make" and node.args:
            first = node.args[0]
            if (isinstance(first, ast.Constant) and first.value == "ALDMHighway-v0") or (
                isinstance(first, ast.Name) and first.id == "ENV_ID"
            ):
                self.found.add(ENV_MODULE)
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


def _imports(source: str, known: dict[str, Path]) -> set[str]:
    visitor = _Imports(known)
    visitor.visit(ast.parse(source))
    return visitor.found


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


def test_a_registry_string_is_an_edge_to_the_env() -> None:
    """``gym.make("ALDMHighway-v0")`` in the scenario player would be an upward edge
    (scenario sits below envs): the graph sees it, as it sees an import."""
    known = _modules()
    source = (
        "import gymnasium as gym\n"
        "from aldm_gym import ENV_ID\n"
        "def play():\n"
        "    return gym.make('ALDMHighway-v0'), gym.make(ENV_ID, config={})\n"
    )
    found = _imports(source, known)
    assert ENV_MODULE in found
    assert _layer(ENV_MODULE) > _layer("aldm_gym.scenario.runner")
    assert ENV_MODULE not in _imports("gym.make('CartPole-v1')\n", known)


def test_every_kernel_lives_in_a_layer_the_kernel_digest_covers() -> None:
    """numba freezes the globals a kernel reads into its machine code; the cache's
    digest (``aldm_gym._numba.KERNEL_LAYERS``) covers the layers a kernel can read
    from, which holds only while no kernel lives in a higher layer."""
    from aldm_gym._numba import KERNEL_LAYERS

    def compiles(path: Path) -> bool:  # numba.njit in the code, not in a docstring
        return any(
            isinstance(node, ast.Attribute) and node.attr == "njit"
            for node in ast.walk(ast.parse(path.read_text()))
        )

    kernels = [p for p in PACKAGE.rglob("*.py") if compiles(p)]
    assert kernels
    outside = [
        p.relative_to(PACKAGE).as_posix()
        for p in kernels
        if p.relative_to(PACKAGE).parts[0].removesuffix(".py") not in KERNEL_LAYERS
    ]
    assert outside == [], outside
    assert list(KERNEL_LAYERS[1:]) == list(LAYERS[: LAYERS.index("envs") + 1])
