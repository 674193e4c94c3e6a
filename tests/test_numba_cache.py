"""numba's cache survives faults: a corrupt entry, no writable cache folder, a callee
edited in another file.

(A training's faults, kills, signals and corrupt checkpoints, are tested in
``tests/training/``.)
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

_KERNEL = """
import numpy as np
import aldm_gym._numba  # the guards (aldm_gym/__init__.py imports it first)
from aldm_gym.sensor.trajectory import _cubic_ok
print(bool(_cubic_ok(np.zeros((5, 2)))))
"""


def _run_kernel(env: dict[str, str], cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", _KERNEL], capture_output=True, text=True, env=env, cwd=cwd
    )


def test_a_corrupt_numba_cache_entry_is_recompiled_with_a_warning(tmp_path: Path) -> None:
    # the shipped kernels off: this is numba's own cache (tests/test_kernel_store.py)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "ALDM_GYM_KERNEL_STORE": "off"}
    env.pop("NUMBA_DISABLE_JIT", None)
    first = _run_kernel(env)
    assert first.returncode == 0, first.stderr
    # A cold cache announces the compile, once.
    assert first.stderr.count("aldm-gym: compiling numba kernels") == 1, first.stderr
    (index,) = tmp_path.rglob("trajectory._cubic_ok_py-*.nbi")
    (data,) = tmp_path.rglob("trajectory._cubic_ok_py-*.nbc")
    for broken in (data, index):
        broken.write_bytes(broken.read_bytes()[:7])  # truncated, as by a full disk
        run = _run_kernel(env)
        assert run.returncode == 0 and run.stdout.strip() == "False", run.stderr
        lines = [line for line in run.stderr.splitlines() if "NumbaCacheWarning" in line]
        assert len(lines) == 1 and lines[0].startswith(f"{broken}:0: "), run.stderr
        # The entry was written again: the next run loads it silently.
        again = _run_kernel(env)
        assert again.returncode == 0 and "Warning" not in again.stderr, again.stderr
        assert "compiling" not in again.stderr, again.stderr


def test_without_a_writable_numba_cache_the_kernels_compile_in_memory(tmp_path: Path) -> None:
    """A copy of the package whose __pycache__ folders cannot be created, no user cache
    folder and no NUMBA_CACHE_DIR: numba used to refuse to decorate the kernels."""
    package = Path(__file__).resolve().parents[1] / "aldm_gym"
    copy = tmp_path / "aldm_gym"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__", "_kernels"))
    for folder in [copy, *[p for p in copy.rglob("*") if p.is_dir()]]:
        (folder / "__pycache__").write_text("a file where numba wants a folder")
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "XDG_CACHE_HOME": "/dev/null/cache"}
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    for name in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT"):
        env.pop(name, None)
    run = _run_kernel(env, cwd=tmp_path)
    assert run.returncode == 0 and run.stdout.strip() == "False", run.stderr
    lines = [line for line in run.stderr.splitlines() if "NumbaCacheWarning" in line]
    assert len(lines) == 1 and "compiling aldm_gym's kernels in memory" in lines[0]


_CALLER = """
import numpy as np
import aldm_gym._numba  # the guards (aldm_gym/__init__.py imports it first)
from aldm_gym.sensor.aldm_kernels.robust import _seed_chains
xs = np.array([1.0, 2.0, 3.0]); ys = np.array([0.0, 0.1, 5.0])
print(_seed_chains(xs, ys, 3, 4.5, 1.5).tolist())
"""


def test_a_kernel_is_recompiled_when_a_kernel_it_calls_changes(tmp_path: Path) -> None:
    """numba keys a cached kernel by its own file's time and size: ``_seed_chains``
    (robust.py) kept the machine code of ``_bucket_order`` (sort.py) after sort.py
    changed. The package keys every kernel by one digest of all kernel sources."""
    package = Path(__file__).resolve().parents[1] / "aldm_gym"
    copy = tmp_path / "pkg" / "aldm_gym"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__", "_kernels"))
    env = {**os.environ, "PYTHONPATH": str(copy.parent), "NUMBA_CACHE_DIR": str(tmp_path / "c")}
    env.pop("NUMBA_DISABLE_JIT", None)

    def run() -> subprocess.CompletedProcess:
        got = subprocess.run(
            [sys.executable, "-c", _CALLER], capture_output=True, text=True, env=env, cwd=tmp_path
        )
        assert got.returncode == 0 and got.stdout.strip() == "[0, 0, 2]", got.stderr
        return got

    assert "compiling" in run().stderr
    assert "compiling" not in run().stderr
    callee = copy / "sensor" / "aldm_kernels" / "sort.py"
    os.utime(callee, (1.0, 1.0))  # a new time, the same text: still cached
    assert "compiling" not in run().stderr
    callee.write_text(callee.read_text() + "\n# edited\n")
    assert "compiling" in run().stderr  # robust.py did not change, its kernel did
