"""The result of lane detection, shared by every detector (naive, ALDM, ground truth).

All coordinates are in the ISO 8855 sensor frame: x forward [m], y left [m].
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from typing import Any

import numba
import numpy as np

from aldm_gym.types import FloatArray

LINE_NAMES: tuple[str, str, str, str] = ("left_adjacent", "ego_left", "ego_right", "right_adjacent")
"""The four lines, left to right. Observation arrays use this order."""

DEFAULT_LANE_WIDTH = 3.75
"""Lane width assumed when only one ego line is found and no estimate exists [m]."""

_EMPTY = np.zeros((0, 2))


def _as_line(points: FloatArray | None, name: str) -> FloatArray:
    """Validate a line: a finite ``(K, 2)`` float array, returned sorted by x."""
    if points is None:
        return _EMPTY.copy()
    arr = np.asarray(points, dtype=np.float64)
    if arr.size == 0:
        return _EMPTY.copy()
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"LaneDetection.{name} must have shape (K, 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"LaneDetection.{name} contains NaN or inf")
    order = np.argsort(arr[:, 0], kind="stable")
    return np.ascontiguousarray(arr[order])


def resample_line(points: FloatArray, n: int) -> FloatArray:
    """``n`` points equally spaced in x over the line's x range, linearly interpolated.

    The paper (§"Advanced Lane Detection Model") transmits 13 equally distributed
    points per line. A line with fewer than two points cannot be resampled and
    gives an empty ``(0, 2)`` array.

    :param points: ``(K, 2)`` points sorted by x [m].
    :param n: number of output points (>= 2).
    :return: ``(n, 2)`` points, or ``(0, 2)``.
    """
    if n < 2:
        raise ValueError(f"resample needs n >= 2, got {n}")
    if len(points) < 2 or points[-1, 0] <= points[0, 0]:
        return _EMPTY.copy()
    xs = np.linspace(points[0, 0], points[-1, 0], n)
    return np.column_stack([xs, np.interp(xs, points[:, 0], points[:, 1])])


def fit_cubic(points: FloatArray) -> np.polynomial.Polynomial | None:
    """Least-squares polynomial y(x) of degree ``min(3, K - 1)`` through a line.

    The paper fits "trend lines using a function of 3rd grade" to the left and
    right lines. The fit is done on a scaled x domain for conditioning.

    :param points: ``(K, 2)`` points [m].
    :return: the polynomial, or ``None`` for an empty line.
    """
    if len(points) == 0:
        return None
    k = len(np.unique(points[:, 0]))
    if k == 1:
        return np.polynomial.Polynomial([float(np.mean(points[:, 1]))])
    deg = min(3, k - 1)
    with warnings.catch_warnings():
        # Nearly coincident x values (degenerate input) only lower the fit's rank.
        warnings.simplefilter("ignore", np.exceptions.RankWarning)
        return np.polynomial.Polynomial.fit(points[:, 0], points[:, 1], deg)


def driving_trajectory(
    left: FloatArray,
    right: FloatArray,
    lane_width: float = DEFAULT_LANE_WIDTH,
    spacing: float = 2.0,
) -> FloatArray:
    """The desired driving path: midway between cubic fits of the ego lines.

    Paper §"Advanced Lane Detection Model", last paragraph: a third-degree trend
    line through each ego line; the trajectory is the middle between them. Where
    the paper is silent we decided:

    * the path starts at the sensor (x = 0) and ends where the shorter line ends,
      i.e. it is extrapolated back over the field-of-view gap (5.52 m) only;
    * with one line only, the path is that line's fit offset by half of
      ``lane_width`` towards the lane (right of a left line, left of a right line);
    * with no line, the trajectory is empty.

    :param left: ``(K, 2)`` left ego line [m], sorted by x.
    :param right: ``(K, 2)`` right ego line [m], sorted by x.
    :param lane_width: lane width used when a single line is known [m].
    :param spacing: x step of the returned path [m].
    :return: ``(M, 2)`` path points (x, y) [m], or ``(0, 2)``.
    """
    left = np.asarray(left, dtype=np.float64)
    right = np.asarray(right, dtype=np.float64)
    if left.ndim == 2 and right.ndim == 2 and left.shape[1] == 2 and right.shape[1] == 2:
        # Lines of >= 4 points with strictly increasing x and finite values (every
        # detector's output): fits and path in one compiled call.
        ok, path = _path(
            np.ascontiguousarray(left), np.ascontiguousarray(right), lane_width, spacing
        )
        if ok:
            return path
    ends = [line[-1, 0] for line in (left, right) if len(line)]
    if not ends:
        return _EMPTY.copy()
    x_end = float(min(ends))
    if x_end <= 0.0:
        return _EMPTY.copy()
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
    assert poly is not None
    return np.asarray(poly(xs), dtype=np.float64)


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


def _path_py(
    left: FloatArray, right: FloatArray, lane_width: float, spacing: float
) -> tuple[bool, FloatArray]:
    """:func:`driving_trajectory` in one call, or ``(False, empty)`` if a line needs
    ``fit_cubic`` (fewer than 4 points, x not strictly increasing, or not finite).
    """
    empty = np.zeros((0, 2))
    nl = left.shape[0]
    nr = right.shape[0]
    if (nl > 0 and not _cubic_ok(left)) or (nr > 0 and not _cubic_ok(right)):
        return False, empty
    if nl == 0 and nr == 0:
        return True, empty
    x_end = math.inf
    if nl > 0:
        x_end = min(x_end, left[nl - 1, 0])
    if nr > 0:
        x_end = min(x_end, right[nr - 1, 0])
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
        yl = _cubic_values(left, xq)
        yr = _cubic_values(right, xq)
        for j in range(m):
            out[j, 1] = 0.5 * (yl[j] + yr[j])
    elif nl > 0:
        yl = _cubic_values(left, xq)
        for j in range(m):
            out[j, 1] = yl[j] - 0.5 * lane_width
    else:
        yr = _cubic_values(right, xq)
        for j in range(m):
            out[j, 1] = yr[j] + 0.5 * lane_width
    out[:, 0] = xq
    return True, out


_path = numba.njit(cache=True)(_path_py)


@dataclass(frozen=True)
class LaneDetection:
    """Detected lane lines of one frame, in the sensor frame (x forward, y left) [m].

    Each line is a ``(K, 2)`` float64 array sorted by x; ``K = 0`` when the line was
    not found. ``trajectory`` is the ``(M, 2)`` desired driving path (empty when no
    ego line was found).

    :ivar ego_left: left marking of the ego lane.
    :ivar ego_right: right marking of the ego lane.
    :ivar left_adjacent: left marking of the lane left of the ego lane.
    :ivar right_adjacent: right marking of the lane right of the ego lane.
    :ivar trajectory: desired path midway between the ego lines.
    :ivar source: name of the detector that produced it (``"naive"``, ``"aldm"``, ...).
    """

    ego_left: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    ego_right: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    left_adjacent: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    right_adjacent: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    trajectory: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    source: str = ""

    def __post_init__(self) -> None:
        for name in (*LINE_NAMES, "trajectory"):
            object.__setattr__(self, name, _as_line(getattr(self, name), name))

    @classmethod
    def from_lines(
        cls,
        ego_left: FloatArray | None = None,
        ego_right: FloatArray | None = None,
        left_adjacent: FloatArray | None = None,
        right_adjacent: FloatArray | None = None,
        *,
        source: str = "",
        lane_width: float = DEFAULT_LANE_WIDTH,
    ) -> LaneDetection:
        """Build a detection from lines; the trajectory comes from :func:`driving_trajectory`."""
        det = cls(
            ego_left=ego_left,  # type: ignore[arg-type]
            ego_right=ego_right,  # type: ignore[arg-type]
            left_adjacent=left_adjacent,  # type: ignore[arg-type]
            right_adjacent=right_adjacent,  # type: ignore[arg-type]
            source=source,
        )
        traj = driving_trajectory(det.ego_left, det.ego_right, lane_width)
        return replace(det, trajectory=traj)

    @classmethod
    def trusted(cls, source: str = "", **lines: FloatArray) -> LaneDetection:
        """Build from arrays that already satisfy the invariants, skipping validation.

        For detectors whose output is by construction finite float64 ``(K, 2)`` arrays
        sorted by x (the ALDM kernels; checked in its tests): validating again costs
        about as much as a whole detection of a typical frame. Missing lines are empty.

        :param lines: any of :data:`LINE_NAMES` and ``trajectory``.
        """
        unknown = set(lines) - {*LINE_NAMES, "trajectory"}
        if unknown:
            raise ValueError(f"unknown LaneDetection field(s) {sorted(unknown)}")
        det = object.__new__(cls)
        for name in (*LINE_NAMES, "trajectory"):
            object.__setattr__(det, name, lines[name] if name in lines else _EMPTY.copy())
        object.__setattr__(det, "source", source)
        return det

    def line(self, name: str) -> FloatArray:
        """One line by name (one of :data:`LINE_NAMES`)."""
        if name not in LINE_NAMES:
            raise ValueError(f"unknown line {name!r}; allowed: {list(LINE_NAMES)}")
        return getattr(self, name)

    def found(self, name: str) -> bool:
        """Whether line ``name`` has at least two points."""
        return len(self.line(name)) >= 2

    def preview(self, name: str) -> float:
        """Farthest x reached by line ``name`` [m]; 0 when missing."""
        line = self.line(name)
        return float(line[-1, 0]) if len(line) else 0.0

    def extent(self, name: str) -> float:
        """Length in x covered by line ``name`` (last x - first x) [m]; 0 when missing."""
        line = self.line(name)
        return float(line[-1, 0] - line[0, 0]) if len(line) else 0.0

    def resample(self, n: int = 13) -> LaneDetection:
        """A copy with every line resampled to ``n`` equally spaced points.

        Lines with fewer than two points become empty. The trajectory is kept.
        """
        kw: dict[str, Any] = {name: resample_line(self.line(name), n) for name in LINE_NAMES}
        return replace(self, **kw)

    def as_array(self, n: int = 13) -> tuple[FloatArray, np.ndarray]:
        """Lines as a fixed-size array for observations.

        :return: ``(points, valid)``: ``points`` is ``(4, n, 2)`` in the order of
            :data:`LINE_NAMES` (zeros for missing lines), ``valid`` is a ``(4,)`` bool mask.
        """
        pts = np.zeros((4, n, 2))
        valid = np.zeros(4, dtype=bool)
        for i, name in enumerate(LINE_NAMES):
            r = resample_line(self.line(name), n)
            if len(r):
                pts[i] = r
                valid[i] = True
        return pts, valid
