"""Old module names that keep working: each is the new module, with a warning.

A renamed module leaves a file at its old path that calls :func:`moved`; importing the
old name then gives the new module itself (``sys.modules`` points both names at it),
so ``from old import X`` and ``old.X`` keep working, and a ``DeprecationWarning`` says
the new name. The project itself imports only new names.
"""

from __future__ import annotations

import importlib
import sys
import warnings

__all__ = ["moved"]


def moved(old: str, new: str) -> None:
    """Make module ``old`` an alias of module ``new`` and warn once per import.

    :param old: the old module name (the caller's ``__name__``).
    :param new: the module it is now.
    """
    warnings.warn(
        f"{old} is now {new}; import it from there (the old name will be removed)",
        DeprecationWarning,
        stacklevel=3,
    )
    sys.modules[old] = importlib.import_module(new)
