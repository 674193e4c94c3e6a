"""How the training package is imported: light, without cycles or private names, and
the deprecated ``aldm_gym.agents`` paths still work with a warning."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "aldm_gym" / "training"

OLD_PATHS = ("training", "rllib", "checkpoints", "callbacks", "sb3", "model_evaluation")
"""The deprecated modules of ``aldm_gym.agents``."""


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """``(module, names)`` of every ``import``/``from ... import`` in ``path``, also
    those inside functions."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.module, [alias.name for alias in node.names]))
        elif isinstance(node, ast.Import):
            found += [(alias.name, []) for alias in node.names]
    return found


def test_import_stays_light() -> None:
    """Building the CLI parser must not import stable-baselines3 or torch."""
    code = (
        "import sys, aldm_gym, aldm_gym.cli as c; c.build_parser(); "
        "print(any(m in sys.modules for m in ('stable_baselines3', 'torch')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_the_training_modules_import_each_other_without_cycles() -> None:
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {
        name: {m for m, _ in _imports(path) if m in modules and m != name}
        for name, path in modules.items()
    }
    done: set[str] = set()

    def visit(name: str, path: tuple[str, ...]) -> None:
        assert name not in path, "import cycle: " + " -> ".join((*path, name))
        if name not in done:
            for other in sorted(graph[name]):
                visit(other, (*path, name))
            done.add(name)

    for name in sorted(graph):
        visit(name, ())


def test_no_private_name_is_imported_from_another_module() -> None:
    private = [
        f"{path.relative_to(ROOT)}: {module}.{name}"
        for folder in (PACKAGE, ROOT / "aldm_gym" / "cli", ROOT / "tests" / "training")
        for path in folder.rglob("*.py")
        for module, names in _imports(path)
        for name in names
        if module.startswith("aldm_gym") and name.startswith("_") and not name.endswith("__")
    ]
    assert private == []


def test_nothing_imports_the_deprecated_paths() -> None:
    old = {f"aldm_gym.agents.{name}" for name in OLD_PATHS}
    users = [
        f"{path.relative_to(ROOT)}: {module}"
        for folder in ("aldm_gym", "benchmarks", "scripts", "tests")
        for path in (ROOT / folder).rglob("*.py")
        if path.parent != ROOT / "aldm_gym" / "agents" and path != Path(__file__)
        for module, _ in _imports(path)
        if module in old
    ]
    assert users == []


def test_the_deprecated_paths_warn_where_they_are_imported() -> None:
    pytest.importorskip("stable_baselines3")  # aldm_gym.agents.callbacks imports it
    code = "\n".join(
        [
            "import warnings",
            "warnings.simplefilter('always')",
            "with warnings.catch_warnings(record=True) as caught:",
            *(f"    import aldm_gym.agents.{name}" for name in OLD_PATHS),
            "for w in caught:",
            "    if w.category is DeprecationWarning and 'aldm_gym.agents' in str(w.message):",
            "        print(w.filename, str(w.message).split(' is ')[0])",
        ]
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.splitlines() == [f"<string> aldm_gym.agents.{name}" for name in OLD_PATHS]


def test_the_deprecated_paths_keep_their_public_names() -> None:
    pytest.importorskip("stable_baselines3")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import aldm_gym.agents.training as old
        from aldm_gym.agents.checkpoints import OutputLocked, load_policy, output_lock
        from aldm_gym.agents.rllib import MODEL_DIR, ClusterError, train_rllib
        from aldm_gym.agents.training import PPOParams, signals_as_interrupt, train
    from aldm_gym.errors import ClusterError as Cluster
    from aldm_gym.errors import OutputLocked as Locked
    from aldm_gym.training.lock import output_lock as lock
    from aldm_gym.training.models import load_policy as load
    from aldm_gym.training.rllib.backend import train_rllib as rllib
    from aldm_gym.training.sb3.backend import train as sb3
    from aldm_gym.training.settings import PPOParams as Params

    assert (OutputLocked, ClusterError, output_lock, load_policy) == (Locked, Cluster, lock, load)
    assert (train, train_rllib, PPOParams, MODEL_DIR) == (sb3, rllib, Params, "rllib_model")
    assert old._linear(2.0, 0.5) == 1.0  # models pickled their schedule under this name
    with signals_as_interrupt():
        pass
