"""The Advanced Lane Detection Model (ALDM): lanes from an unordered point cloud.

Paper: Pannagger et al., "Advanced Lane Detection Model for the Virtual Development
of Highly Automated Functions", section "Advanced Lane Detection Model" (§ALDM).
CarMaker's line sensor reports line objects grouped into a left and a right side;
on roads converted from OpenDRIVE or measurements every dash is its own object and
the grouping is wrong in curves. The ALDM pools all points, ignores the grouping
and object ids, and re-traces every marking:

1. start condition: three points per side near the car (x <= 23.52 m);
2. a quadratic through the last points predicts the line;
3. the next point is the best-fitting one at most 18 m ahead (6 m dash + 12 m gap);
4. the same for the adjacent lines, starting >= 2 m outside the ego lines;
5. 13 equally distributed points per line; the driving trajectory is midway
   between cubic fits of the ego lines.

Two modes:

* ``mode="paper"`` is the paper's algorithm as published (exact 3-point parabola, no
  gate, lowest-|y| start points), with the few interpretations its text needs
  (stop rule, 13-point interpolation, adjacent-line start, Lagrange evaluation;
  listed in ``docs/aldm.md``).
* ``mode="robust"`` (default) keeps the structure but replaces the fragile parts:
  the start condition places chains of nearby points by their offset at the
  sensor under a common lane shape (so a marking crossing the car's axis in a
  100 m curve stays on its side), the prediction is a ridge-regularised least
  squares quadratic over the last ``fit_length`` metres with a curvature bound,
  the next point must pass a residual gate derived from the fit's covariance (a
  line that ends stops instead of jumping), points belong to one line only, and
  the output is smoothed by a local quadratic.

Every decision where the paper is silent is listed in ``docs/aldm.md``.
The hot path is in numba (the package :mod:`aldm_gym.sensor.aldm_kernels`, one
module per stage), compiled once into numba's on-disk cache.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Hashable
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.config import build_config, setting, validate
from aldm_gym.errors import ConfigError, InputError
from aldm_gym.sensor.aldm_kernels.layout import FloatParams, IntParams
from aldm_gym.sensor.aldm_kernels.output import detect_frame
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection
from aldm_gym.sensor.trajectory import DEFAULT_LANE_WIDTH, PATH_STEP, driving_trajectory, fit_reach
from aldm_gym.types import FloatArray, IntArray

MODES = ("robust", "paper")
"""Detector variants: the default robust ALDM, or the paper's algorithm as published."""

OUTPUTS = ("auto", "measured", "smoothed")
"""What a returned line holds (see :class:`ALDMParams`)."""


@dataclass(frozen=True)
class ALDMParams:
    """Parameters of :func:`detect_lanes` (all lengths in [m]).

    Paper parameters (§ALDM), used by both modes:

    :ivar mode: ``"robust"`` (default) or ``"paper"`` (the paper's algorithm as
        published; its interpretations are listed in ``docs/aldm.md``).
    :ivar start_x_max: start points lie at x <= this: 18 m + the 5.52 m field-of-view
        offset = 23.52 m.
    :ivar start_points: paper mode: start points per line (3; the trace needs 3).
    :ivar start_spacing: paper mode: start points are at least this far apart *in x*
        (1.8 m) — x, not Euclidean, so that the 3×3 system is regular.
    :ivar search_length: the next point lies at most this far ahead in x (18 m).
    :ivar adjacent_offset: adjacent lines start at least this far laterally outside
        the ego line (2 m).
    :ivar n_points: points per returned line, equally spaced in x over the traced
        range (13); 0 returns every traced point.
    :ivar output: ``"measured"``: the traced points themselves (resampled points are
        linearly interpolated between them); ``"smoothed"``: a local quadratic fit
        of the traced points, evaluated at the same x; ``"auto"``: measured in paper
        mode, smoothed in robust mode.
    :ivar z_band: points with ``|z| > z_band`` (an overpass's lines, which the
        paper notes the simulated sensor sees; barriers) are ignored when z is given.
    :ivar max_range: points farther than this ahead or sideways are ignored
        (the sensor sees 200 m; this guards the arithmetic against absurd input).
    :ivar view_range: paper mode: the sensor's range of view; the trace ends when its
        next 18 m window would reach past it (§ALDM: "until the sensor's range of
        view is reached").
    :ivar lane_width: lane width used for a one-line trajectory when no estimate from
        an adjacent line exists.

    Robust-mode parameters:

    :ivar noise_std: design lateral noise of the points (scales priors and gate).
    :ivar gap_search_length: the next point may lie this far ahead (36 m = dash + two
        gaps) when none passes the gate within ``search_length``; the nearest gated
        point wins, so this only bridges a dash the sensor did not deliver.
    :ivar gate_sigmas: residual gate in predicted standard deviations.
    :ivar gate_min: smallest residual gate.
    :ivar gate_max: largest residual gate (well below half a lane width).
    :ivar fit_length: the prediction fits accepted points within this distance behind
        the last one.
    :ivar min_radius: smallest curve radius the prediction may assume (bound on the
        quadratic term).
    :ivar curvature_prior_std: prior standard deviation of the curvature about the
        common lane shape of the start region [1/m].
    :ivar heading_prior_std: prior standard deviation of the slope dy/dx [-].
    :ivar guide_curvature_std: prior standard deviation of the curvature about that of
        the guide line (the first, best-supported line traced) at the same x [1/m].
    :ivar guide_heading_std: prior standard deviation of the slope about the guide's [-].
    :ivar max_slope: a trace stops where the line is steeper than this in the sensor
        frame (|dy/dx| = 1 is 45°; a polynomial y(x) cannot follow further).
    :ivar min_seed_points: fewest start-region points a line needs.
    :ivar link_dx: start region: points chain when at most this far apart in x ...
    :ivar link_dy: ... and this far apart in y (first pass, for the common shape).
    :ivar chain_dy: second pass, where a chain strays from the common shape by more
        than a quarter of this (RMS), with that shape taken out: points chain when at
        most link_dx apart in x and this far apart in y (keeps a seam beside a marking
        apart from it).
    :ivar merge_dy: chains whose offsets at the sensor differ less are one marking.
    :ivar max_ego_offset: an ego line passes within this lateral distance of the sensor.
    :ivar min_lane_width: smallest plausible lane width (lane-width estimate).
    :ivar max_lane_width: an adjacent line lies at most this far outside the ego line.
    :ivar smooth_half_width: half width of the local quadratic of smoothed output.
    :ivar tie_dx: gated candidates within this x of the nearest one compete by residual.
    :ivar skip_residual: a winning candidate with a larger |residual| yields to the
        nearest gated point farther in the window with at most half its residual
        (clutter beside a dashed line, in its gaps).
    :ivar parallel_gate: a winning candidate farther than this from the guide line
        (the first traced line with at least 6 points over 30 m) shifted by the traced
        line's mean offset from it
        yields to the nearest gated point at most half as far off (an old marking
        diverging from the paint); after a winner above ``skip_residual``, a point
        more than 1.5 times this from the line on a marking that has run beside it
        ends the line (a solid shoulder line beside a broken edge line; ``docs/
        aldm.md``, robust step 3). 10 m turns both checks off.
    """

    mode: str = setting("robust", choices=MODES)
    start_x_max: float = setting(23.52, lo=0.0, lo_open=True, hi=1000.0)
    start_points: int = setting(3, lo=3, hi=1000, integer=True)
    start_spacing: float = setting(1.8, lo=0.0, lo_open=True, hi=100.0)
    # Search windows are bounded: the grid kernel turns them into cell counts, and
    # nothing beyond the 200 m range of view is meaningful (a huge window would
    # overflow its cell count).
    search_length: float = setting(18.0, lo=0.0, lo_open=True, hi=1000.0)
    adjacent_offset: float = setting(2.0, lo=0.0, lo_open=True, hi=50.0)
    n_points: int = setting(13, lo=0, hi=100_000, integer=True)
    output: str = setting("auto", choices=OUTPUTS)
    z_band: float = setting(0.5, lo=0.0, lo_open=True, hi=100.0)
    max_range: float = setting(500.0, lo=1.0, hi=1.0e4)
    view_range: float = setting(200.0, lo=0.0, lo_open=True, hi=1.0e4)
    lane_width: float = setting(DEFAULT_LANE_WIDTH, lo=0.5, hi=20.0)
    noise_std: float = setting(0.1, lo=0.0, lo_open=True, hi=5.0)
    gap_search_length: float = setting(36.0, lo=0.0, hi=1000.0)
    gate_sigmas: float = setting(4.0, lo=0.0, lo_open=True, hi=100.0)
    gate_min: float = setting(0.3, lo=0.0, lo_open=True, hi=10.0)
    gate_max: float = setting(1.2, lo="gate_min", hi=10.0)
    fit_length: float = setting(40.0, lo=0.0, lo_open=True, hi=1000.0)
    min_radius: float = setting(100.0, lo=1.0, hi=1.0e6)
    # Prior standard deviations enter the fit as 1 / std²: at least 1e-9 keeps them finite.
    curvature_prior_std: float = setting(1.0 / 250.0, lo=1e-9, hi=10.0)
    heading_prior_std: float = setting(0.1, lo=1e-9, hi=100.0)
    guide_curvature_std: float = setting(0.001, lo=1e-9, hi=10.0)
    guide_heading_std: float = setting(0.03, lo=1e-9, hi=100.0)
    max_slope: float = setting(1.0, lo=0.0, lo_open=True, hi=100.0)
    min_seed_points: int = setting(1, lo=1, hi=1000, integer=True)
    link_dx: float = setting(4.5, lo=0.0, lo_open=True, hi=100.0)
    link_dy: float = setting(1.5, lo=0.0, lo_open=True, hi=100.0)
    chain_dy: float = setting(0.3, lo=0.0, lo_open=True, hi=100.0)
    merge_dy: float = setting(0.3, lo=0.0, hi=100.0)
    max_ego_offset: float = setting(4.0, lo=0.0, lo_open=True, hi=100.0)
    min_lane_width: float = setting(2.5, lo=0.0, hi=20.0)
    max_lane_width: float = setting(5.0, lo="min_lane_width", hi=50.0)
    smooth_half_width: float = setting(20.0, lo=0.0, lo_open=True, hi=1000.0)
    tie_dx: float = setting(1.0, lo=0.0, hi=100.0)
    skip_residual: float = setting(0.3, lo=0.0, hi=10.0)
    parallel_gate: float = setting(0.3, lo=0.0, hi=10.0)

    def __post_init__(self) -> None:
        validate(self, "aldm")
        if self.n_points == 1:
            raise ConfigError("aldm.n_points must be 0 (every traced point) or >= 2, got 1")

    @property
    def smooth(self) -> bool:
        """Whether returned lines are smoothed (``output`` resolved for ``mode``)."""
        if self.output == "auto":
            return self.mode == "robust"
        return self.output == "smoothed"


def _packed(params: ALDMParams) -> tuple[FloatArray, IntArray]:
    """The kernels' float and int parameter vectors for ``params`` (cached on it).

    Kept on the (frozen) instance rather than in an ``lru_cache``: hashing a
    33-field dataclass on every call costs more than the rest of the wrapper.
    """
    got: tuple[FloatArray, IntArray] | None = params.__dict__.get("_kernel_params")
    if got is None:
        got = _pack(params)
        object.__setattr__(params, "_kernel_params", got)
    return got


def _pack(params: ALDMParams) -> tuple[FloatArray, IntArray]:
    fp = FloatParams(
        start_x_max=params.start_x_max,
        start_spacing=params.start_spacing,
        search_length=params.search_length,
        adjacent_offset=params.adjacent_offset,
        noise_std=params.noise_std,
        gate_sigmas=params.gate_sigmas,
        gate_min=params.gate_min,
        gate_max=params.gate_max,
        fit_length=params.fit_length,
        a_max=0.5 / params.min_radius,  # y ~ x^2 / (2 R)
        a_std=0.5 * params.curvature_prior_std,
        b_std=params.heading_prior_std,
        link_dx=params.link_dx,
        link_dy=params.link_dy,
        merge_dy=params.merge_dy,
        max_ego_offset=params.max_ego_offset,
        max_lane_width=params.max_lane_width,
        smooth_half_width=params.smooth_half_width,
        tie_dx=params.tie_dx,
        lane_width=params.lane_width,
        min_lane_width=params.min_lane_width,
        z_band=params.z_band,
        max_range=params.max_range,
        view_range=params.view_range,
        gap_search_length=params.gap_search_length,
        max_slope=params.max_slope,
        guide_a_std=0.5 * params.guide_curvature_std,
        guide_b_std=params.guide_heading_std,
        chain_dy=params.chain_dy,
        skip_residual=params.skip_residual,
        parallel_gate=params.parallel_gate,
    )
    ip = IntParams(
        paper=1 if params.mode == "paper" else 0,
        start_points=params.start_points,
        min_seed_points=params.min_seed_points,
        n_points=params.n_points,
        smooth=1 if params.smooth else 0,
    )
    fv = np.array(fp, dtype=np.float64)
    iv = np.array(ip, dtype=np.int64)
    fv.flags.writeable = False
    iv.flags.writeable = False
    return fv, iv


@functools.lru_cache(maxsize=256)
def _params_from_items(items: tuple[tuple[str, Hashable], ...]) -> ALDMParams:
    return build_config(ALDMParams, dict(items), where="aldm")


def make_params(params: ALDMParams | None = None, **overrides: Any) -> ALDMParams:
    """Validated :class:`ALDMParams` from an optional base and keyword overrides.

    :raises ValueError: an unknown key (naming it and the allowed ones) or an
        impossible value.
    """
    if params is not None and not isinstance(params, ALDMParams):
        raise TypeError(f"params must be ALDMParams or None, got {type(params).__name__}")
    if not overrides:
        return params if params is not None else _params_from_items(())
    if params is not None:
        build_config(ALDMParams, overrides, where="aldm")  # names unknown keys
        return dataclasses.replace(params, **overrides)
    try:
        return _params_from_items(tuple(sorted(overrides.items())))
    except TypeError:  # unhashable value: validate without the cache
        return build_config(ALDMParams, overrides, where="aldm")


def as_points(points: Any) -> FloatArray:
    """The ``(N, 2|3)`` float64 C-contiguous point array of ``points``.

    Accepts a NumPy array (float or integer dtype) or a line-sensor frame (any
    object with a callable ``points()`` returning such an array, pooled over all
    line objects).

    :raises TypeError: not an array / frame, or a non-numeric or boolean dtype.
    :raises ValueError: not of shape ``(N, 2)`` or ``(N, 3)``.
    """
    if hasattr(points, "points") and callable(points.points):
        points = points.points()
    if not isinstance(points, np.ndarray):
        raise TypeError(
            "detect_lanes expects a numpy array of shape (N, 2) or (N, 3) or a sensor "
            f"frame with points(), got {type(points).__name__}"
        )
    if points.dtype.kind not in "fiu":
        raise TypeError(
            f"detect_lanes: points must be a float (or integer) array, got dtype {points.dtype}"
        )
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise InputError(
            f"detect_lanes expects points of shape (N, 2) or (N, 3), got {points.shape}"
        )
    return np.ascontiguousarray(points, dtype=np.float64)


def detect_lanes(
    points: Any,
    params: ALDMParams | None = None,
    *,
    path_range: float | None = None,
    **overrides: Any,
) -> LaneDetection:
    """Detect the ego lane's lines and the adjacent lines with the ALDM (§ALDM).

    The points are an unordered cloud in the sensor frame (x forward, y left,
    optional z = height above the road) [m]; CarMaker's left/right grouping and
    object ids are not used. Rows with NaN/inf are dropped, as are points behind
    the sensor (x < 0) and, when z is given, points off the road plane
    (``|z| > z_band``). The result does not depend on the order of the points.

    Lines are sorted by x and span only the x range where points were traced (no
    extrapolation); with the default ``n_points=13`` each found line has 13 points
    equally spaced in x, a line not found is ``(0, 2)``. In robust mode the points
    lie on a local quadratic smoothing of the traced points, in paper mode they are
    interpolated between the measured points (see ``output``). The trajectory is
    midway between cubic fits of the ego lines
    (:func:`~aldm_gym.sensor.trajectory.driving_trajectory`, the same function as for
    every detector); with one ego line, that line offset by half the lane width
    estimated from its adjacent line (or ``lane_width``).

    :param points: ``(N, 2)`` or ``(N, 3)`` float array [m], or a sensor frame.
    :param params: an :class:`ALDMParams` (defaults if omitted).
    :param path_range: the trajectory fits each ego line on its points with x <= this
        (at least 4 points) [m]; ``None`` (default): the whole line.
    :param overrides: individual :class:`ALDMParams` fields, e.g. ``mode="paper"``.
    :return: a :class:`~aldm_gym.sensor.lane_detection.LaneDetection` with ``source="aldm"``.
    :raises TypeError: ``points`` is not an array or frame, or has a bad dtype.
    :raises ValueError: bad shape, unknown parameter or impossible value.
    """
    p = params if type(params) is ALDMParams and not overrides else make_params(params, **overrides)
    return detect_lanes_checked(as_points(points), p, path_range)[0]


def detect_lanes_checked(
    pts: FloatArray, p: ALDMParams, path_range: float | None
) -> tuple[LaneDetection, float, FloatArray, IntArray]:
    """:func:`detect_lanes` on checked points and parameters; also the lane width
    [m] its trajectory used with a single ego line, and the lines concatenated in
    :data:`LINE_NAMES` order with their offsets (the detection's lines are views of
    it)."""
    reach = fit_reach(path_range)
    fp, ip = _packed(p)
    lines, starts, _offsets, ok, traj, width = detect_frame(pts, fp, ip, reach)
    fields = {name: lines[starts[s] : starts[s + 1]] for s, name in enumerate(LINE_NAMES)}
    if not ok:  # lines of < 4 points (n_points 2 or 3) or repeated x: numpy's fit
        traj = driving_trajectory(fields["ego_left"], fields["ego_right"], width, PATH_STEP, reach)
    det = LaneDetection.trusted(**fields, trajectory=traj, source="aldm")
    return det, float(width), lines, starts


__all__ = ["MODES", "OUTPUTS", "ALDMParams", "as_points", "detect_lanes", "make_params"]
