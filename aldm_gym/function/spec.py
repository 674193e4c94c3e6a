"""``--function SPEC``: a function under test by name.

SPEC is one of:

* ``builtin`` (the default): the env's own function, no lane changes;
  ``builtin:rule_based``: with the rule-based lane change;
* a ``.fmu`` file (:class:`~aldm_gym.function.fmu.FMUFunction`);
* a training's output folder, an SB3 model ``.zip`` or an RLlib checkpoint folder
  (:meth:`PolicyFunction.from_model <aldm_gym.function.builtin.PolicyFunction.from_model>`);
* ``module:attr`` or ``path/to/file.py:attr``: a class (instantiated without
  arguments), an object with the protocol, or a callable ``inputs -> FunctionOutput``.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path
from typing import Any

from aldm_gym.errors import InputError
from aldm_gym.function.builtin import LANE_CHANGE_MODES, BuiltinFunction, CallableFunction
from aldm_gym.function.drive import check_function
from aldm_gym.function.interface import Function

__all__ = ["SPEC_KINDS", "load_function"]

SPEC_KINDS = (
    "builtin, builtin:rule_based, a .fmu, a training output folder or model (SB3 .zip, "
    "RLlib checkpoint), or module:attr / file.py:attr"
)
"""The kinds of SPEC, for messages."""


def _import(module: str, attr: str, spec: str) -> Any:
    if module.endswith(".py"):
        path = Path(module)
        if not path.is_file():
            raise InputError(f"--function {spec}: no file {path}")
        name = f"_aldm_function_{path.stem}"
        loader = importlib.util.spec_from_file_location(name, path)
        if loader is None or loader.loader is None:
            raise InputError(f"--function {spec}: cannot import {path}")
        mod = importlib.util.module_from_spec(loader)
        sys.modules[name] = mod
        try:
            loader.loader.exec_module(mod)
        except Exception as exc:  # the user's file: report it, not a traceback of ours
            raise InputError(
                f"--function {spec}: importing {path} raised {type(exc).__name__}: {exc}"
            ) from None
    else:
        try:
            mod = importlib.import_module(module)
        except ImportError as exc:
            raise InputError(f"--function {spec}: cannot import {module}: {exc}") from None
        except Exception as exc:  # the user's module failed while importing
            raise InputError(
                f"--function {spec}: importing {module} raised {type(exc).__name__}: {exc}"
            ) from None
    obj: Any = mod
    for part in attr.split("."):
        if not hasattr(obj, part):
            names = sorted(n for n in dir(mod) if not n.startswith("_"))
            raise InputError(f"--function {spec}: {module} has no {attr!r}; it has {names}")
        obj = getattr(obj, part)
    return obj


def load_function(spec: str) -> Function:
    """The function under test SPEC names (module docstring).

    :raises InputError: a SPEC of none of the four kinds, a missing file, or an object
        without the function protocol (naming what it lacks).
    :raises CheckpointError, MissingRLDependencies: a broken model, or the RL extra
        missing (:func:`~aldm_gym.training.models.load_policy`).
    """
    text = str(spec).strip()
    if text == "builtin" or text.startswith("builtin:"):
        mode = text.partition(":")[2] or "none"
        if mode not in LANE_CHANGE_MODES:
            raise InputError(
                f"--function {text}: builtin's lane changes are "
                + ", ".join(f"builtin:{m}" for m in LANE_CHANGE_MODES)
            )
        return BuiltinFunction(mode)
    path = Path(text)
    if text.lower().endswith(".fmu"):
        from aldm_gym.function.fmu import FMUFunction

        return FMUFunction(path)
    if path.exists():
        from aldm_gym.function.builtin import PolicyFunction

        try:
            return PolicyFunction.from_model(path)
        except FileNotFoundError as exc:
            raise InputError(f"--function {text}: {exc}") from None
    module, sep, attr = text.rpartition(":")
    if not sep or not module or not attr:
        raise InputError(
            f"--function {text!r}: no such file, and not module:attr; a SPEC is {SPEC_KINDS}"
        )
    obj = _import(module, attr, text)
    if isinstance(obj, type):
        try:
            obj = obj()
        except Exception as exc:  # a class that needs arguments, or fails to build
            raise InputError(
                f"--function {text}: {attr}() raised {type(exc).__name__}: {exc} (a class "
                "named by --function is made without arguments; name an instance instead)"
            ) from None
    elif not hasattr(obj, "step") and callable(obj):
        obj = CallableFunction(obj)
    return check_function(obj)
