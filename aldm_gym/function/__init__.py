"""The function under test: an interface, the env's own function, trained policies,
FMUs, and a driver that steps ``ALDMHighway-v0`` with any of them.

See :mod:`aldm_gym.function.interface` for what a function receives and returns,
``docs/api.md`` ("Your function under test") for a worked example.
"""

from aldm_gym.function.builtin import BuiltinFunction, CallableFunction, PolicyFunction
from aldm_gym.function.drive import (
    FunctionDriver,
    FunctionPolicy,
    close_function,
    env_for,
    function_input,
)
from aldm_gym.function.interface import (
    DOMAINS,
    LINE_ROLES,
    EgoState,
    Function,
    FunctionInput,
    FunctionOutput,
    PerceivedLine,
    PerceivedObject,
)
from aldm_gym.function.spec import load_function

__all__ = [
    "DOMAINS",
    "LINE_ROLES",
    "BuiltinFunction",
    "CallableFunction",
    "EgoState",
    "Function",
    "FunctionDriver",
    "FunctionInput",
    "FunctionOutput",
    "FunctionPolicy",
    "PerceivedLine",
    "PerceivedObject",
    "PolicyFunction",
    "close_function",
    "env_for",
    "function_input",
    "load_function",
]
