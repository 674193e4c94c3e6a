"""The README is a landing page whose examples run and whose links resolve."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), re.S)


def test_the_readme_is_a_landing_page_with_the_two_commands() -> None:
    text = README.read_text()
    assert len(text.splitlines()) <= 150
    assert "make demo" in text and "make test" in text
    ci = (ROOT / ".ci" / "run").read_text()
    assert "make test\n" in ci  # CI calls the README's test command


@pytest.mark.parametrize("block", _python_blocks(README), ids=lambda b: b.splitlines()[0][:40])
def test_readme_examples_run(block: str, tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-c", block], capture_output=True, text=True, cwd=tmp_path, timeout=300
    )
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.parametrize("page", [README, *sorted((ROOT / "docs").glob("*.md"))], ids=str)
def test_relative_links_resolve(page: Path) -> None:
    missing = []
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
        if "://" in target:
            continue
        if not (page.parent / target).exists():
            missing.append(target)
    assert missing == []


def _figures_script():  # type: ignore[no-untyped-def]
    import importlib.util

    spec = importlib.util.spec_from_file_location("figures", ROOT / "scripts" / "figures.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_the_readme_table_is_what_the_quick_comparison_computes(tmp_path: Path) -> None:
    """``make demo``'s run, recomputed: the README's headline table cannot go stale
    (``make figures`` rewrites it)."""
    figures = _figures_script()
    computed = figures.quick_headline(tmp_path / "quick")
    assert figures.block(README.read_text(), "headline") == computed


def test_every_generated_block_has_its_markers() -> None:
    figures = _figures_script()
    figures.block(README.read_text(), "headline")
    results = (ROOT / "docs" / "results.md").read_text()
    for name in figures.RESULTS_BLOCKS:
        assert figures.block(results, name).startswith("| "), name  # a table
    with pytest.raises(ValueError, match="no <!-- generated:nothing --> block"):
        figures.replace_block("text", "nothing", "x")
