"""Kernels of the lane-model filter (:class:`aldm_gym.sensor.lane_filter.LaneModelFilter`).

:func:`robust_update`: the filter's measurement update with the associated points,
in information form, re-weighted by Tukey's biweight. The state is the shared shape
(3 entries) followed by one offset per line; a point on line ``j`` has the
measurement row ``(g0, g1, g2, e_j)``. The information matrix is small (3 + lines,
at most a dozen) and symmetric positive definite: it is solved and inverted by its
Cholesky factor, written out rather than taken from LAPACK (``np.linalg.cholesky``
in numba), whose kernels pick their SIMD paths at run time: the kernel's sums run in
the order written. (The filter's predict and prior still use numpy's BLAS products:
like the rest of the env, it is bit-reproducible on one machine.) Decisions and their
reasons: ``docs/aldm.md``, section "Lane-model filter". Plain-Python twins
``_name_py`` as in the other kernel modules.
"""

from __future__ import annotations

import math

import numba
import numpy as np

N_GEOMETRY = 3
"""State entries of the shared shape (see :mod:`aldm_gym.sensor.lane_filter`)."""


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
