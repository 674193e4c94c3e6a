"""Array aliases used across aldm-gym (shapes are documented where they are used)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
"""A float64 array; shapes are given in each docstring, e.g. ``(N, 2)`` points [m]."""

IntArray = npt.NDArray[np.int64]
"""An int64 array (indices, counts)."""

BoolArray = npt.NDArray[np.bool_]
"""A boolean mask."""

Pose = tuple[float, float, float]
"""A planar pose ``(x [m], y [m], heading [rad])`` in the highway-env world frame."""
