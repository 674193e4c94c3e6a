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
  ...: no locator available``) and importing the env would fail: the kernels load from
  the shipped kernels, or compile in memory (each run) with a one-line warning saying
  how to cache them.

numba keys a cached kernel by its own file's modification time and size only, so a
kernel that calls a kernel of another module would keep the callee's *old* machine
code after the callee's file changed (an edit, or a ``git pull`` that touches only
that file): silently stale behaviour; and numba freezes every global a kernel reads
(a constant of another module, the slot numbers of ``aldm_kernels/layout.py``) into its
machine code. Every kernel of this package is therefore keyed by one digest of the
source of all modules a kernel can read from (:data:`KERNEL_LAYERS`): any change to any
of them recompiles them all (a minute), and an unchanged checkout keeps its cache
whatever the files' times.

**Shipped kernels.** Compiling every kernel takes about a minute on 2 cores, on every
new install, CI runner and cluster node. The package therefore ships its kernels
compiled ahead of time for a generic x86-64 CPU (``NUMBA_CPU_NAME=generic``: code that
runs on every x86-64 CPU and gives the same numbers as a compile for the CPU at hand;
no kernel uses ``fastmath``), in numba's own cache format, in :data:`STORE`. When
numba's cache misses one of the package's kernels, it is loaded from there before it
is compiled. The store is keyed like the cache: by the same digest of the kernel
sources, the function's bytecode, numba's version, the Python version and the
architecture, so it never serves stale code, and where it does not match (another
numba, Python or CPU family, an edited kernel) the kernels compile as before, with the
reason in the compile notice. It is only read; a corrupt entry is compiled instead,
with one warning. ``python -m aldm_gym.warmup --store`` builds it (every Makefile
setup does) into :data:`STORE_BUILD` and then moves it into place, and a wheel built
afterwards carries it (``make wheel``). Setting :data:`STORE_ENV` to ``off`` ignores
it.

On a cache miss of one of the package's kernels that the store does not serve (the
first run after a source install or an edit), one log record says that kernels are
being compiled, once per process (logger ``aldm_gym.compile``, level WARNING: Python
shows it on stderr with no logging set up).

:func:`install` wraps numba's ``Cache.load_overload`` and
``Dispatcher.enable_caching`` for functions of this package only (another package's
cache errors still raise); it runs when this module is imported, which
``aldm_gym/__init__.py`` does before any kernel module, and is idempotent. The kernel
modules keep their plain ``numba.njit(cache=True)``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import platform
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, ClassVar

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
            "about a minute on 2 cores, cached on disk afterwards)...%s",
            _store_note(),
        )


def _store_note() -> str:
    """Why the shipped kernels did not serve (appended to the compile notice)."""
    try:
        if store_mode() == "off":
            return f" ({STORE_ENV}=off)"
        status = store_status()
        if status == "missing":
            return " (no shipped kernels: python -m aldm_gym.warmup --store builds them)"
        if status == "stale":
            shipped = json.loads((STORE / MANIFEST).read_text())
            here = store_manifest()
            differ = [
                "the kernel source differs"
                if key == "digest"
                else f"{key} {shipped.get(key)} there, {value} here"
                for key, value in here.items()
                if shipped.get(key) != value
            ]
            return f" (the shipped kernels do not match this install: {'; '.join(differ)})"
    except Exception:  # a note only: never in the way of the compile
        return ""
    return ""


def _guarded_load_overload(original: Any) -> Any:
    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        if getattr(self, "_aldm_store", False):
            return original(self, sig, target_context)  # the store's own faults: _from_store
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
            got = _from_store(self._py_func, sig, target_context)
            if got is None:
                _announce_compile()
        return got

    load_overload.__wrapped__ = original  # type: ignore[attr-defined]
    return load_overload


KERNEL_LAYERS = (
    "__init__",
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
)
"""The package's modules and subpackages a kernel can read from: those of the layers up
to the highest one holding a kernel (``envs``; the layers of ``tests/test_layers.py``).
numba freezes every global a kernel reads (a slot number of
``aldm_kernels/layout.py``, a constant of another module) into its machine code, so
all of them key the cache, not only the files that define kernels."""


def kernel_digest() -> str:
    """sha256 of the source of every module of :data:`KERNEL_LAYERS`, in path order;
    computed once per process."""
    global _digest
    if _digest is None:
        root = Path(__file__).parent
        h = hashlib.sha256()
        for path in sorted(root.rglob("*.py")):
            rel = path.relative_to(root)
            if rel.parts[0].removesuffix(".py") in KERNEL_LAYERS:
                h.update(rel.as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
        _digest = h.hexdigest()
    return _digest


STORE = Path(__file__).parent / "_kernels"
"""The shipped kernels: the package's kernels compiled ahead of time for a generic
x86-64 CPU (``NUMBA_CPU_NAME=generic``), in numba's cache format, one folder per
package folder (``python -m aldm_gym.warmup --store`` writes it; a wheel carries it)."""

STORE_BUILD = STORE.with_name("_kernels.build")
"""Where ``build`` mode compiles, before :func:`aldm_gym.warmup.build_store` moves it
to :data:`STORE` (a failed build leaves the old store as it was)."""

STORE_ENV = "ALDM_GYM_KERNEL_STORE"
"""Environment variable: ``read`` (default) loads a kernel from :data:`STORE` when the
numba cache misses it, ``off`` never does, ``build`` makes this process compile into
:data:`STORE` (it must run with ``NUMBA_CPU_NAME=generic``)."""

STORE_MODES = ("read", "off", "build")
"""The allowed values of :data:`STORE_ENV`."""

_GENERIC = "generic"
_ROOT = Path(__file__).resolve().parent
_store_class: Any = None
_stores: dict[Any, Any] = {}
_warned_store = False
_mode: str | None = None


def store_mode() -> str:
    """The value of :data:`STORE_ENV` (``read`` when unset), read once per process.

    :raise ValueError: an unknown value, naming the allowed ones.
    :raise RuntimeError: ``build`` without ``NUMBA_CPU_NAME=generic`` and no
        ``NUMBA_CPU_FEATURES`` (code for this CPU would be stored as generic code,
        and crash another CPU).
    """
    global _mode
    if _mode is not None:
        return _mode
    value = os.environ.get(STORE_ENV, "").strip().lower() or "read"
    if value not in STORE_MODES:
        raise ValueError(
            f"{STORE_ENV}={os.environ[STORE_ENV]!r} is not one of {', '.join(STORE_MODES)}"
        )
    if value == "build":
        from numba.core import config

        if str(config.CPU_NAME).lower() != _GENERIC or (config.CPU_FEATURES or ""):
            raise RuntimeError(
                f"{STORE_ENV}=build compiles the shipped kernels, which must run on any "
                "x86-64 CPU: set NUMBA_CPU_NAME=generic too, and no NUMBA_CPU_FEATURES "
                "(python -m aldm_gym.warmup --store does)"
            )
    _mode = value
    return value


MANIFEST = "manifest.json"
"""The file in the store that says what it was compiled from."""


def store_manifest() -> dict[str, str]:
    """What the shipped kernels must match to be used: the kernel digest, the numba and
    Python versions and the machine architecture (numba checks each itself, entry by
    entry; the manifest says it at a glance)."""
    import numba

    return {
        "digest": kernel_digest(),
        "numba": numba.__version__,
        "python": f"{sys.version_info[0]}.{sys.version_info[1]}",
        "machine": platform.machine(),
        "cpu": "generic",
    }


def store_status() -> str:
    """``current`` (the shipped kernels match this install), ``stale`` (they were
    compiled for another digest, numba, Python or architecture: kernels compile on
    first use) or ``missing``."""
    try:
        shipped = json.loads((STORE / MANIFEST).read_text())
    except (OSError, ValueError):
        return "missing"
    return "current" if shipped == store_manifest() else "stale"


def _store_cache_class() -> Any:
    """numba's ``FunctionCache`` reading and writing :data:`STORE` under the generic
    CPU's key (created on first use: numba is imported lazily)."""
    global _store_class
    if _store_class is not None:
        return _store_class
    from numba.core import caching, config

    class StoreLocator(caching._CacheLocator):
        """The folder of :data:`STORE` that mirrors the kernel's package folder."""

        def __init__(self, py_func: Any, py_file: str) -> None:
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            # a build writes next to the store, which it replaces when it has finished
            root = STORE_BUILD if store_mode() == "build" else STORE
            self._path = root / Path(py_file).resolve().parent.relative_to(_ROOT)

        def get_cache_path(self) -> str:
            return str(self._path)

        def get_source_stamp(self) -> Any:
            return (PACKAGE, kernel_digest())

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            try:
                return cls(py_func, py_file)
            except ValueError:  # not a file of this package
                return None

    class StoreImpl(caching.CompileResultCacheImpl):
        _locator_classes: ClassVar[list[type]] = [StoreLocator]

        def __init__(self, py_func: Any) -> None:
            # NUMBA_CACHE_LOCATOR_CLASSES (numba >= 0.62) would replace the locator
            overridden = hasattr(config, "CACHE_LOCATOR_CLASSES")
            saved = getattr(config, "CACHE_LOCATOR_CLASSES", None)
            if overridden:
                config.CACHE_LOCATOR_CLASSES = None
            try:
                super().__init__(py_func)
            finally:
                if overridden:
                    config.CACHE_LOCATOR_CLASSES = saved

    class StoreCache(caching.FunctionCache):
        """The shipped kernels of one function: keyed by the generic CPU whatever CPU
        this process compiles for (generic code runs on every x86-64 CPU)."""

        _impl_class = StoreImpl
        _aldm_store = True

        def _index_key(self, sig: Any, codegen: Any) -> Any:
            sig_key, magic, code = super()._index_key(sig, codegen)
            generic = (magic[0], _GENERIC, "")
            if store_mode() == "build" and tuple(magic) != generic:
                raise RuntimeError(f"the shipped kernels must be generic code, not {magic}")
            return sig_key, generic, code

    _store_class = StoreCache
    return StoreCache


def _from_store(py_func: Any, sig: Any, target_context: Any) -> Any:
    """The shipped machine code of ``py_func`` for ``sig``, or None (no store, another
    digest, numba or Python version, another architecture, or an unreadable entry: the
    last with one warning, as numba then compiles)."""
    global _warned_store
    if not STORE.is_dir() or store_mode() != "read":
        return None
    try:
        cache = _stores.get(py_func)
        if cache is None:
            cache = _stores[py_func] = _store_cache_class()(py_func)
        return cache.load_overload(sig, target_context)
    except Exception as exc:
        if not _warned_store:
            _warned_store = True
            _warn(
                f"unreadable shipped kernel ({type(exc).__name__}: {exc}); compiling "
                f"{getattr(py_func, '__qualname__', '?')} and any other such kernel",
                str(STORE),
            )
        return None


def _guarded_enable_caching(original: Any, null_cache: Any) -> Any:
    class StoreOnly(null_cache):  # type: ignore[misc, valid-type]
        """No writable cache: the shipped kernels, else an in-memory compile."""

        def __init__(self, py_func: Any) -> None:
            super().__init__()
            self._py_func = py_func

        def load_overload(self, sig: Any, target_context: Any) -> Any:
            global _warned_no_cache
            got = _from_store(self._py_func, sig, target_context)
            if got is None and not _warned_no_cache:
                _warned_no_cache = True
                _warn(
                    "no writable numba cache location (the package folder, the user "
                    "cache folder and NUMBA_CACHE_DIR are not writable): compiling "
                    "aldm_gym's kernels in memory, every run; set NUMBA_CACHE_DIR to a "
                    "writable folder to cache them",
                    str(Path(__file__).parent),
                )
            return got

    def enable_caching(self: Any) -> None:
        if _ours(self.py_func) and store_mode() == "build":
            self._cache = _store_cache_class()(self.py_func)
            return
        try:
            original(self)
            if _ours(self.py_func):
                cache_file = getattr(self._cache, "_cache_file", None)
                if cache_file is not None and hasattr(cache_file, "_source_stamp"):
                    cache_file._source_stamp = (PACKAGE, kernel_digest())
        except RuntimeError as exc:
            if "no locator available" not in str(exc) or not _ours(self.py_func):
                raise
            self._cache = StoreOnly(self.py_func)

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
