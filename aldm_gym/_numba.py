"""Guards around numba's on-disk cache of the package's kernels.

The kernels are compiled with ``numba.njit(cache=True)``, which stores machine code in
a ``__pycache__`` folder next to each module (or the user's cache folder, or
``NUMBA_CACHE_DIR``). Two faults of that cache would stop the package, and are handled:

* a corrupt entry (a truncated ``*.nbi`` index or ``*.nbc`` data file, e.g. after a
  full disk) makes numba fail in ``pickle`` (``UnpicklingError``, ``EOFError``) on every
  run: the entry is removed and the kernel recompiled (and cached again), with a
  one-line :class:`NumbaCacheWarning` naming the file;
* with no writable cache location (read-only package folder and user cache folder,
  no ``NUMBA_CACHE_DIR``), numba refuses to decorate a kernel (``cannot cache function
  ...: no locator available``) and importing the env would fail: the kernels compile
  in memory (each run) with a one-line warning saying how to cache them.

numba keys a cached kernel by its own file's modification time and size only, so a
kernel that calls a kernel of another module would keep the callee's *old* machine
code after the callee's file changed (an edit, or a ``git pull`` that touches only
that file): silently stale behaviour. Every kernel of this package is therefore keyed by
one digest of the source of all the package's modules that define kernels: any change
to any of them recompiles them all (a minute), and an unchanged checkout keeps its
cache whatever the files' times.

On a cache miss of one of the package's kernels (the first run after an install or an
edit), one log record says that kernels are being compiled, once per process (logger
``aldm_gym.compile``, level WARNING: Python shows it on stderr with no logging set up).

:func:`install` wraps numba's ``Cache.load_overload`` and
``Dispatcher.enable_caching`` for functions of this package only (another package's
cache errors still raise); it runs when this module is imported, which
``aldm_gym/__init__.py`` does before any kernel module, and is idempotent. The kernel
modules keep their plain ``numba.njit(cache=True)``.
"""

from __future__ import annotations

import hashlib
import logging
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from aldm_gym.errors import NumbaCacheWarning

_LOG = logging.getLogger("aldm_gym.compile")

PACKAGE = "aldm_gym"
"""Functions of modules under this package are guarded."""

_installed = False
_warned_no_cache = False
_announced = False
_digest: str | None = None


def _ours(py_func: Any) -> bool:
    """``py_func`` is defined in this package."""
    module = getattr(py_func, "__module__", None) or ""
    return module == PACKAGE or module.startswith(PACKAGE + ".")


def _warn(message: str, filename: str) -> None:
    """A one-line warning located at ``filename`` (no source line is printed)."""
    warnings.warn_explicit(message, NumbaCacheWarning, filename, 0)


def _corrupt_files(cache: Any, sig: Any, target_context: Any) -> list[Path]:
    """The files of ``cache``'s entry for ``sig`` that cannot be read, best effort:
    the index if it does not load, else the data file it names for ``sig``."""
    cache_file = cache._cache_file
    index = Path(cache_file._index_path)
    try:
        overloads = cache_file._load_index()
    except Exception:
        return [index]
    try:
        name = overloads.get(cache._index_key(sig, target_context.codegen()))
    except Exception:
        name = None
    if name is None:
        return [index]
    return [Path(cache_file._data_path(name)), index]


@contextmanager
def notice_given() -> Iterator[None]:
    """No compile notice inside this block: its caller says itself that it compiles
    (the warm-up)."""
    global _announced
    saved, _announced = _announced, True
    try:
        yield
    finally:
        _announced = saved


def _announce_compile() -> None:
    """One log record (a warning, so that Python shows it on stderr without any logging
    set up), once per process, when a kernel is not in the cache: the first run after
    an install compiles for about a minute, and should not look hung."""
    global _announced
    if not _announced:
        _announced = True
        _LOG.warning(
            "aldm-gym: compiling numba kernels (first run after an install or an update; "
            "about a minute on 2 cores, cached on disk afterwards)..."
        )


def _guarded_load_overload(original: Any) -> Any:
    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        try:
            got = original(self, sig, target_context)
        except Exception as exc:
            if not _ours(getattr(self, "_py_func", None)):
                raise
            try:
                files = _corrupt_files(self, sig, target_context)
            except Exception:  # numba internals changed: still recompile
                files = []
            for path in files:
                path.unlink(missing_ok=True)  # the recompiled kernel is saved afresh
            where = str(files[0]) if files else f"numba cache of {self._name}"
            _warn(
                f"unreadable numba cache entry ({type(exc).__name__}: {exc}) removed; "
                f"recompiling {getattr(self._py_func, '__qualname__', '?')}",
                where,
            )
            _announce_compile()
            return None  # a cache miss: numba compiles, then saves the entry again
        if got is None and _ours(getattr(self, "_py_func", None)):
            _announce_compile()
        return got

    load_overload.__wrapped__ = original  # type: ignore[attr-defined]
    return load_overload


def kernel_digest() -> str:
    """sha256 of the source of every module of the package that defines a kernel
    (``njit`` in its text), in path order; computed once per process."""
    global _digest
    if _digest is None:
        root = Path(__file__).parent
        h = hashlib.sha256()
        for path in sorted(root.rglob("*.py")):
            text = path.read_bytes()
            if b"njit" in text:
                h.update(path.relative_to(root).as_posix().encode() + b"\0" + text + b"\0")
        _digest = h.hexdigest()
    return _digest


def _guarded_enable_caching(original: Any, null_cache: Any) -> Any:
    def enable_caching(self: Any) -> None:
        global _warned_no_cache
        try:
            original(self)
            if _ours(self.py_func):
                cache_file = getattr(self._cache, "_cache_file", None)
                if cache_file is not None and hasattr(cache_file, "_source_stamp"):
                    cache_file._source_stamp = (PACKAGE, kernel_digest())
        except RuntimeError as exc:
            if "no locator available" not in str(exc) or not _ours(self.py_func):
                raise
            self._cache = null_cache()
            if not _warned_no_cache:
                _warned_no_cache = True
                _warn(
                    "no writable numba cache location (the package folder, the user "
                    "cache folder and NUMBA_CACHE_DIR are not writable): compiling "
                    "aldm_gym's kernels in memory, every run; set NUMBA_CACHE_DIR to a "
                    "writable folder to cache them",
                    str(Path(__file__).parent),
                )

    enable_caching.__wrapped__ = original  # type: ignore[attr-defined]
    return enable_caching


def install() -> bool:
    """Guard numba's cache for this package's kernels (idempotent).

    :return: whether the guards are in place (False if numba is missing or its
        caching internals are not the expected ones; then numba behaves as before).
    """
    global _installed
    if _installed:
        return True
    try:
        from numba.core import caching, dispatcher
    except ImportError:
        return False
    cache_cls = getattr(caching, "Cache", None)
    null_cache = getattr(caching, "NullCache", None)
    dispatcher_cls = getattr(dispatcher, "Dispatcher", None)
    if not (
        cache_cls is not None
        and null_cache is not None
        and hasattr(cache_cls, "load_overload")
        and hasattr(dispatcher_cls, "enable_caching")
    ):
        return False
    cache_cls.load_overload = _guarded_load_overload(cache_cls.load_overload)
    dispatcher_cls.enable_caching = _guarded_enable_caching(
        dispatcher_cls.enable_caching, null_cache
    )
    _installed = True
    return True


install()
