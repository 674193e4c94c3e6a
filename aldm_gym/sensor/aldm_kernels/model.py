"""Kernels of the lane-model filter (:class:`aldm_gym.sensor.lane_filter.LaneModelFilter`).

:func:`predict` moves the model by the odometry; :func:`associate_update` is the rest
of a frame's estimation: the gating of every point, and the measurement update with
the associated points, in information form, re-weighted by Tukey's biweight
(:func:`robust_update`); :func:`draw` draws lines of the model as points. A frame
of the filter is these three calls and a little bookkeeping.

The state is the shared shape (3 entries) followed by one offset per line; a point on
line ``j`` has the measurement row ``(g0, g1, g2, e_j)``. The information matrix is
small (3 + lines, at most a dozen) and symmetric positive definite: it is solved and
inverted by its Cholesky factor, written out rather than taken from LAPACK
(``np.linalg.cholesky`` in numba), whose kernels pick their SIMD paths at run time:
the kernels' sums run in the order written (numba compiles without fast-math, so no
sum is reordered for a wider SIMD unit). Decisions and their reasons:
``docs/aldm.md``, section "Lane-model filter". Plain-Python twins ``_name_py`` as in
the other kernel modules.
"""

from __future__ import annotations

import math

import numba
import numpy as np

N_GEOMETRY = 3
"""State entries of the shared shape (see :mod:`aldm_gym.sensor.lane_filter`)."""

SCALE = 100.0
"""Length scale ``L`` of the state [m]: the shape is kept as ``a1 = tan(psi) L``,
``a2 = c0 L^2``, ``a3 = c1 L^3`` (all in metres), so that the covariance of a 100 m
model is well conditioned."""


def _cholesky_py(a):
    """Lower Cholesky factor of the symmetric matrix ``a``; ``ok`` False when ``a`` is
    not positive definite (to rounding)."""
    n = a.shape[0]
    low = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = a[i, j]
            for k in range(j):
                s -= low[i, k] * low[j, k]
            if i == j:
                if not s > 0.0:
                    return low, False
                low[i, i] = math.sqrt(s)
            else:
                low[i, j] = s / low[j, j]
    return low, True


_cholesky = numba.njit(cache=True)(_cholesky_py)


def _cho_solve_py(low, b):
    """``x`` with ``low low^T x = b``."""
    n = low.shape[0]
    z = np.empty(n)
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= low[i, k] * z[k]
        z[i] = s / low[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = z[i]
        for k in range(i + 1, n):
            s -= low[k, i] * x[k]
        x[i] = s / low[i, i]
    return x


_cho_solve = numba.njit(cache=True)(_cho_solve_py)


def robust_update_py(g, line, r0, sigma, w, prior_info, tukey, iterations, reweight):
    """The robust information-form update of the lane model.

    :param g: ``(N, 3)`` the shape's part of each point's measurement row.
    :param line: ``(N,)`` each point's line (0-based among the lines).
    :param r0: ``(N,)`` each point's residual to the predicted model [m].
    :param sigma: ``(N,)`` each point's standard deviation [m].
    :param w: ``(N,)`` the first weights (copied).
    :param prior_info: ``(n, n)`` the inverse of the predicted covariance.
    :param tukey: Tukey's threshold in standard deviations.
    :param iterations: solves; before each but the first, with ``reweight``, the
        weights become the biweight of the residuals to the model of the last solve.
    :return: ``(delta, cov, w, ok)``: the state's correction, the updated covariance,
        the weights of the last solve (those ``delta`` and ``cov`` come from), and
        False when the information matrix was not positive definite (``delta``,
        ``cov`` then undefined).
    """
    n = prior_info.shape[0]
    w = w.copy()
    delta = np.zeros(n)
    cov = np.zeros((n, n))
    low = np.eye(n)
    for it in range(iterations):
        if reweight and it > 0:
            for k in range(len(r0)):
                j = N_GEOMETRY + line[k]
                fit = delta[j]
                for a in range(N_GEOMETRY):
                    fit += g[k, a] * delta[a]
                e = abs(r0[k] - fit) / sigma[k] / tukey
                t = 1.0 - e * e
                w[k] = t * t if e < 1.0 else 0.0
        info = prior_info.copy()
        grad = np.zeros(n)
        for k in range(len(r0)):
            ws = w[k] / (sigma[k] * sigma[k])
            if ws == 0.0:
                continue
            j = N_GEOMETRY + line[k]
            for a in range(N_GEOMETRY):
                ga = ws * g[k, a]
                for b in range(N_GEOMETRY):
                    info[a, b] += ga * g[k, b]
                info[a, j] += ga
                info[j, a] += ga
                grad[a] += ga * r0[k]
            info[j, j] += ws
            grad[j] += ws * r0[k]
        low, ok = _cholesky(info)
        if not ok:
            return delta, cov, w, False
        delta = _cho_solve(low, grad)
    eye = np.zeros(n)
    for i in range(n):
        eye[:] = 0.0
        eye[i] = 1.0
        cov[:, i] = _cho_solve(low, eye)
    return delta, cov, w, True


robust_update = numba.njit(cache=True)(robust_update_py)


def predict_py(state, cov, dx, dy, dpsi, travel, q_shape, q_offset, q_width):
    """The filter's predict step: the model moved into the new sensor frame.

    The origin advances ``dx`` along the old x and ``dy`` along the old y [m], the
    axes turn by ``dpsi`` [rad]: the cubic is shifted by ``u = dx / L`` along its own
    Taylor series (``y0 += a1 u + a2 u^2/2 + a3 u^3/6``, ``a1 += a2 u + a3 u^2/2``,
    ``a2 += a3 u``), the heading loses ``tan(dpsi)``, the offsets ``dy``. The process
    noise grows with ``travel`` [m].

    :param state: ``(n,)`` shape ``(a1, a2, a3)`` then one offset per line.
    :param cov: ``(n, n)`` its covariance.
    :param q_shape: ``(3,)`` process noise of ``a1, a2, a3`` per square root of travel.
    :param q_offset: of the lines' common offset [m / sqrt(m)].
    :param q_width: of each line's own offset [m / sqrt(m)].
    :return: ``(state, cov)`` predicted (new arrays; ``cov`` symmetric).
    """
    n = state.shape[0]
    u = dx / SCALE
    f = np.eye(n)
    f[0, 1] = u
    f[0, 2] = 0.5 * u * u
    f[1, 2] = u
    for j in range(N_GEOMETRY, n):
        f[j, 0] = u
        f[j, 1] = 0.5 * u * u
        f[j, 2] = u * u * u / 6.0
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for k in range(n):
            s += f[i, k] * state[k]
        out[i] = s
    out[0] -= math.tan(dpsi) * SCALE
    for j in range(N_GEOMETRY, n):
        out[j] -= dy
    fp = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                s += f[i, k] * cov[k, j]
            fp[i, j] = s
    p = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = 0.0
            for k in range(n):
                s += fp[i, k] * f[j, k]
            if i < N_GEOMETRY and i == j:
                s += q_shape[i] * q_shape[i] * travel
            elif i >= N_GEOMETRY and j >= N_GEOMETRY:
                q = q_offset * q_offset
                if i == j:
                    q += q_width * q_width
                s += q * travel
            p[i, j] = s
            p[j, i] = s
    return out, p


predict = numba.njit(cache=True)(predict_py)


def _inverse_py(a):
    """The inverse of the symmetric positive definite ``a`` by its Cholesky factor;
    ``ok`` False when ``a`` is not positive definite (to rounding)."""
    n = a.shape[0]
    inv = np.zeros((n, n))
    low, ok = _cholesky(a)
    if not ok:
        return inv, False
    eye = np.zeros(n)
    for i in range(n):
        eye[:] = 0.0
        eye[i] = 1.0
        inv[:, i] = _cho_solve(low, eye)
    return inv, True


_inverse = numba.njit(cache=True)(_inverse_py)


def associate_update_py(
    x, y, state, cov, point_std, point_std_slope, sigmas, gate_min, gate_max, tukey, iterations
):
    """One frame's association and robust update of the lane model.

    Each point goes to the nearest predicted line whose gate it falls in (``sigmas``
    predicted standard deviations of the line at its x, the state's and the point's,
    clipped to ``[gate_min, gate_max]``); the associated points update the model in
    information form, first weighted by Tukey's biweight of their innovation, then
    re-weighted by it (:func:`robust_update`). Points the update gives no weight are
    free again.

    :param x: ``(N,)`` the points' x [m] (finite, ahead of the sensor).
    :param y: ``(N,)`` their y [m].
    :param state: ``(n,)`` the predicted state (see :func:`predict`).
    :param cov: ``(n, n)`` its covariance.
    :param point_std: a point's lateral standard deviation at x = 0 [m] ...
    :param point_std_slope: ... plus this much per metre ahead [m/m].
    :return: ``(state, cov, line, w, support, far, ok)``: the updated state and
        covariance (the predicted ones when no point was associated or ``ok`` is
        False), each point's line (-1: free) and robust weight, each line's support
        (the sum of its points' weights) and farthest point's x (-inf: none), and
        False when an information matrix was not positive definite (rounding: every
        point is then free and the prediction kept).
    """
    n = state.shape[0]
    n_lines = n - N_GEOMETRY
    n_pts = x.shape[0]
    line = np.full(n_pts, -1, dtype=np.int64)
    w = np.zeros(n_pts)
    support = np.zeros(n_lines)
    far = np.full(n_lines, -np.inf)
    a1 = state[0]
    a2 = state[1]
    a3 = state[2]
    k_line = np.empty(n_lines)
    for i in range(n_lines):
        k_line[i] = 1.0 / max(1.0 - state[N_GEOMETRY + i] * (a2 / (SCALE * SCALE)), 0.5)
    r0 = np.zeros(n_pts)
    n_take = 0
    for p in range(n_pts):
        u = x[p] / SCALE
        g0 = u
        g1 = 0.5 * u * u
        g2 = u * u * u / 6.0
        gpg = (
            g0 * (cov[0, 0] * g0 + cov[0, 1] * g1 + cov[0, 2] * g2)
            + g1 * (cov[1, 0] * g0 + cov[1, 1] * g1 + cov[1, 2] * g2)
            + g2 * (cov[2, 0] * g0 + cov[2, 1] * g1 + cov[2, 2] * g2)
        )
        sig = point_std + point_std_slope * x[p]
        best = np.inf
        for i in range(n_lines):
            j = N_GEOMETRY + i
            res = y[p] - (state[j] + a1 * u + (a2 * g1 + a3 * g2) * k_line[i])
            var = gpg + 2.0 * (g0 * cov[0, j] + g1 * cov[1, j] + g2 * cov[2, j])
            var += cov[j, j] + sig * sig
            gate = sigmas * math.sqrt(max(var, 0.0))
            gate = min(max(gate, gate_min), gate_max)
            d = abs(res)
            if d <= gate and d < best:
                best = d
                line[p] = i
                r0[p] = res
        if line[p] >= 0:
            n_take += 1
    if n_take == 0:
        return state.copy(), cov.copy(), line, w, support, far, True
    # the taken points: measurement rows with their line's parallel-curve factor, and
    # the first weights from the innovation over its standard deviation
    idx = np.empty(n_take, dtype=np.int64)
    c = 0
    for p in range(n_pts):
        if line[p] >= 0:
            idx[c] = p
            c += 1
    g = np.empty((n_take, N_GEOMETRY))
    lt = np.empty(n_take, dtype=np.int64)
    rt = np.empty(n_take)
    st = np.empty(n_take)
    wt = np.empty(n_take)
    for c in range(n_take):
        p = idx[c]
        i = line[p]
        j = N_GEOMETRY + i
        u = x[p] / SCALE
        g[c, 0] = u
        g[c, 1] = 0.5 * u * u * k_line[i]
        g[c, 2] = u * u * u / 6.0 * k_line[i]
        lt[c] = i
        rt[c] = r0[p]
        sig = point_std + point_std_slope * x[p]
        st[c] = sig
        var = sig * sig + cov[j, j]
        for a in range(N_GEOMETRY):
            var += 2.0 * g[c, a] * cov[a, j]
            for b in range(N_GEOMETRY):
                var += g[c, a] * cov[a, b] * g[c, b]
        e = abs(rt[c]) / math.sqrt(max(var, sig * sig)) / tukey
        t = 1.0 - e * e
        wt[c] = t * t if e < 1.0 else 0.0
    prior_info, ok = _inverse(cov)
    if not ok:
        return state.copy(), cov.copy(), np.full(n_pts, -1, dtype=np.int64), w, support, far, False
    delta, post, wt, ok = robust_update(g, lt, rt, st, wt, prior_info, tukey, iterations, True)
    if not ok:
        return state.copy(), cov.copy(), np.full(n_pts, -1, dtype=np.int64), w, support, far, False
    new_state = state + delta
    new_cov = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            new_cov[i, j] = 0.5 * (post[i, j] + post[j, i])
    for c in range(n_take):
        p = idx[c]
        if wt[c] == 0.0:
            line[p] = -1
            continue
        w[p] = wt[c]
        i = lt[c]
        support[i] += wt[c]
        if x[p] > far[i]:
            far[i] = x[p]
    return new_state, new_cov, line, w, support, far, True


associate_update = numba.njit(cache=True)(associate_update_py)


def draw_py(state, lines, near, far, n_points):
    """Lines of the model drawn as points.

    :param state: ``(n,)`` the model (see :func:`predict`).
    :param lines: ``(m,)`` the lines to draw (0-based among the lines).
    :param near: the first x of every line [m].
    :param far: ``(m,)`` the last x of each [m].
    :param n_points: points per line, equally spaced in x.
    :return: ``(m, n_points, 2)`` x, y [m].
    """
    m = lines.shape[0]
    out = np.empty((m, n_points, 2))
    a1 = state[0]
    a2 = state[1]
    a3 = state[2]
    for c in range(m):
        y0 = state[N_GEOMETRY + lines[c]]
        k = 1.0 / max(1.0 - y0 * (a2 / (SCALE * SCALE)), 0.5)
        step = (far[c] - near) / (n_points - 1)
        for i in range(n_points):
            xi = far[c] if i == n_points - 1 else near + i * step
            u = xi / SCALE
            out[c, i, 0] = xi
            out[c, i, 1] = y0 + a1 * u + k * (a2 * 0.5 * u * u + a3 * u * u * u / 6.0)
    return out


draw = numba.njit(cache=True)(draw_py)
