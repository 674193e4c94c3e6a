"""Kernels of the lane-model filter (:class:`aldm_gym.sensor.lane_filter.LaneModelFilter`).

:func:`curve_table` tabulates the reference curve (heading, curvature nodes) and the
derivatives the measurement rows need; :func:`project` puts points in its frame (arc
length, signed distance). :func:`predict` moves the model by the odometry;
:func:`associate_update` is the rest of a frame's estimation: the gating of every
point, and the measurement update with the associated points, in information form,
re-weighted by Tukey's biweight (:func:`robust_update`); :func:`existence` keeps the
lines' hits and misses; :func:`draw_on` draws lines of the model as points and
:func:`lateral_std` gives each drawn point's standard deviation; :func:`spans` is
where each line was measured; :func:`one_stripe` keeps one stripe of a double line per
line (:func:`any_closer` first tells whether a frame can hold one);
:func:`measurements` picks a frame's valid rows; :func:`receded` checks the far ends;
:func:`fit` is the start's Gauss-Newton update. A frame of the filter is a handful of
kernel calls and a little bookkeeping.

The state is the shared shape (:data:`N_GEOMETRY` entries) followed by one offset per
line; a point on line ``j`` has the measurement row ``(g_0 .. g_N, e_j)`` (``N =
N_NODES``). The information matrix is small (:data:`N_GEOMETRY` + lines, about
seventeen at most) and symmetric positive definite: it is solved and
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

N_NODES = 6
"""Curvature nodes of the reference curve, :data:`NODE_STEP` apart from the sensor."""

NODE_STEP = 18.0
"""Arc length between two curvature nodes [m] (nodes at 0, 18, 36, 54, 72 and 90 m):
a kink of the curvature (a clothoid transition starting in view) lies within one node
step of a node, and a curvature step (a straight meeting an arc with no transition, as
OpenDRIVE allows) is matched with less overshoot the closer the nodes (on the drive
benchmark's curvature-step map with vehicles and worn, noisy paint, both ego lines
correct in 0.942 of the frames against 0.921 with five nodes 22.5 m apart). Seven
nodes 15 m apart let worn paint bend the model (``features`` worn 1.000 → 0.915): see
``docs/aldm.md``, "Lane-model filter"."""

N_GEOMETRY = 1 + N_NODES
"""State entries of the shared shape: the heading and the curvature at each node
(see :mod:`aldm_gym.sensor.lane_filter`)."""

SCALE = 100.0
"""Length scale ``L`` of the state [m]: the shape is kept as ``psi L`` and ``kappa_k
L^2`` (all in metres), so that the covariance of a 100 m model is well conditioned."""


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

    :param g: ``(N, N_GEOMETRY)`` the shape's part of each point's measurement row.
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
    if iterations < 1:
        raise ValueError("robust_update needs at least one solve")
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


TABLE_STEP = 4.0
"""Arc-length step of the reference curve's table [m] (:func:`curve_table`)."""

TABLE_MARGIN = 16.0
"""The table runs this far [m] in x beyond the farthest point: a point up to 12 m
inside a bend has its foot point farther on than its own x."""

_X, _Y, _C, _S, _K = 0, 1, 2, 3, 4
"""Columns of :func:`curve_table`: x, y, cos and sin of the heading, the curvature;
then the moments (x, y) of each shape entry from column :data:`_M`, and each shape
entry's measurement row from column :data:`_H`."""

_M = 5
_H = _M + 2 * N_GEOMETRY
_COLS = _H + N_GEOMETRY


def _theta_py(state, s, phi):
    """The reference curve's heading at arc length ``s`` [m] [rad]; ``phi`` (length
    :data:`N_GEOMETRY`) receives its derivative by each shape entry in SI units
    (1 for the heading; for node ``k`` the integral of its hat function up to ``s``).
    The curvature is linear between the nodes, constant beyond the last one and
    before the first."""
    phi[0] = 1.0
    theta = state[0] / SCALE
    for k in range(1, N_GEOMETRY):
        phi[k] = 0.0
    if s <= 0.0:
        phi[1] = s
        return theta + state[1] / (SCALE * SCALE) * s
    h = NODE_STEP
    for j in range(N_NODES - 1):
        lo = j * h
        if s <= lo:
            break
        t = min(s, lo + h) - lo
        a = t - 0.5 * t * t / h  # weight of node j
        b = 0.5 * t * t / h  # weight of node j + 1
        phi[1 + j] += a
        phi[2 + j] += b
    top = (N_NODES - 1) * h
    if s > top:
        phi[N_NODES] += s - top
    for k in range(1, N_GEOMETRY):
        theta += phi[k] * state[k] / (SCALE * SCALE)
    return theta


_theta = numba.njit(cache=True)(_theta_py)


def _kappa_py(state, s):
    """The reference curve's curvature at arc length ``s`` [m] [1/m]."""
    h = NODE_STEP
    if s <= 0.0:
        return state[1] / (SCALE * SCALE)
    j = int(s // h)
    if j >= N_NODES - 1:
        return state[N_NODES] / (SCALE * SCALE)
    t = (s - j * h) / h
    return ((1.0 - t) * state[1 + j] + t * state[2 + j]) / (SCALE * SCALE)


_kappa = numba.njit(cache=True)(_kappa_py)


def _simpson_step_py(tab, k, state, s, out, phi0, phim, phi1):
    """``out`` = the curve's row at arc length ``s`` [m], by Simpson's rule from row
    ``k`` of ``tab``; ``phi0`` holds the heading's derivatives at row ``k`` (as
    :func:`_theta` gives them), ``phim`` and ``phi1`` receive those at the middle and
    at ``s``."""
    s0 = k * TABLE_STEP
    sm = 0.5 * (s0 + s)
    thm = _theta(state, sm, phim)
    th1 = _theta(state, s, phi1)
    cm, sn_m = math.cos(thm), math.sin(thm)
    c1, sn1 = math.cos(th1), math.sin(th1)
    c0, sn0 = tab[k, _C], tab[k, _S]
    w = (s - s0) / 6.0
    out[_X] = tab[k, _X] + w * (c0 + 4.0 * cm + c1)
    out[_Y] = tab[k, _Y] + w * (sn0 + 4.0 * sn_m + sn1)
    out[_C] = c1
    out[_S] = sn1
    out[_K] = _kappa(state, s)
    # moments of the normal n = (-sin, cos) weighted by d theta / d entry, and the
    # measurement row n(s) . moment (over the entry's scale)
    for p in range(N_GEOMETRY):
        col = _M + 2 * p
        mx = tab[k, col] - w * (phi0[p] * sn0 + 4.0 * phim[p] * sn_m + phi1[p] * sn1)
        my = tab[k, col + 1] + w * (phi0[p] * c0 + 4.0 * phim[p] * cm + phi1[p] * c1)
        out[col] = mx
        out[col + 1] = my
        scale = SCALE if p == 0 else SCALE * SCALE
        out[_H + p] = (-sn1 * mx + c1 * my) / scale


_simpson_step = numba.njit(cache=True)(_simpson_step_py)


def curve_table_py(state, x_max):
    """The reference curve of ``state`` tabulated every :data:`TABLE_STEP` of arc
    length from the sensor (s = 0) until its x passes ``x_max`` [m] by
    :data:`TABLE_MARGIN` (or
    its arc length ``1.6 x_max + 10``: a quarter turn within the view is more than any
    road here makes; R 100 m turns 0.9 rad in 90 m).

    The reference curve starts at the sensor with heading ``psi``; its curvature is
    linear in arc length between :data:`N_NODES` nodes :data:`NODE_STEP` apart
    (a clothoid spline). Columns (:data:`_X` ...): x, y [m], cos and sin of the
    heading, the curvature [1/m], for each shape entry ``p`` the moment ``int_0^s
    (d theta / d p)(t) n(t) dt`` (x and y; ``n`` the unit normal to the left), and the
    measurement rows ``n(s) . moment`` over each entry's scale; all by Simpson's rule
    per step.
    """
    cap = int((1.6 * max(x_max, 0.0) + 10.0) / TABLE_STEP) + 2
    tab = np.zeros((cap, _COLS))
    phi0 = np.empty(N_GEOMETRY)
    phim = np.empty(N_GEOMETRY)
    phi1 = np.empty(N_GEOMETRY)
    th = _theta(state, 0.0, phi0)
    tab[0, _C] = math.cos(th)
    tab[0, _S] = math.sin(th)
    tab[0, _K] = _kappa(state, 0.0)
    n = 1
    while n < cap:
        _simpson_step(tab, n - 1, state, n * TABLE_STEP, tab[n], phi0, phim, phi1)
        phi0, phi1 = phi1, phi0  # this step's end is the next one's start
        n += 1
        if tab[n - 1, _X] > x_max + TABLE_MARGIN:
            break
    return tab[:n]


curve_table = numba.njit(cache=True)(curve_table_py)


def _locate_py(tab, px, py, g):
    """Point ``(px, py)`` [m] in the reference curve's frame: returns ``(s, l)``, its
    foot point's arc length ``s`` [m] and its signed distance ``l`` [m] to the left of
    the curve; ``g`` receives ``dh/da`` of the measurement ``h = y0_j - l`` for the
    shape entries ``a`` as the state holds them (about ``(s/L, (s/L)^2/2 ...)`` on a
    straight road, the cubic model's rows), interpolated in the table (which has at
    least three rows).

    The foot point lies between the table's node ``k`` whose tangential component is
    not negative and the next; from node ``k`` the curve is taken as the circle of
    the node's curvature (exact for an arc; within ~2 mm on a 60 m clothoid
    transition into R 100 m, whose curvature changes over the 4 m step).
    """
    h = TABLE_STEP
    n = tab.shape[0]
    k = min(max(int(px / h), 0), n - 2)
    f = (px - tab[k, _X]) * tab[k, _C] + (py - tab[k, _Y]) * tab[k, _S]
    while f < 0.0 and k > 0:
        k -= 1
        f = (px - tab[k, _X]) * tab[k, _C] + (py - tab[k, _Y]) * tab[k, _S]
    while k < n - 2:
        q = (px - tab[k + 1, _X]) * tab[k + 1, _C] + (py - tab[k + 1, _Y]) * tab[k + 1, _S]
        if q < 0.0:
            break
        k += 1
        f = q
    lk = -(px - tab[k, _X]) * tab[k, _S] + (py - tab[k, _Y]) * tab[k, _C]
    kap = tab[k, _K]
    # distance to the circle through node k with its tangent and curvature, in the
    # form that stays exact as the curvature goes to 0 (a straight line: l = lk)
    bend = 1.0 - kap * lk
    lt = (2.0 * lk - kap * (lk * lk + f * f)) / (1.0 + math.sqrt(kap * kap * f * f + bend * bend))
    if abs(kap * f) < 1e-12:
        d = f
    else:
        d = math.atan2(kap * f, bend) / kap
    s = k * h + d
    # the rows by quadratic interpolation over three nodes (exact near the sensor,
    # where the curvature entries' rows grow as s^2 / 2)
    t = d / h
    c = min(max(k, 1), n - 2)
    t += k - c
    w0 = 0.5 * t * (t - 1.0)
    w1 = (1.0 - t) * (1.0 + t)
    w2 = 0.5 * t * (t + 1.0)
    for p in range(N_GEOMETRY):
        g[p] = w0 * tab[c - 1, _H + p] + w1 * tab[c, _H + p] + w2 * tab[c + 1, _H + p]
    return s, lt


_locate = numba.njit(cache=True)(_locate_py)


def _max_py(x):
    """The largest of ``x`` (0 for none)."""
    top = 0.0
    for v in x:
        top = max(top, v)
    return top


_max = numba.njit(cache=True)(_max_py)


def project_on_py(tab, x, y):
    """Points in the frame of the reference curve tabulated in ``tab``
    (:func:`curve_table`, to at least the points' x): :func:`_locate` each.

    :param x: ``(N,)`` the points' x [m] (ahead of the sensor).
    :param y: ``(N,)`` their y [m].
    :return: ``(s, l, g)``: arc length of each foot point [m], signed distance to the
        left of the reference curve [m], and ``(N, N_GEOMETRY)`` the shape's part of
        each point's measurement row.
    """
    n_pts = x.shape[0]
    s_out = np.zeros(n_pts)
    l_out = np.zeros(n_pts)
    g = np.zeros((n_pts, N_GEOMETRY))
    for p in range(n_pts):
        s_out[p], l_out[p] = _locate(tab, x[p], y[p], g[p])
    return s_out, l_out, g


project_on = numba.njit(cache=True)(project_on_py)


def project_py(state, x, y):
    """:func:`project_on` the reference curve of ``state`` (the shape, heading and node
    curvatures, then the offsets)."""
    return project_on(curve_table(state, _max(x)), x, y)


project = numba.njit(cache=True)(project_py)


def predict_py(state, cov, dx, dy, dpsi, travel, q_shape, q_offset, q_width, q_far, far_trend):
    """The filter's predict step: the model moved into the new sensor frame.

    The origin advances ``dx`` along the old x and ``dy`` along the old y [m], the
    axes turn by ``dpsi`` [rad]. The new origin's foot point on the old reference
    curve (arc length ``s_e``, distance ``l_e`` to its left) becomes the new
    reference curve's start: the heading there less ``dpsi``; the node curvatures
    those of the old curve ``s_e`` farther on (linear between the old nodes; beyond
    the last one, its curvature and ``far_trend`` times the last node step's trend),
    as the parallel curve through the origin has them
    (``kappa / (1 - l_e kappa)``); the offsets less ``l_e``. The covariance moves
    with the Jacobian of that map (the offsets' rows are the measurement rows at
    ``s_e``; the foot point held, and the parallel-curve factor applied as to the
    mean: an approximation within 1 % for the ego's offsets from the curve) and grows
    by the process noise times ``travel`` [m].

    :param state: ``(n,)`` the shape (heading, node curvatures) then one offset per line.
    :param cov: ``(n, n)`` its covariance.
    :param q_shape: ``(N_GEOMETRY, N_GEOMETRY)`` process noise covariance of the shape
        entries (as the state holds them) per metre of travel.
    :param q_offset: of the lines' common offset [m / sqrt(m)].
    :param q_width: of each line's own offset [m / sqrt(m)].
    :param q_far: the road's curvature rate where the curve is extrapolated [1/m^2]:
        a node moved a distance ``d`` beyond the old last node (new road entering the
        view) gets the variance ``(q_far d)^2`` on top of its held curvature.
    :param far_trend: how much of the last node step's curvature change goes on
        beyond the last node (0: its curvature held; 1: the clothoid continued).
    :return: ``(state, cov)`` predicted (new arrays; ``cov`` symmetric).
    """
    n = state.shape[0]
    tab = curve_table(state, abs(dx))
    he = np.empty(N_GEOMETRY)
    s_e, l_e = _locate(tab, dx, dy, he)
    phi = np.empty(N_GEOMETRY)
    theta_e = _theta(state, s_e, phi)
    f = np.eye(n)
    out = state.copy()
    out[0] = (theta_e - dpsi) * SCALE
    for p in range(1, N_GEOMETRY):
        f[0, p] = phi[p] * SCALE / (SCALE * SCALE)
    # node k of the new curve lies at s_e + k NODE_STEP on the old one
    for k in range(N_NODES):
        at = s_e + k * NODE_STEP
        j = int(at // NODE_STEP)
        row_k = 1 + k
        for p in range(1, N_GEOMETRY):
            f[row_k, p] = 0.0
        if at <= 0.0:
            f[row_k, 1] = 1.0
        elif j >= N_NODES - 1:
            # beyond the last node: its curvature, plus far_trend times the last node
            # step's change carried on (0: held)
            u = far_trend * (at - (N_NODES - 1) * NODE_STEP) / NODE_STEP
            f[row_k, N_NODES] = 1.0 + u
            f[row_k, N_NODES - 1] = -u
        else:
            t = (at - j * NODE_STEP) / NODE_STEP
            f[row_k, 1 + j] = 1.0 - t
            f[row_k, 2 + j] = t
        kappa = 0.0
        for p in range(1, N_GEOMETRY):
            kappa += f[row_k, p] * state[p]
        grow = 1.0 / max(1.0 - l_e * kappa / (SCALE * SCALE), 0.5)
        out[row_k] = kappa * grow
        for p in range(1, N_GEOMETRY):
            f[row_k, p] *= grow
    for j in range(N_GEOMETRY, n):
        out[j] = state[j] - l_e
        for p in range(N_GEOMETRY):
            f[j, p] = he[p]
    fp = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += f[i, k] * cov[k, j]
            fp[i, j] = acc
    p = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            acc = 0.0
            for k in range(n):
                acc += fp[i, k] * f[j, k]
            if i < N_GEOMETRY and j < N_GEOMETRY:
                acc += q_shape[i, j] * travel
                if i == j and i >= 1:
                    beyond = s_e + (i - 1) * NODE_STEP - (N_NODES - 1) * NODE_STEP
                    if beyond > 0.0:
                        acc += (q_far * beyond * SCALE * SCALE) ** 2
            elif i >= N_GEOMETRY and j >= N_GEOMETRY:
                q = q_offset * q_offset
                if i == j:
                    q += q_width * q_width
                acc += q * travel
            p[i, j] = acc
            p[j, i] = acc
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
    x,
    y,
    state,
    cov,
    point_std,
    point_std_slope,
    sigmas,
    gate_min,
    gate_max,
    tukey,
    iterations,
    s_max,
):
    """One frame's association and robust update of the lane model.

    Every point is put in the predicted reference curve's frame (:func:`project`);
    it goes to the line nearest in that frame whose gate it falls in (``sigmas``
    predicted standard deviations of the line there, the state's and the point's,
    clipped to ``[gate_min, gate_max]``); the associated points update the model in
    information form, first weighted by Tukey's biweight of their innovation, then
    re-weighted by it (:func:`robust_update`). Points the update gives no weight are
    free again, and so are points whose foot point lies more than ``s_max`` [m] along
    the curve (the model's range along the road). In a bend, x up to the range
    reaches farther along the road than the curvature nodes, beyond which the model
    only holds the last node's curvature: such points would bend that node to
    whatever the road does next (a straight after an arc pulled it past zero).

    :param x: ``(N,)`` the points' x [m] (finite, ahead of the sensor).
    :param y: ``(N,)`` their y [m].
    :param state: ``(n,)`` the predicted state (see :func:`predict`).
    :param cov: ``(n, n)`` its covariance.
    :param point_std: a point's standard deviation at x = 0 [m] ...
    :param point_std_slope: ... plus this much per metre ahead [m/m].
    :return: ``(state, cov, line, support, far, ok)``: the updated state and
        covariance (the predicted ones when no point was associated or ``ok`` is
        False), each point's line (-1: free), each line's support (the sum of its
        points' robust weights) and farthest point's x (-inf: none), and False when an
        information matrix was not positive definite (rounding: every point is then
        free and the prediction kept).
    """
    n = state.shape[0]
    n_lines = n - N_GEOMETRY
    n_pts = x.shape[0]
    line = np.full(n_pts, -1, dtype=np.int64)
    support = np.zeros(n_lines)
    far = np.full(n_lines, -np.inf)
    s_foot, lat, g_all = project(state, x, y)
    r0 = np.zeros(n_pts)
    var0 = np.zeros(n_pts)
    n_take = 0
    for p in range(n_pts):
        if s_foot[p] > s_max:
            continue
        gpg = 0.0
        for a in range(N_GEOMETRY):
            acc = 0.0
            for b in range(N_GEOMETRY):
                acc += cov[a, b] * g_all[p, b]
            gpg += g_all[p, a] * acc
        sig = point_std + point_std_slope * x[p]
        best = np.inf
        for i in range(n_lines):
            j = N_GEOMETRY + i
            res = lat[p] - state[j]
            cross = 0.0
            for a in range(N_GEOMETRY):
                cross += g_all[p, a] * cov[a, j]
            var = gpg + 2.0 * cross + cov[j, j] + sig * sig
            gate = sigmas * math.sqrt(max(var, 0.0))
            gate = min(max(gate, gate_min), gate_max)
            d = abs(res)
            if d <= gate and d < best:
                best = d
                line[p] = i
                r0[p] = res
                var0[p] = var
        if line[p] >= 0:
            n_take += 1
    if n_take == 0:
        return state.copy(), cov.copy(), line, support, far, True
    # the taken points, first weighted by the innovation over its standard deviation
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
        for a in range(N_GEOMETRY):
            g[c, a] = g_all[p, a]
        lt[c] = line[p]
        rt[c] = r0[p]
        sig = point_std + point_std_slope * x[p]
        st[c] = sig
        e = abs(rt[c]) / math.sqrt(max(var0[p], sig * sig)) / tukey
        t = 1.0 - e * e
        wt[c] = t * t if e < 1.0 else 0.0
    prior_info, ok = _inverse(cov)
    if not ok:
        return state.copy(), cov.copy(), np.full(n_pts, -1, dtype=np.int64), support, far, False
    delta, post, wt, ok = robust_update(g, lt, rt, st, wt, prior_info, tukey, iterations, True)
    if not ok:
        return state.copy(), cov.copy(), np.full(n_pts, -1, dtype=np.int64), support, far, False
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
        i = lt[c]
        support[i] += wt[c]
        if x[p] > far[i]:
            far[i] = x[p]
    return new_state, new_cov, line, support, far, True


associate_update = numba.njit(cache=True)(associate_update_py)


def _arc_py(kap, u):
    """An arc of curvature ``kap`` [1/m] and length ``u`` [m] from the origin along x:
    its end ``(fx, fy)`` [m] in the frame of its start (tangent, normal to the left),
    and the cosine and sine of the angle it turns."""
    a = kap * u
    ca, sa = math.cos(a), math.sin(a)
    if abs(a) < 1e-9:
        return u, 0.5 * kap * u * u, ca, sa
    return sa / kap, (1.0 - ca) / kap, ca, sa


_arc = numba.njit(cache=True)(_arc_py)


def draw_on_py(tab, state, lines, near, far, n_points):
    """Lines of the model drawn as points: each line is the parallel curve at its
    offset from the reference curve, sampled at ``n_points`` x equally spaced from
    ``near`` to its ``far`` [m]. Each x is bracketed between two of the table's nodes
    and found on the circle of the lower node's curvature (Newton's method on the
    arc length, as :func:`_locate` takes the curve there).

    :param tab: the reference curve of ``state`` (:func:`curve_table`, to at least
        ``max(far)``).
    :param state: ``(n,)`` the model (see :func:`predict`).
    :param lines: ``(m,)`` the lines to draw (0-based among the lines).
    :param near: the first x of every line [m].
    :param far: ``(m,)`` the last x of each [m].
    :param n_points: points per line.
    :return: ``(m, n_points, 2)`` x, y [m].
    """
    m = lines.shape[0]
    out = np.empty((m, n_points, 2))
    n = tab.shape[0]
    for c in range(m):
        d = state[N_GEOMETRY + lines[c]]
        step = (far[c] - near) / (n_points - 1)
        k = 0
        for i in range(n_points):
            xi = far[c] if i == n_points - 1 else near + i * step
            # the last node whose point of the line lies at or before xi
            while k < n - 2 and tab[k + 1, _X] - d * tab[k + 1, _S] <= xi:
                k += 1
            while k > 0 and tab[k, _X] - d * tab[k, _S] > xi:
                k -= 1
            kap = tab[k, _K]
            ct, st = tab[k, _C], tab[k, _S]
            x0 = tab[k, _X] - d * st
            # on the circle: the line's point at arc u from node k (turned by kap u)
            u = (xi - x0) / max(ct * (1.0 - d * kap), 0.1)
            for _ in range(3):
                fx, fy, ca, sa = _arc(kap, u)
                cx = tab[k, _X] + fx * ct - fy * st
                nx = -(st * ca + ct * sa)  # x of the turned normal
                xl = cx + d * nx
                # d xl / du: the line's tangent's x, (1 - d kap) cos(theta + a)
                dxl = (1.0 - d * kap) * (ct * ca - st * sa)
                u -= (xl - xi) / (dxl if abs(dxl) > 0.1 else 0.1)
            fx, fy, ca, sa = _arc(kap, u)
            cy = tab[k, _Y] + fx * st + fy * ct
            ny = ct * ca - st * sa  # y of the turned normal
            out[c, i, 0] = xi
            out[c, i, 1] = cy + d * ny
    return out


draw_on = numba.njit(cache=True)(draw_on_py)


def lateral_std_py(tab, x, y, lines, cov):
    """``(L, n)`` the standard deviation [m] of the lateral position of drawn points
    ``(x, y)`` (each ``(L, n)``) of the model lines ``lines`` (``(L,)``, 0-based among
    the lines) on the reference curve tabulated in ``tab``: a point of line ``i`` is
    where ``l = y0_i``, so its variance is that of ``y0_i - l`` under the state's
    covariance ``cov`` (the point's measurement row ``(g, e_i)``)."""
    n_lines, n = x.shape
    out = np.zeros((n_lines, n))
    g = np.empty(N_GEOMETRY)
    for c in range(n_lines):
        j = N_GEOMETRY + lines[c]
        for k in range(n):
            _locate(tab, x[c, k], y[c, k], g)
            var = cov[j, j]
            for a in range(N_GEOMETRY):
                acc = 0.0
                for b in range(N_GEOMETRY):
                    acc += cov[a, b] * g[b]
                var += g[a] * acc + 2.0 * g[a] * cov[a, j]
            out[c, k] = math.sqrt(max(var, 0.0))
    return out


lateral_std = numba.njit(cache=True)(lateral_std_py)


def spans_py(x, line, support, n_lines, min_support):
    """``(n_lines, 2)`` per line, the x range ``[from, to]`` [m] of the points ``x``
    that updated it (``line``: each point's line, -1: none), NaN for a line without a
    hit (robust weights summing to less than ``min_support``)."""
    out = np.full((n_lines, 2), np.nan)
    lo = np.full(n_lines, np.inf)
    hi = np.full(n_lines, -np.inf)
    for p in range(x.shape[0]):
        i = line[p]
        if i >= 0:
            lo[i] = min(lo[i], x[p])
            hi[i] = max(hi[i], x[p])
    for i in range(n_lines):
        if support[i] >= min_support and lo[i] < np.inf:
            out[i, 0] = lo[i]
            out[i, 1] = hi[i]
    return out


spans = numba.njit(cache=True)(spans_py)


def any_closer_py(x, y, radius):
    """Whether any two of the points ``(x, y)`` [m] lie closer than ``radius`` [m] to
    each other: a cheap test before :func:`one_stripe` (two stripes of a double line at
    one station are closer than their gap and the station's length together; the line
    sensor samples one line every 2 m)."""
    n = x.shape[0]
    order = np.argsort(x, kind="mergesort")
    r2 = radius * radius
    for a in range(n):
        p = order[a]
        for b in range(a + 1, n):
            q = order[b]
            dx = x[q] - x[p]
            if dx >= radius:
                break
            dy = y[q] - y[p]
            if dx * dx + dy * dy < r2:
                return True
    return False


any_closer = numba.njit(cache=True)(any_closer_py)


def one_stripe_py(s, lat, offsets, reach, gap, station, near):
    """Which points to keep so that each line takes one stripe of a double line.

    Two points at one station (arc lengths ``s`` within ``station`` [m]) whose
    distances ``lat`` to the left of the reference curve differ by less than ``gap``
    [m], both nearest to the same line and within ``reach`` [m] of its offset, are the
    two stripes of one border (a ``solid broken`` centre line: 0.24 m apart). A line
    follows the stripe it lies on near the sensor, where the shape is sure: among the
    line's pairs closer than ``near`` [m] of arc, the stripe nearer its offset more
    often (the one to the right on a tie). Its other stripe's points are not kept at any
    distance: left to the nearest-neighbour gate, a shape that lags a bend far out
    takes the other stripe there, and the 0.24 m step bends the shape the wrong way.
    A line without such a pair near the sensor keeps every point.

    :param s: ``(N,)`` the points' arc lengths along the reference curve [m].
    :param lat: ``(N,)`` their signed distances to the left of it [m].
    :param offsets: ``(n_lines,)`` the lines' offsets [m].
    :return: ``(N,)`` bool, the points kept.
    """
    n = s.shape[0]
    n_lines = offsets.shape[0]
    keep = np.ones(n, dtype=np.bool_)
    if n < 2 or n_lines == 0:
        return keep
    line = np.full(n, -1, dtype=np.int64)
    for p in range(n):
        best = reach
        for i in range(n_lines):
            d = abs(lat[p] - offsets[i])
            if d <= best:
                best = d
                line[p] = i
    order = np.argsort(s, kind="mergesort")
    lo = np.empty(n, dtype=np.int64)
    hi = np.empty(n, dtype=np.int64)
    paired = np.zeros(n, dtype=np.bool_)
    n_pairs = 0
    for a in range(n):
        p = order[a]
        if line[p] < 0 or paired[p]:
            continue
        for b in range(a + 1, n):
            q = order[b]
            if s[q] - s[p] >= station:
                break
            if line[q] != line[p] or paired[q] or abs(lat[q] - lat[p]) >= gap:
                continue
            paired[p] = True
            paired[q] = True
            lo[n_pairs] = p if lat[p] <= lat[q] else q
            hi[n_pairs] = q if lat[p] <= lat[q] else p
            n_pairs += 1
            break
    votes = np.zeros(n_lines, dtype=np.int64)  # > 0: the line is on its lower stripe
    seen = np.zeros(n_lines, dtype=np.bool_)
    for k in range(n_pairs):
        i = line[lo[k]]
        if s[lo[k]] < near or s[hi[k]] < near:
            seen[i] = True
            d_lo = abs(lat[lo[k]] - offsets[i])
            d_hi = abs(lat[hi[k]] - offsets[i])
            if d_lo < d_hi:
                votes[i] += 1
            elif d_hi < d_lo:
                votes[i] -= 1
    for k in range(n_pairs):
        i = line[lo[k]]
        if seen[i]:
            keep[hi[k] if votes[i] >= 0 else lo[k]] = False
    return keep


one_stripe = numba.njit(cache=True)(one_stripe_py)


def draw_py(state, lines, near, far, n_points):
    """:func:`draw_on` the reference curve of ``state``."""
    return draw_on(curve_table(state, _max(far)), state, lines, near, far, n_points)


draw = numba.njit(cache=True)(draw_py)


def existence_py(
    support,
    far,
    conf,
    miss,
    far_old,
    confirmed,
    ids,
    offsets,
    seen,
    travel,
    hit_gain,
    miss_loss,
    min_confidence,
    drop_length,
    max_offset,
    min_spacing,
    lane_spacing,
    min_support,
):
    """The lines' hits and misses in a frame, and which lines are kept.

    A line whose support reaches ``min_support`` is hit: its confidence gains
    ``hit_gain`` of what it lacks to 1, its miss length is reset and its far end set to
    ``far``; otherwise it loses ``seen`` times ``miss_loss`` of its confidence and its
    miss length grows by ``seen`` times ``travel`` [m], ``seen`` being the share of the
    line in view that no vehicle hides (0 for a hidden line: no evidence either way; a
    miss is evidence of absence as far as the line could have been seen). A line is
    confirmed once its confidence reaches ``min_confidence``. Kept: lines missed for at
    most ``drop_length`` [m] and within ``max_offset`` [m] of the sensor; of two kept
    lines closer than ``min_spacing`` [m], the less confident goes (on a tie the
    younger, the larger id), each compared with the nearest kept one to its right, so no
    two kept lines end closer. Two lines at least ``min_spacing`` but less than
    ``lane_spacing`` [m] apart (a narrow strip: a shoulder's edge line beside a lane
    line) both stay while the less confident one is unconfirmed (it has no role yet) or
    at least ``min_confidence``; once it is confirmed and has fallen below that, it
    goes.

    ``conf``, ``miss``, ``far_old`` and ``confirmed`` are updated in place.
    :return: ``(n_lines,)`` bool, the lines kept.
    """
    n = support.shape[0]
    for i in range(n):
        if support[i] >= min_support:
            conf[i] += hit_gain * (1.0 - conf[i])
            miss[i] = 0.0
            far_old[i] = far[i]
        elif seen[i] > 0.0:
            conf[i] *= 1.0 - miss_loss * seen[i]
            miss[i] += travel * seen[i]
        if conf[i] >= min_confidence:
            confirmed[i] = True
    keep = np.empty(n, dtype=np.bool_)
    for i in range(n):
        keep[i] = miss[i] <= drop_length and abs(offsets[i]) <= max_offset
    order = np.argsort(offsets, kind="mergesort")
    prev = -1
    for b in order:
        if not keep[b]:
            continue
        if prev >= 0 and offsets[b] - offsets[prev] < lane_spacing:
            a = prev
            if conf[a] < conf[b] or (conf[a] == conf[b] and ids[a] > ids[b]):
                weaker = a
            else:
                weaker = b
            strip = offsets[b] - offsets[prev] >= min_spacing
            if strip and (not confirmed[weaker] or conf[weaker] >= min_confidence):
                prev = b
                continue
            keep[weaker] = False
            if weaker == a:
                prev = b
        else:
            prev = b
    return keep


existence = numba.njit(cache=True)(existence_py)


def receded_py(far_old, far, confirmed, length):
    """Whether a confirmed line hit in this frame (``far`` [m]: its farthest point,
    -inf: no hit) has that point more than ``length`` [m] short of its carried far end
    ``far_old`` [m]."""
    for i in range(far_old.shape[0]):
        if confirmed[i] and far[i] > -math.inf and far_old[i] - far[i] > length:
            return True
    return False


receded = numba.njit(cache=True)(receded_py)


def measurements_py(pts, x_max, z_band):
    """The frame's measurements: ``(x, y)`` [m] of the rows of ``pts`` (``(N, 2|3)``)
    that are finite, at ``0 <= x <= x_max`` and (with a z column) ``|z| <= z_band``,
    in their order."""
    n = pts.shape[0]
    has_z = pts.shape[1] == 3
    x = np.empty(n)
    y = np.empty(n)
    m = 0
    for i in range(n):
        px = pts[i, 0]
        py = pts[i, 1]
        if not (px >= 0.0 and px <= x_max and math.isfinite(py)):
            continue
        if has_z:
            pz = pts[i, 2]
            if not (math.isfinite(pz) and abs(pz) <= z_band):
                continue
        x[m] = px
        y[m] = py
        m += 1
    return x[:m].copy(), y[:m].copy()


measurements = numba.njit(cache=True)(measurements_py)


def fit_py(x, y, line, x0, p0, sigma, tukey, iterations):
    """The update of the prior ``(x0, p0)`` with points ``(x, y)`` [m] on lines
    ``line``, by Gauss-Newton: ``iterations`` times the points are put in the current
    estimate's reference frame (:func:`project`) and the update about the prior is
    solved three times, re-weighted in between by Tukey's biweight at ``tukey``
    (:func:`robust_update`, first weights 1). The start's prior is flat, so the first
    linearisation (a straight road) can be far off in a bend: the iterations bring
    the foot points to the curve.

    :param sigma: ``(N,)`` each point's standard deviation [m].
    :return: ``(state, cov)``: the estimate and its covariance (the last good
        iteration's when an information matrix was not positive definite).
    """
    n = x0.shape[0]
    prior_info, ok = _inverse(p0)
    state = x0.copy()
    cov = p0.copy()
    if not ok:
        return state, cov
    lines = line.astype(np.int64)
    for _ in range(iterations):
        _s, lat, g = project(state, x, y)
        r0 = np.empty(x.shape[0])
        for k in range(x.shape[0]):
            j = N_GEOMETRY + lines[k]
            # the residual of the update about the prior, linearised at ``state``:
            # l - y0_j at the state, plus the rows times the state's move from the prior
            acc = lat[k] - x0[j]
            for a in range(N_GEOMETRY):
                acc += g[k, a] * (state[a] - x0[a])
            r0[k] = acc
        delta, post, _w, ok = robust_update(
            g, lines, r0, sigma, np.ones(x.shape[0]), prior_info, tukey, 3, True
        )
        if not ok:
            break
        for i in range(n):
            state[i] = x0[i] + delta[i]
            for j in range(n):
                cov[i, j] = 0.5 * (post[i, j] + post[j, i])
    return state, cov


fit = numba.njit(cache=True)(fit_py)
