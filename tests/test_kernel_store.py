"""The shipped kernels (``aldm_gym/_kernels``): compiled ahead of time for a generic
x86-64 CPU, loaded when numba's cache misses, never stale, faults recovered, the same
numbers as this CPU's own compile, and carried by a wheel.

Each test runs child interpreters on a copy of the package (its own store, its own
numba cache folders), except the wheel test, which packs the checkout's store.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from aldm_gym._numba import MANIFEST, STORE, STORE_ENV, store_status

ROOT = Path(__file__).resolve().parents[1]

_KERNEL = """
import numpy as np
import aldm_gym._numba  # the guards (aldm_gym/__init__.py imports it first)
from aldm_gym.sensor.trajectory import _cubic_ok
print(bool(_cubic_ok(np.zeros((5, 2)))))
"""

_FRAME = """
import hashlib
from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor import LineSensor
road = HighwayRoad({"seed": 3, "length": 1500.0})
sensor = LineSensor({"lateral_noise": 0.05, "dropout": 0.1}, seed=0)
h = hashlib.sha256()
for s in (200.0, 650.0, 1100.0):
    pose = (*road.reference.position(s, road.lane_offset(1)), road.reference.heading_at(s))
    h.update(sensor.measure(road, tuple(float(v) for v in pose)).all_points.tobytes())
print(h.hexdigest())
"""


def _package_copy(tmp_path: Path) -> Path:
    """A copy of the package without its caches and without shipped kernels."""
    copy = tmp_path / "pkg" / "aldm_gym"
    shutil.copytree(
        ROOT / "aldm_gym", copy, ignore=shutil.ignore_patterns("__pycache__", "_kernels")
    )
    return copy


def _env(copy: Path, cache: Path | None, **extra: str) -> dict[str, str]:
    env = {**os.environ, "PYTHONPATH": str(copy.parent), **extra}
    for name in ("NUMBA_DISABLE_JIT", "NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES", STORE_ENV):
        if name not in extra:
            env.pop(name, None)
    if cache is None:
        env.pop("NUMBA_CACHE_DIR", None)
    else:
        env["NUMBA_CACHE_DIR"] = str(cache)
    return env


def _run(code: str, env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=cwd
    )


def _build(copy: Path, tmp_path: Path, code: str = _KERNEL) -> subprocess.CompletedProcess:
    """Compile ``code``'s kernels into the copy's store, as ``warmup --store`` does
    (into ``_kernels.build``, then moved into place)."""
    env = _env(copy, tmp_path / "build-cache", NUMBA_CPU_NAME="generic", **{STORE_ENV: "build"})
    got = _run(code, env, tmp_path)
    assert got.returncode == 0, got.stderr
    assert not (copy / "_kernels").exists()  # nothing is written into the store itself
    (copy / "_kernels.build").rename(copy / "_kernels")
    return got


def test_a_stored_kernel_loads_without_compiling_and_never_stale(tmp_path: Path) -> None:
    copy = _package_copy(tmp_path)
    _build(copy, tmp_path)
    (stored,) = (copy / "_kernels" / "sensor").glob("trajectory._cubic_ok_py-*.nbc")
    assert not list((tmp_path / "build-cache").rglob("*.nbc"))  # nothing in numba's cache

    # This CPU, an empty numba cache: the generic code loads, nothing compiles.
    read = _run(_KERNEL, _env(copy, tmp_path / "c1"), tmp_path)
    assert read.returncode == 0 and read.stdout.strip() == "False", read.stderr
    assert "compiling" not in read.stderr and "Warning" not in read.stderr, read.stderr

    # Switched off: it compiles, and says why the store did not serve.
    off = _run(_KERNEL, _env(copy, tmp_path / "c2", **{STORE_ENV: "off"}), tmp_path)
    assert off.returncode == 0 and off.stdout.strip() == "False", off.stderr
    assert "compiling numba kernels" in off.stderr and f"{STORE_ENV}=off" in off.stderr

    # Any kernel source edited: the stored code is not used (it would be stale).
    source = copy / "sensor" / "trajectory.py"
    source.write_text(source.read_text() + "\n# edited\n")
    edited = _run(_KERNEL, _env(copy, tmp_path / "c3"), tmp_path)
    assert edited.returncode == 0 and edited.stdout.strip() == "False", edited.stderr
    assert "compiling numba kernels" in edited.stderr
    assert stored.exists()  # the store is read only: a build replaces it


def test_a_corrupt_stored_kernel_is_compiled_with_one_warning(tmp_path: Path) -> None:
    copy = _package_copy(tmp_path)
    _build(copy, tmp_path)
    (stored,) = (copy / "_kernels" / "sensor").glob("trajectory._cubic_ok_py-*.nbc")
    stored.write_bytes(stored.read_bytes()[:7])  # truncated
    run = _run(_KERNEL, _env(copy, tmp_path / "c"), tmp_path)
    assert run.returncode == 0 and run.stdout.strip() == "False", run.stderr
    lines = [line for line in run.stderr.splitlines() if "NumbaCacheWarning" in line]
    assert len(lines) == 1 and "unreadable shipped kernel" in lines[0], run.stderr
    assert "compiling numba kernels" in run.stderr


def test_a_read_only_install_uses_its_stored_kernels(tmp_path: Path) -> None:
    """No writable cache anywhere (no __pycache__ folder can be made, no user cache, no
    NUMBA_CACHE_DIR): the stored kernels load, with no warning and no compile."""
    copy = _package_copy(tmp_path)
    _build(copy, tmp_path)
    for folder in [copy, *[p for p in copy.rglob("*") if p.is_dir()]]:
        (folder / "__pycache__").write_text("a file where numba wants a folder")
    env = _env(copy, None, XDG_CACHE_HOME="/dev/null/cache", PYTHONDONTWRITEBYTECODE="1")
    run = _run(_KERNEL, env, tmp_path)
    assert run.returncode == 0 and run.stdout.strip() == "False", run.stderr
    assert "Warning" not in run.stderr and "compiling" not in run.stderr, run.stderr


def test_generic_code_gives_this_cpus_numbers_bit_for_bit(tmp_path: Path) -> None:
    """The sensor (trigonometry, noise, dropout) from the store's generic x86-64 code and
    from this CPU's own compile: the same bytes. The store is used on every x86-64 CPU,
    so a difference would change results by where the kernels were compiled."""
    copy = _package_copy(tmp_path)
    generic = _build(copy, tmp_path, _FRAME).stdout.strip()
    stored = _run(_FRAME, _env(copy, tmp_path / "c1"), tmp_path)
    assert stored.returncode == 0 and "compiling" not in stored.stderr, stored.stderr
    native = _run(_FRAME, _env(copy, tmp_path / "c2", **{STORE_ENV: "off"}), tmp_path)
    assert native.returncode == 0 and "compiling" in native.stderr, native.stderr
    assert len(generic) == 64 and generic == stored.stdout.strip() == native.stdout.strip()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({STORE_ENV: "maybe"}, f"{STORE_ENV}='maybe' is not one of read, off, build"),
        ({STORE_ENV: "build"}, "set NUMBA_CPU_NAME=generic too"),
        # generic with this CPU's features would be stored as generic code
        (
            {STORE_ENV: "build", "NUMBA_CPU_NAME": "generic", "NUMBA_CPU_FEATURES": "+avx2"},
            "no NUMBA_CPU_FEATURES",
        ),
    ],
)
def test_bad_store_settings_are_refused_by_name(
    tmp_path: Path, extra: dict[str, str], message: str
) -> None:
    copy = _package_copy(tmp_path)
    run = _run(_KERNEL, _env(copy, tmp_path / "c", **extra), tmp_path)
    assert run.returncode != 0 and message in run.stderr, run.stderr
    assert not (copy / "_kernels").exists() and not (copy / "_kernels.build").exists()


_FIRST_STEP = """
import gymnasium as gym
import aldm_gym
assert aldm_gym.__file__.startswith(__import__("sys").argv[1]), aldm_gym.__file__
env = gym.make("ALDMHighway-v0")
env.reset(seed=0)
env.step(1)
print("stepped")
"""


def test_a_wheel_carries_the_kernels_and_its_install_compiles_nothing(tmp_path: Path) -> None:
    """The checkout's store (``python -m aldm_gym.warmup --store``, run by every Makefile
    setup) packed into a wheel, the wheel installed into an empty folder: the default
    env's first step there compiles nothing."""
    if store_status() != "current":
        pytest.fail(
            f"the shipped kernels of this checkout are {store_status()}: "
            "run `python -m aldm_gym.warmup --store` (make setup does)"
        )
    source = tmp_path / "src"
    source.mkdir()
    shutil.copytree(
        ROOT / "aldm_gym", source / "aldm_gym", ignore=shutil.ignore_patterns("__pycache__")
    )
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    dist, target = tmp_path / "dist", tmp_path / "site"
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--quiet"]
    built = subprocess.run(
        [*pip, "wheel", "--no-deps", "--no-build-isolation", "-w", str(dist), str(source)],
        capture_output=True,
        text=True,
    )
    assert built.returncode == 0, built.stderr
    (wheel,) = dist.glob("aldm_gym-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    stored = sorted(p.relative_to(ROOT).as_posix() for p in STORE.rglob("*") if p.is_file())
    assert f"aldm_gym/_kernels/{MANIFEST}" in names
    assert set(stored) <= set(names) and sum(n.endswith(".nbc") for n in names) > 20
    installed = subprocess.run(
        [*pip, "install", "--no-deps", "--no-compile", "--target", str(target), str(wheel)],
        capture_output=True,
        text=True,
    )
    assert installed.returncode == 0, installed.stderr
    env = {**os.environ, "PYTHONPATH": str(target), "NUMBA_CACHE_DIR": str(tmp_path / "c")}
    for name in ("NUMBA_DISABLE_JIT", "NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES", STORE_ENV):
        env.pop(name, None)
    run = subprocess.run(
        [sys.executable, "-c", _FIRST_STEP, str(target)],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert run.returncode == 0 and run.stdout.strip() == "stepped", run.stderr
    assert "compiling" not in run.stderr, run.stderr
    digest = hashlib.sha256((target / "aldm_gym" / "_kernels" / MANIFEST).read_bytes())
    assert digest.hexdigest() == hashlib.sha256((STORE / MANIFEST).read_bytes()).hexdigest()
