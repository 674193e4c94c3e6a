"""What running FMUs in this process needs beyond fmpy.

An FMU packaged with pythonfmu runs its model in the host's own interpreter: the
Python objects it creates can outlive its instance and still point into its shared
library. fmpy's ``freeInstance`` unloads that library, and the interpreter's garbage
collector then crashes on them. :func:`free_instance` frees the instance and keeps the
library loaded for the rest of the process (a few MB per FMU loaded, once).
"""

from __future__ import annotations

from typing import Any

__all__ = ["free_instance"]


def free_instance(fmu: Any) -> None:
    """``fmi2FreeInstance`` / ``fmi3FreeInstance`` on an fmpy ``FMU2Slave`` or
    ``FMU3Slave``, without unloading its shared library."""
    if hasattr(fmu, "fmi3FreeInstance"):
        fmu.fmi3FreeInstance(fmu.component)
    else:
        fmu.fmi2FreeInstance(fmu.component)
