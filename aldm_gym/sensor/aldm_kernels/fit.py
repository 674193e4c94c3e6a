"""Fit stage: the small least-squares fits every trace and the output share.

The ridge-regularised quadratic ``y = A u² + B u + C`` (u = x - x_ref) from its
normal-equation sums, the one update of those running sums (:func:`update_sums`),
and the local quadratic that smooths a traced line (:func:`smooth_at`).
"""

from __future__ import annotations

import math

import numba
import numpy as np


def _inv3_py(m, inv):
    """Inverse of a 3×3 matrix by the adjugate (as the paper's C code, §ALDM).

    Writes the inverse into ``inv`` (zeros when ``det == 0``).

    :return: ``det``.
    """
    c00 = m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]
    c01 = m[1, 2] * m[2, 0] - m[1, 0] * m[2, 2]
    c02 = m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]
    det = m[0, 0] * c00 + m[0, 1] * c01 + m[0, 2] * c02
    if det == 0.0 or not math.isfinite(det):
        inv[:, :] = 0.0
        return 0.0
    inv[0, 0] = c00 / det
    inv[1, 0] = c01 / det
    inv[2, 0] = c02 / det
    inv[0, 1] = (m[0, 2] * m[2, 1] - m[0, 1] * m[2, 2]) / det
    inv[1, 1] = (m[0, 0] * m[2, 2] - m[0, 2] * m[2, 0]) / det
    inv[2, 1] = (m[0, 1] * m[2, 0] - m[0, 0] * m[2, 1]) / det
    inv[0, 2] = (m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1]) / det
    inv[1, 2] = (m[0, 2] * m[1, 0] - m[0, 0] * m[1, 2]) / det
    inv[2, 2] = (m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]) / det
    return det


_inv3 = numba.njit(cache=True)(_inv3_py)


def update_sums_py(s0, s1, s2, s3, s4, t0, t1, t2, u, y, w):
    """The running fit sums with the point ``(u, y)`` added (``w = 1``) or dropped
    (``w = -1``); u = x - x_last [m].

    ``s_k = Σ u^k`` (k = 0..4) and ``t_k = Σ u^k y`` (k = 0..2) of the points in the
    fit window: the normal equations of the quadratic fit ``y = A u² + B u + C``.
    ``w`` is ±1, so ``s + w * v`` is exactly ``s ± v``.
    """
    uu = u * u
    return (
        s0 + w,
        s1 + w * u,
        s2 + w * uu,
        s3 + w * (uu * u),
        s4 + w * (uu * uu),
        t0 + w * y,
        t1 + w * (u * y),
        t2 + w * (uu * y),
    )


update_sums = numba.njit(cache=True, inline="always")(update_sums_py)


def _ridge_quadratic_py(us, ys, n, a0, b0, lam_a, lam_b, a_max, work):
    """Ridge least-squares quadratic ``y = A u^2 + B u + C`` through ``n`` points.

    Gaussian priors ``A ~ a0`` and ``B ~ b0`` enter as ``lam_a = sigma^2/sigma_A^2``
    and ``lam_b = sigma^2/sigma_B^2`` (MAP estimate); ``|A|`` is then bounded by
    ``a_max`` (minimum curve radius) and B, C refitted with A fixed.

    ``work`` is a ``(2, 3, 3)`` scratch array (no allocation per call): ``work[0]``
    receives the regularised normal matrix, ``work[1]`` its inverse.

    :return: ``(A, B, C, inv)``; ``inv = work[1]``, ``sigma^2 * inv`` is the
        coefficient covariance.
    """
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    s4 = 0.0
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for k in range(n):
        s0, s1, s2, s3, s4, t0, t1, t2 = update_sums(
            s0, s1, s2, s3, s4, t0, t1, t2, us[k], ys[k], 1.0
        )
    return ridge_solve(s0, s1, s2, s3, s4, t0, t1, t2, a0, b0, lam_a, lam_b, a_max, work)


_ridge_quadratic = numba.njit(cache=True)(_ridge_quadratic_py)


def ridge_solve_py(s0, s1, s2, s3, s4, t0, t1, t2, a0, b0, lam_a, lam_b, a_max, work):
    """:func:`_ridge_quadratic` from the point sums ``s_k = sum u^k``, ``t_k = sum y u^k``.

    Lets a trace keep running sums over its sliding fit window (:func:`_robust_trace`).
    """
    m = work[0]
    inv = work[1]
    m[0, 0] = s4 + lam_a
    m[0, 1] = s3
    m[0, 2] = s2
    m[1, 0] = s3
    m[1, 1] = s2 + lam_b
    m[1, 2] = s1
    m[2, 0] = s2
    m[2, 1] = s1
    m[2, 2] = s0
    r0 = t2 + lam_a * a0
    r1 = t1 + lam_b * b0
    r2 = t0
    det = _inv3(m, inv)
    if det == 0.0:
        # Degenerate (no points and no prior): the prior alone, through the mean.
        c = t0 / s0 if s0 > 0.0 else 0.0
        return a0, b0, c, inv
    a = inv[0, 0] * r0 + inv[0, 1] * r1 + inv[0, 2] * r2
    b = inv[1, 0] * r0 + inv[1, 1] * r1 + inv[1, 2] * r2
    c = inv[2, 0] * r0 + inv[2, 1] * r1 + inv[2, 2] * r2
    # y'' = kappa (1 + y'^2)^(3/2): the bound on A grows with the slope at u = 0.
    bound = a_max * (1.0 + b * b) ** 1.5
    if abs(a) > bound:
        a = bound if a > 0.0 else -bound
        # [[s2 + lam_b, s1], [s1, s0]] [b, c] = [r1 - a s3, t0 - a s2]
        q00 = s2 + lam_b
        d2 = q00 * s0 - s1 * s1
        v0 = r1 - a * s3
        v1 = t0 - a * s2
        if d2 != 0.0:
            b = (s0 * v0 - s1 * v1) / d2
            c = (q00 * v1 - s1 * v0) / d2
    return a, b, c, inv


ridge_solve = numba.njit(cache=True)(ridge_solve_py)


def smooth_at_py(lx, ly, xq, h, a0, b0, lam_a, lam_b, a_max):
    """Local quadratic (ridge) fit of a line's points at each ``xq`` [m].

    Uses the points within ``h`` of ``xq`` (at least the three nearest), so a value
    inside a dash gap interpolates along the curve rather than along a chord.

    :return: ``(y, slope, a)`` at each ``xq``: value [m], dy/dx [-], half the second
        derivative [1/m].
    """
    k = lx.shape[0]
    nq = xq.shape[0]
    out_y = np.empty(nq)
    out_b = np.empty(nq)
    out_a = np.empty(nq)
    us = np.empty(k)
    vs = np.empty(k)
    work = np.empty((2, 3, 3))
    lo = 0
    for q in range(nq):
        x0 = xq[q]
        while lo < k and lx[lo] < x0 - h:
            lo += 1
        hi = lo
        while hi < k and lx[hi] <= x0 + h:
            hi += 1
        a = lo
        bnd = hi
        # at least three points: widen towards the nearer neighbour
        while bnd - a < 3 and (a > 0 or bnd < k):
            if a == 0:
                bnd += 1
            elif bnd == k:
                a -= 1
            elif x0 - lx[a - 1] <= lx[bnd] - x0:
                a -= 1
            else:
                bnd += 1
        nf = np.int64(0)  # int64, not a literal: one compiled callee (numba)
        for j in range(a, bnd):
            us[nf] = lx[j] - x0
            vs[nf] = ly[j]
            nf += 1
        A, B, C, _ = _ridge_quadratic(us, vs, nf, a0, b0 + 2.0 * a0 * x0, lam_a, lam_b, a_max, work)
        out_y[q] = C
        out_b[q] = B
        out_a[q] = A
    return out_y, out_b, out_a


smooth_at = numba.njit(cache=True)(smooth_at_py)
