"""The driving trajectory: the path midway between cubic fits of the ego lines.

The one implementation of the path every detector returns as
:attr:`LaneDetection.trajectory <aldm_gym.sensor.lane_detection.LaneDetection>`: the
naive and ground-truth detectors call :func:`driving_trajectory`, the ALDM kernel
calls its compiled core :func:`fit_path` directly (numba calls it across modules).

Paper §"Advanced Lane Detection Model", last paragraph: a third-degree trend line
through each ego line; the trajectory is the middle between them. Where the paper is
silent we decided:

* the path starts at the sensor (x = 0) and ends where the shorter line ends, i.e. it
  is extrapolated back over the field-of-view gap (5.52 m) only;
* with one line only, the path is that line's fit offset by half of ``lane_width``
  towards the lane (right of a left line, left of a right line);
* with no line, the trajectory is empty;
* ``path_range``: each line is fitted only on its points with x <= ``path_range``
  (keeping at least its first 4 points). One cubic over the whole visible line (up to
  200 m) is off by metres near the car in a tight curve (R = 100 m turns the marking
  sideways within the view), where the controller looks; the first 80 m keep the path
  exact there on any radius the road generator allows.

Kernels follow the package habit: ``_name_py`` is the plain-Python reference,
``_name = numba.njit(cache=True)(_name_py)`` its compiled twin.
"""

from __future__ import annotations

import math
import warnings

import numba
import numpy as np

from aldm_gym.errors import ConfigError
from aldm_gym.types import FloatArray

DEFAULT_LANE_WIDTH = 3.75
"""Lane width assumed when only one ego line is found and no estimate exists [m]."""

PATH_STEP = 2.0
"""x step of the returned path [m]."""

MIN_FIT_POINTS = 4
"""A line cut at ``path_range`` keeps at least this many points (a cubic needs 4)."""


def fit_cubic(points: FloatArray) -> np.polynomial.Polynomial | None:
    """Least-squares polynomial y(x) of degree ``min(3, K - 1)`` through a line.

    The paper fits "trend lines using a function of 3rd grade" to the left and
    right lines. The fit is done on a scaled x domain for conditioning. This is the
    fallback of :func:`driving_trajectory` for lines the compiled fit does not take
    (fewer than 4 points, x not strictly increasing, or not finite).

    :param points: ``(K, 2)`` points [m].
    :return: the polynomial, or ``None`` for an empty line.
    """
    if len(points) == 0:
        return None
    k = len(np.unique(points[:, 0]))
    span = float(np.max(points[:, 0]) - np.min(points[:, 0]))
    # One x, or an x span so small (sub-normal) that mapping it onto [-1, 1] overflows.
    if k == 1 or not math.isfinite(2.0 / span):
        return np.polynomial.Polynomial([float(np.mean(points[:, 1]))])
    deg = min(3, k - 1)
    with warnings.catch_warnings():
        # Nearly coincident x values (degenerate input) only lower the fit's rank.
        warnings.simplefilter("ignore", np.exceptions.RankWarning)
        return np.polynomial.Polynomial.fit(points[:, 0], points[:, 1], deg)


def fit_reach(path_range: float | None) -> float:
    """``path_range`` as the float the kernels take: ``inf`` for ``None`` [m].

    :raises ConfigError: ``path_range`` is not a number > 0 (NaN included).
    """
    if path_range is None:
        return math.inf
    reach = float(path_range)
    if not reach > 0.0:
        raise ConfigError(f"path_range must be > 0 or None, got {path_range!r}")
    return reach


def driving_trajectory(
    left: FloatArray,
    right: FloatArray,
    lane_width: float = DEFAULT_LANE_WIDTH,
    spacing: float = PATH_STEP,
    path_range: float | None = None,
) -> FloatArray:
    """The desired driving path: midway between cubic fits of the ego lines.

    See the module docstring for the rules. Lines of >= 4 points with strictly
    increasing, finite x (every detector's output) are fitted in one compiled call
    (:func:`fit_path`, Householder QR); any other line by :func:`fit_cubic`.

    :param left: ``(K, 2)`` left ego line [m], sorted by x.
    :param right: ``(K, 2)`` right ego line [m], sorted by x.
    :param lane_width: lane width used when a single line is known [m].
    :param spacing: x step of the returned path [m].
    :param path_range: fit each line on its points with x <= this (at least its first
        4 points) [m]; ``None``: the whole line.
    :return: ``(M, 2)`` path points (x, y) [m], or ``(0, 2)``.
    :raises ConfigError: ``path_range`` is not > 0.
    """
    left = np.asarray(left, dtype=np.float64)
    right = np.asarray(right, dtype=np.float64)
    reach = fit_reach(path_range)
    if left.ndim == 2 and right.ndim == 2 and left.shape[1] == 2 and right.shape[1] == 2:
        left = np.ascontiguousarray(left)
        right = np.ascontiguousarray(right)
        ok, path = fit_path(left, right, float(lane_width), float(spacing), reach)
        if ok:
            return path
        left = left[: _cut_length(left, reach)]
        right = right[: _cut_length(right, reach)]
    ends = [line[-1, 0] for line in (left, right) if len(line)]
    if not ends:
        return np.zeros((0, 2))
    x_end = float(min(ends))
    if x_end <= 0.0:
        return np.zeros((0, 2))
    m = max(2, int(np.ceil(x_end / spacing)) + 1)
    xs = np.linspace(0.0, x_end, m)
    if len(left) and len(right):
        ys = 0.5 * (_line_values(left, xs) + _line_values(right, xs))
    elif len(left):
        ys = _line_values(left, xs) - 0.5 * lane_width
    else:
        ys = _line_values(right, xs) + 0.5 * lane_width
    return np.column_stack([xs, ys])


def _line_values(points: FloatArray, xs: FloatArray) -> FloatArray:
    """The line's cubic fit at ``xs``: compiled when the line allows it, else ``fit_cubic``."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if _cubic_ok(pts):
        return _cubic_values(pts, np.ascontiguousarray(xs, dtype=np.float64))
    poly = fit_cubic(points)
    assert poly is not None  # only called for non-empty lines
    return np.asarray(poly(xs), dtype=np.float64)


def _cut_length_py(line: FloatArray, path_range: float) -> int:
    """How many leading points of ``line`` (sorted by x) the fit uses.

    The points with x <= ``path_range`` (``np.searchsorted(x, path_range, "right")``
    for sorted x, by bisection), but at least :data:`MIN_FIT_POINTS` (all of a shorter
    line). ``path_range = inf`` keeps the whole line.
    """
    k = line.shape[0]
    if k <= MIN_FIT_POINTS:
        return k
    lo = 0
    hi = k
    while lo < hi:
        mid = (lo + hi) // 2
        if line[mid, 0] <= path_range:
            lo = mid + 1
        else:
            hi = mid
    return max(lo, MIN_FIT_POINTS)


_cut_length = numba.njit(cache=True)(_cut_length_py)


def _cubic_ok_py(points: FloatArray) -> bool:
    """Whether the compiled fit applies: >= 4 points, x strictly increasing, all finite."""
    k = points.shape[0]
    if k < 4:
        return False
    for i in range(k):
        if not (math.isfinite(points[i, 0]) and math.isfinite(points[i, 1])):
            return False
        if i > 0 and not (points[i, 0] > points[i - 1, 0]):
            return False
    return True


_cubic_ok = numba.njit(cache=True)(_cubic_ok_py)


def _cubic_values_py(points: FloatArray, xq: FloatArray) -> FloatArray:
    """Least-squares cubic y(x) through ``points`` (``_cubic_ok``), evaluated at ``xq``.

    As ``np.polynomial.Polynomial.fit(x, y, 3)`` and its ``__call__``: x is mapped from
    [x_first, x_last] onto [-1, 1] (same mapping arithmetic), the 4-column
    Vandermonde system is solved in the least-squares sense, here by Householder QR
    instead of an SVD (the result differs by rounding only), and the polynomial is
    evaluated by Horner's scheme in the mapped variable.
    """
    k = points.shape[0]
    lo = points[0, 0]
    hi = points[k - 1, 0]
    span = hi - lo
    off = (hi * -1.0 - lo * 1.0) / span
    scl = 2.0 / span
    a = np.empty((k, 4))
    b = np.empty(k)
    for i in range(k):
        t = off + scl * points[i, 0]
        a[i, 0] = 1.0
        a[i, 1] = t
        a[i, 2] = t * t
        a[i, 3] = a[i, 2] * t
        b[i] = points[i, 1]
    # Householder QR: column c is reflected onto (alpha, 0, ..., 0); the same
    # reflections are applied to the remaining columns and to b.
    for c in range(4):
        norm = 0.0
        for i in range(c, k):
            norm += a[i, c] * a[i, c]
        norm = math.sqrt(norm)
        if norm == 0.0:
            continue
        alpha = -norm if a[c, c] >= 0.0 else norm
        a[c, c] -= alpha  # a[c:, c] now holds the Householder vector v
        vv = 0.0
        for i in range(c, k):
            vv += a[i, c] * a[i, c]
        for cc in range(c + 1, 4):
            d = 0.0
            for i in range(c, k):
                d += a[i, c] * a[i, cc]
            f = 2.0 * d / vv
            for i in range(c, k):
                a[i, cc] -= f * a[i, c]
        d = 0.0
        for i in range(c, k):
            d += a[i, c] * b[i]
        f = 2.0 * d / vv
        for i in range(c, k):
            b[i] -= f * a[i, c]
        a[c, c] = alpha
    coef = np.zeros(4)
    for c in range(3, -1, -1):
        if a[c, c] == 0.0:
            continue
        s = b[c]
        for cc in range(c + 1, 4):
            s -= a[c, cc] * coef[cc]
        coef[c] = s / a[c, c]
    out = np.empty(xq.shape[0])
    for j in range(xq.shape[0]):
        u = off + scl * xq[j]
        out[j] = coef[0] + (coef[1] + (coef[2] + coef[3] * u) * u) * u
    return out


_cubic_values = numba.njit(cache=True)(_cubic_values_py)


def fit_path_py(
    left: FloatArray, right: FloatArray, lane_width: float, spacing: float, path_range: float
) -> tuple[bool, FloatArray]:
    """:func:`driving_trajectory` in one call, or ``(False, empty)`` if a line needs
    ``fit_cubic`` (fewer than 4 points, x not strictly increasing, or not finite,
    after the cut at ``path_range``).

    :param path_range: fit on the points with x <= this (:func:`_cut_length`) [m];
        ``inf``: the whole lines.
    """
    empty = np.zeros((0, 2))
    lc = left[: _cut_length(left, path_range)]
    rc = right[: _cut_length(right, path_range)]
    nl = lc.shape[0]
    nr = rc.shape[0]
    if (nl > 0 and not _cubic_ok(lc)) or (nr > 0 and not _cubic_ok(rc)):
        return False, empty
    if nl == 0 and nr == 0:
        return True, empty
    x_end = math.inf
    if nl > 0:
        x_end = min(x_end, lc[nl - 1, 0])
    if nr > 0:
        x_end = min(x_end, rc[nr - 1, 0])
    if x_end <= 0.0:
        return True, empty
    m = max(2, math.ceil(x_end / spacing) + 1)
    # np.linspace(0, x_end, m), same arithmetic: i * step + 0, the end point exact.
    xq = np.empty(m)
    step = x_end / (m - 1)
    for i in range(m):
        xq[i] = (i * step if step != 0.0 else i / (m - 1) * x_end) + 0.0
    xq[m - 1] = x_end
    out = np.empty((m, 2))
    if nl > 0 and nr > 0:
        yl = _cubic_values(lc, xq)
        yr = _cubic_values(rc, xq)
        for j in range(m):
            out[j, 1] = 0.5 * (yl[j] + yr[j])
    elif nl > 0:
        yl = _cubic_values(lc, xq)
        for j in range(m):
            out[j, 1] = yl[j] - 0.5 * lane_width
    else:
        yr = _cubic_values(rc, xq)
        for j in range(m):
            out[j, 1] = yr[j] + 0.5 * lane_width
    out[:, 0] = xq
    return True, out


fit_path = numba.njit(cache=True)(fit_path_py)


__all__ = [
    "DEFAULT_LANE_WIDTH",
    "MIN_FIT_POINTS",
    "PATH_STEP",
    "driving_trajectory",
    "fit_cubic",
    "fit_reach",
]
