"""The kernels' parameters, declared once, and the four line slots.

The float parameters travel as one float64 vector ``fp``, the integer ones as one
int64 vector ``ip`` (arrays cost nothing to pass into a compiled function; a
33-field tuple costs ~2.4 µs per call in numba's argument typing). Each vector's
layout is declared once, as a ``NamedTuple``: the wrapper builds the vector from the
named tuple (:func:`aldm_gym.sensor.aldm._pack`), and the kernels read a slot by
name through the tuple of slot numbers, ``fp[P.search_length]`` — a global tuple is
a compile-time constant in numba, so this is the plain ``fp[2]``.
"""

from __future__ import annotations

from typing import NamedTuple


class FloatParams(NamedTuple):
    """The float parameters, in the order of ``fp`` (lengths [m]).

    Most are the :class:`~aldm_gym.sensor.aldm.ALDMParams` field of the same name;
    ``a_max``, ``a_std``, ``b_std``, ``guide_a_std`` and ``guide_b_std`` are derived
    from it (the quadratic coefficient ``a`` of ``y = a x² + ...`` is half the
    curvature).
    """

    start_x_max: float  # start points only at x <= this (paper: 18 + 5.52)
    start_spacing: float  # paper mode: start points at least this far apart in x
    search_length: float  # next-point search window ahead of the last point (paper: 18)
    adjacent_offset: float  # adjacent line starts this far outside the ego line (paper: 2)
    noise_std: float  # robust: design lateral noise sigma
    gate_sigmas: float  # robust: residual gate in predicted standard deviations [-]
    gate_min: float  # robust: smallest residual gate
    gate_max: float  # robust: largest residual gate
    fit_length: float  # robust: fit uses accepted points within this x distance
    a_max: float  # robust: |a| bound, 1 / (2 R_min) [1/m]
    a_std: float  # robust: prior std of a [1/m]
    b_std: float  # robust: prior std of the slope dy/dx [-]
    link_dx: float  # robust seeds: link points at most this far apart in x
    link_dy: float  # robust seeds: ... and this far apart in y
    merge_dy: float  # robust seeds: chains whose offsets differ less are one line
    max_ego_offset: float  # robust: an ego line passes within this |y| of the sensor
    max_lane_width: float  # robust: adjacent line at most this far outside the ego line
    smooth_half_width: float  # smoothed output: half width of the local quadratic fit
    tie_dx: float  # robust: gated points within this x of the first one compete
    lane_width: float  # default lane width for a one-line trajectory
    min_lane_width: float  # smallest plausible lane width (lane-width estimate)
    z_band: float  # points with |z| above this are not road paint (overpass, barrier)
    max_range: float  # points farther ahead or sideways are ignored
    view_range: float  # paper mode: the sensor's range of view (trace end)
    gap_search_length: float  # robust: next-point window, bridging a missing dash
    max_slope: float  # robust: a trace stops where its slope |dy/dx| exceeds this [-]
    guide_a_std: float  # robust: prior std of a about the guide line's [1/m]
    guide_b_std: float  # robust: prior std of the slope about the guide line's [-]
    chain_dy: float  # robust seeds: ... second pass, shape removed: this far apart in y
    skip_residual: float  # robust: a nearest point fitting worse yields to a better one
    parallel_gate: float  # robust: a point this far off parallel to the guide yields


class IntParams(NamedTuple):
    """The integer parameters, in the order of ``ip``."""

    paper: int  # 1: the paper's literal algorithm, 0: the robust variant
    start_points: int  # paper mode: number of start points per line (3)
    min_seed_points: int  # robust: fewest start-region points of a line
    n_points: int  # points per output line (0: all traced points)
    smooth: int  # 1: output the smoothed line, 0: the measured points


P = FloatParams(*range(len(FloatParams._fields)))
"""Slot of each float parameter in ``fp``: ``fp[P.noise_std]``."""

I = IntParams(*range(len(IntParams._fields)))  # noqa: E741  (the ``ip`` twin of ``P``)
"""Slot of each integer parameter in ``ip``: ``ip[I.n_points]``."""

N_LINES = 4
"""Line slots, in the order of ``LINE_NAMES``: left_adjacent, ego_left, ego_right,
right_adjacent. A point's mask bit ``1 << slot`` says that line owns it."""
L_LEFT_ADJ = 0
L_EGO_LEFT = 1
L_EGO_RIGHT = 2
L_RIGHT_ADJ = 3
