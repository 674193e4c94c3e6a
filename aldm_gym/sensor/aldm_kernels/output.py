"""Output stage: the traced lines as returned, the one-line lane width, and the
whole pipeline (:func:`detect_frame`, the single entry point called from Python).

The trajectory is not computed here: :func:`detect_frame` calls the one path fit of
every detector, :func:`aldm_gym.sensor.trajectory.fit_path`.
"""

from __future__ import annotations

import numba
import numpy as np

from aldm_gym.sensor.aldm_kernels.fit import smooth_at
from aldm_gym.sensor.aldm_kernels.layout import (
    L_EGO_LEFT,
    L_EGO_RIGHT,
    L_LEFT_ADJ,
    L_RIGHT_ADJ,
    N_LINES,
    I,
    P,
)
from aldm_gym.sensor.aldm_kernels.paper import paper_detect
from aldm_gym.sensor.aldm_kernels.robust import robust_detect
from aldm_gym.sensor.aldm_kernels.sort import gather
from aldm_gym.sensor.trajectory import PATH_STEP, fit_path


def _assemble_py(xs, ys, mask, fp, ip, a0, b0):
    """Output lines: measured or smoothed, all points or ``n_out`` equally spaced.

    Lines with fewer than two points, or no extent in x, are empty. Output never
    extends beyond the first and last traced point (no extrapolation).

    :return: ``(lines, starts)``: ``lines[starts[l]:starts[l+1]]`` is line l ``(K, 2)``.
    """
    n = xs.shape[0]
    n_out = ip[I.n_points]
    smooth = ip[I.smooth] == 1
    sig2 = fp[P.noise_std] * fp[P.noise_std]
    lam_a = sig2 / (fp[P.a_std] * fp[P.a_std])
    lam_b = sig2 / (fp[P.b_std] * fp[P.b_std])
    cnt = np.zeros(N_LINES, dtype=np.int64)
    x_lo = np.full(N_LINES, np.inf)
    x_hi = np.full(N_LINES, -np.inf)
    # owned[:n_owned]: the points of any line, so each line's pass below visits
    # only those (a few hundred) rather than all N points.
    owned = np.empty(n, dtype=np.int64)
    n_owned = 0
    for i in range(n):
        mk = mask[i]
        if mk != 0:
            owned[n_owned] = i
            n_owned += 1
            for s in range(N_LINES):
                if mk & (1 << s):
                    cnt[s] += 1
                    x_lo[s] = min(x_lo[s], xs[i])
                    x_hi[s] = max(x_hi[s], xs[i])
    starts = np.zeros(N_LINES + 1, dtype=np.int64)
    for s in range(N_LINES):
        size = 0
        if cnt[s] >= 2 and x_hi[s] > x_lo[s]:
            size = n_out if n_out >= 2 else cnt[s]
        starts[s + 1] = starts[s] + size
    lines = np.empty((starts[N_LINES], 2))
    for s in range(N_LINES):
        size = starts[s + 1] - starts[s]
        if size == 0:
            continue
        lx = np.empty(cnt[s])
        ly = np.empty(cnt[s])
        k = 0
        for t in range(n_owned):
            i = owned[t]
            if mask[i] & (1 << s):
                lx[k] = xs[i]
                ly[k] = ys[i]
                k += 1
        if n_out >= 2:
            xq = np.linspace(lx[0], lx[k - 1], n_out)
        else:
            xq = lx
        if smooth:
            yq, _, _ = smooth_at(
                lx, ly, xq, fp[P.smooth_half_width], a0, b0, lam_a, lam_b, fp[P.a_max]
            )
        elif n_out >= 2:
            yq = np.interp(xq, lx, ly)
        else:
            yq = ly
        o = starts[s]
        for j in range(size):
            lines[o + j, 0] = xq[j]
            lines[o + j, 1] = yq[j]
    return lines, starts


_assemble = numba.njit(cache=True)(_assemble_py)


def _one_line_width_py(starts, offsets, fp):
    """Lane width [m] for a trajectory from one ego line (§ALDM is silent).

    With only one ego line found, the distance between its offset at x = 0 and that
    of the adjacent line on the same side, when found and within
    [min_lane_width, max_lane_width]; otherwise (and with two or no ego lines, where
    it is unused) the ``lane_width`` parameter.
    """
    width = fp[P.lane_width]
    nl = starts[L_EGO_LEFT + 1] - starts[L_EGO_LEFT]
    nr = starts[L_EGO_RIGHT + 1] - starts[L_EGO_RIGHT]
    if nl > 0 and nr == 0 and starts[L_LEFT_ADJ + 1] > starts[L_LEFT_ADJ]:
        w = offsets[L_LEFT_ADJ] - offsets[L_EGO_LEFT]
        if fp[P.min_lane_width] <= w <= fp[P.max_lane_width]:
            width = w
    elif nr > 0 and nl == 0 and starts[L_RIGHT_ADJ + 1] > starts[L_RIGHT_ADJ]:
        w = offsets[L_EGO_RIGHT] - offsets[L_RIGHT_ADJ]
        if fp[P.min_lane_width] <= w <= fp[P.max_lane_width]:
            width = w
    return width


_one_line_width = numba.njit(cache=True)(_one_line_width_py)


def _finish_py(xs, ys, mask, offsets, fp, ip, a0, b0, path_range):
    """Output lines, one-line lane width and trajectory of a traced frame.

    :return: ``(lines, starts, offsets, ok, trajectory, width)`` as :func:`detect_frame`.
    """
    lines, starts = _assemble(xs, ys, mask, fp, ip, a0, b0)
    width = _one_line_width(starts, offsets, fp)
    left = lines[starts[L_EGO_LEFT] : starts[L_EGO_LEFT + 1]]
    right = lines[starts[L_EGO_RIGHT] : starts[L_EGO_RIGHT + 1]]
    ok, traj = fit_path(left, right, width, PATH_STEP, path_range)
    return lines, starts, offsets, ok, traj, width


_finish = numba.njit(cache=True)(_finish_py)


def _robust_pipeline_py(pts, fp, ip, path_range):
    """The whole robust-mode ALDM on one frame (see :func:`detect_frame`)."""
    xs, ys = gather(pts, pts.shape[1] >= 3, fp[P.z_band], fp[P.max_range])
    mask = np.zeros(xs.shape[0], dtype=np.uint8)
    offsets = np.full(N_LINES, np.nan)
    a0, b0 = robust_detect(xs, ys, fp, ip, mask, offsets)
    return _finish(xs, ys, mask, offsets, fp, ip, a0, b0, path_range)


_robust_pipeline = numba.njit(cache=True)(_robust_pipeline_py)


def _paper_pipeline_py(pts, fp, ip, path_range):
    """The whole paper-mode ALDM on one frame (see :func:`detect_frame`)."""
    xs, ys = gather(pts, pts.shape[1] >= 3, fp[P.z_band], fp[P.max_range])
    mask = np.zeros(xs.shape[0], dtype=np.uint8)
    offsets = np.full(N_LINES, np.nan)
    paper_detect(xs, ys, fp, ip, mask, offsets)
    return _finish(xs, ys, mask, offsets, fp, ip, 0.0, 0.0, path_range)


_paper_pipeline = numba.njit(cache=True)(_paper_pipeline_py)


def detect_frame_py(pts, fp, ip, path_range):
    """The whole ALDM on one frame, each stage's plain-Python reference at the top
    level (the stages it calls are compiled); see :func:`detect_frame`."""
    if ip[I.paper] == 1:
        return _paper_pipeline_py(pts, fp, ip, path_range)
    return _robust_pipeline_py(pts, fp, ip, path_range)


def detect_frame(pts, fp, ip, path_range):
    """The whole ALDM on one frame; the single entry point called from Python.

    One compiled pipeline per mode, so a first run compiles only the mode it uses
    (robust alone compiles in about two thirds of the time of both modes together).

    :param pts: ``(N, 2|3)`` float64 raw points (x, y[, z]) [m].
    :param fp: float parameters (layout ``P_*``).
    :param ip: integer parameters (layout ``I_*``).
    :param path_range: the trajectory fits the ego lines up to this x [m] (``inf``:
        whole lines), see :func:`aldm_gym.sensor.trajectory.fit_path`.
    :return: ``(lines, starts, offsets, ok, trajectory, width)``: packed output lines
        (see :func:`_assemble`), the lines' offsets at x = 0 ``(4,)`` [m] (NaN if not
        found), whether the compiled path fit applied (else the caller falls back to
        ``driving_trajectory`` with the same lines and ``width``), the ``(M, 2)``
        driving trajectory [m] and the lane width used for a one-line path [m].
    """
    if ip[I.paper] == 1:
        return _paper_pipeline(pts, fp, ip, path_range)
    return _robust_pipeline(pts, fp, ip, path_range)
