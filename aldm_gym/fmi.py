"""Running FMUs in this process with fmpy: one instance's life cycle.

:class:`Instance` extracts an FMI 2.0 or 3.0 co-simulation FMU, instantiates it,
initialises it at time 0 (with parameters set in initialisation mode), resets and
closes it; the function-under-test runner and the OSMP host both use it.

An FMU packaged with pythonfmu runs its model in the host's own interpreter: the
Python objects it creates can outlive its instance and still point into its shared
library. fmpy's ``freeInstance`` unloads that library, and the interpreter's garbage
collector then crashes on them. :meth:`Instance.close` frees the instance and keeps the
library loaded for the rest of the process (a few MB per FMU loaded, once).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["Instance", "free_instance", "import_fmpy"]


def import_fmpy() -> Any:
    """fmpy, or :class:`~aldm_gym.errors.MissingFMIDependencies` naming the extra."""
    try:
        import fmpy
    except ImportError:
        from aldm_gym.errors import MissingFMIDependencies

        raise MissingFMIDependencies(
            "running an FMU needs fmpy: pip install 'aldm-gym[fmi]'"
        ) from None
    return fmpy


def free_instance(fmu: Any) -> None:
    """``fmi2FreeInstance`` / ``fmi3FreeInstance`` on an fmpy ``FMU2Slave`` or
    ``FMU3Slave``, without unloading its shared library."""
    if hasattr(fmu, "fmi3FreeInstance"):
        fmu.fmi3FreeInstance(fmu.component)
    else:
        fmu.fmi2FreeInstance(fmu.component)


class Instance:
    """One co-simulation instance of an FMU (fmpy's ``FMU2Slave`` or ``FMU3Slave``).

    :param path: the ``.fmu``.
    :param model_description: fmpy's reading of its ``modelDescription.xml``.
    :param name: the instance's name.
    :param setup: called with the fmpy slave in initialisation mode (parameters).
    :raises MissingFMIDependencies: fmpy missing.
    """

    def __init__(
        self,
        path: str | Path,
        model_description: Any,
        name: str,
        setup: Callable[[Any], None] | None = None,
    ) -> None:
        fmpy = import_fmpy()
        md = model_description
        self.version = str(md.fmiVersion)
        self.setup = setup
        self._dir: str | None = fmpy.extract(str(path))
        kwargs = {
            "guid": md.guid,
            "unzipDirectory": self._dir,
            "modelIdentifier": md.coSimulation.modelIdentifier,
            "instanceName": name,
        }
        if self.version == "2.0":
            from fmpy.fmi2 import FMU2Slave

            self.fmu: Any = FMU2Slave(**kwargs)
        else:
            from fmpy.fmi3 import FMU3Slave

            self.fmu = FMU3Slave(**kwargs)
        self.fmu.instantiate()
        self.initialize()

    def initialize(self) -> None:
        """Initialise at time 0, calling ``setup`` in initialisation mode."""
        fmu = self.fmu
        if self.version == "2.0":
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
        else:
            fmu.enterInitializationMode(startTime=0.0)
        if self.setup is not None:
            self.setup(fmu)
        fmu.exitInitializationMode()

    def reset(self) -> None:
        """``fmi2Reset`` / ``fmi3Reset``, then initialise again."""
        self.fmu.reset()
        self.initialize()

    def close(self) -> None:
        """Terminate and free the instance (its library stays loaded: module
        docstring); remove the extracted files. Closing twice does nothing."""
        if self._dir is None:
            return
        try:
            self.fmu.terminate()
        finally:
            free_instance(self.fmu)
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None
