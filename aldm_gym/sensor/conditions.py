"""Sensor conditions beyond CarMaker's ideal line sensor (all off by default).

A real lane sensor loses markings behind vehicles and on worn paint, gets noisier with
range, sees clutter (tar seams, old markings, specks) and the markings of a road passing
overhead. :class:`~aldm_gym.sensor.LineSensor` applies these on the grid of sampled
markings before it groups points into line objects (``docs/sensor.md``):

* **masks** hide points of the grid (the point's ``y`` becomes NaN, which the frame
  assembly treats as "not seen"): :func:`_occlude` (vehicle footprints cast shadows),
  :func:`_wear` (worn dashes and worn stretches);
* **extra rows** add objects that are not markings of the road: :func:`_clutter` (tar
  seams parallel to a marking, old markings at a small angle), specks, and
  :func:`overpass_rows` (markings of a bridge, at ``z > 0``).

Road-fixed conditions (worn paint, seams, old markings) must be the same every time
the car passes a place, whatever the episode's seed. They are not drawn from a
generator but from a counter-based hash of (road key, marking, cell along the marking):
the road key digests the road's geometry (:func:`road_key`), so the same road gives the
same worn stretches in every pass, seed and marking model, and nothing needs to be
generated for the whole road up front. Per-frame randomness (specks, noise) comes from
the generator passed to ``LineSensor.measure``.

Kernels follow the package habit: plain-Python ``_foo_py``, compiled ``_foo``.
"""

from __future__ import annotations

import hashlib
import math
import weakref
from typing import Any

import numba
import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.types import FloatArray, IntArray

CELL = 100.0
"""Length of the cells along a marking that each hold at most one worn stretch, seam or
old marking [m]; a rate is therefore at most ``1000 / CELL`` = 10 per km."""

MAX_STRETCH = 500.0
"""Longest worn stretch [m] (a stretch may run on through later cells)."""

SEAM_LENGTH = (20.0, 80.0)
"""Length of a tar seam along its marking [m] (uniform)."""

SEAM_OFFSET = (0.3, 1.0)
"""Lateral distance of a tar seam from its marking [m] (uniform, either side)."""

OLD_LENGTH = (30.0, 80.0)
"""Length of an old marking along the current one [m] (uniform)."""

OLD_START_OFFSET = (0.0, 0.5)
"""Lateral distance of an old marking from the current one where it starts [m]."""

OLD_ANGLE = (math.radians(1.0), math.radians(4.0))
"""Angle between an old marking and the current one [rad] (uniform, either side)."""

SPECK_BAND = 10.0
"""Specks lie at ``|y| <= SPECK_BAND`` [m] of the sensor's axis."""

TRUCK_LENGTH = 10.0
"""A vehicle this long or longer counts as a truck [m]."""

CAR_HEIGHT = 1.5
"""Height of a vehicle shorter than :data:`TRUCK_LENGTH` without a ``HEIGHT`` [m]."""

TRUCK_HEIGHT = 4.0
"""Height of a vehicle of :data:`TRUCK_LENGTH` or longer without a ``HEIGHT`` [m]."""

_MASK32 = 0xFFFFFFFF
_SALT_DASH = 1
_SALT_STRETCH = 2
_SALT_SEAM = 3
_SALT_OLD = 4


# --------------------------------------------------------------------- hashing
def _mul32_py(x: int, c: int) -> int:
    """``x * c mod 2**32`` in int64 arithmetic that cannot overflow (x, c < 2**32)."""
    lo = x * (c & 0xFFFF)
    hi = ((x * (c >> 16)) & 0xFFFF) << 16
    return (lo + hi) & _MASK32


_mul32 = numba.njit(cache=True)(_mul32_py)


def _hash32_py(x: int) -> int:
    """A 32-bit integer mix (``lowbias32``): every input bit affects every output bit."""
    x = x & _MASK32
    x ^= x >> 16
    x = _mul32(x, 0x7FEB352D)
    x ^= x >> 15
    x = _mul32(x, 0x846CA68B)
    x ^= x >> 16
    return x


_hash32 = numba.njit(cache=True)(_hash32_py)


def _uniform_py(key: int, marking: int, cell: int, salt: int, k: int) -> float:
    """A uniform number in [0, 1) fixed by its arguments (road-fixed draws)."""
    h = _hash32(key ^ _hash32(marking & _MASK32))
    h = _hash32(h ^ (cell & _MASK32))
    h = _hash32(h ^ ((salt << 8) | k))
    return h / 4294967296.0


_uniform = numba.njit(cache=True)(_uniform_py)


_KEYS: weakref.WeakKeyDictionary[Any, int] = weakref.WeakKeyDictionary()


KEY_GRID = 1e-3
"""The grid [m] :func:`road_key` rounds the road's numbers to before digesting them."""


def _grid_bytes(values: Any) -> bytes:
    """``values`` rounded to :data:`KEY_GRID` as int64 bytes (non-finite values as a
    fixed sentinel)."""
    arr = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(arr)
    grid = np.where(finite, np.round(np.where(finite, arr, 0.0) / KEY_GRID), -(2.0**62))
    return np.ascontiguousarray(grid.astype(np.int64)).tobytes()


def road_key(road: Any, seed: int = 0) -> int:
    """A 32-bit key of ``road``'s geometry and ``seed``: the road-fixed draws' identity.

    Digests the road's marking geometry (the reference table of a generated road, the
    marking vertices of a map) and paint table, so two roads built alike share their
    worn stretches and clutter, and a road and its twin with the other marking model
    (same geometry) do too. The numbers are digested on a 1 mm grid (:func:`_grid_bytes`),
    so the last-bit differences of numpy's SIMD paths between CPUs do not give the same
    road other wear. Cached per road object.

    :param road: the marked road (:class:`~aldm_gym.roads.MarkedRoad`).
    :param seed: the sensor's ``wear_seed``: another seed wears other stretches.
    """
    try:
        base = _KEYS[road]
    except (KeyError, TypeError):
        digest = hashlib.blake2b(digest_size=8)
        reference = getattr(road, "reference", None)
        if reference is not None:
            digest.update(_grid_bytes(reference.xy))
        markings = getattr(road, "markings", None)
        xy = getattr(markings, "xy", None)
        if xy is not None:
            digest.update(_grid_bytes(xy))
        tab = road.marking_table
        for name in ("phase", "period", "dash", "paint", "paint_start"):
            digest.update(_grid_bytes(tab[name]))
        base = int.from_bytes(digest.digest()[:4], "little")
        try:
            _KEYS[road] = base
        except TypeError:
            pass
    return _hash32_py(base ^ _hash32_py(seed & _MASK32))


# ------------------------------------------------------------------ worn paint
def _piece_py(
    j: int,
    u: float,
    phase: FloatArray,
    period: FloatArray,
    broken: np.ndarray,
    paint: FloatArray,
    paint_start: IntArray,
) -> int:
    """Index of the dash (or painted interval) of marking ``j`` at arc length ``u``;
    -1 on a continuous marking without explicit intervals (as ``_assemble`` counts)."""
    a = paint_start[j]
    b = paint_start[j + 1]
    if b > a:
        lo = a
        hi = b
        while lo < hi:  # the last interval starting at or before u
            mid = (lo + hi) // 2
            if paint[mid, 0] <= u:
                lo = mid + 1
            else:
                hi = mid
        return lo - 1 - a
    if broken[j]:
        return math.floor((u - phase[j]) / period[j])
    return -1


_piece = numba.njit(cache=True)(_piece_py)


def _in_stretch_py(
    key: int, j: int, u: float, salt: int, rate: float, lo: float, hi: float
) -> bool:
    """Whether ``u`` [m] lies in a road-fixed stretch of marking ``j`` (worn paint).

    Each cell of :data:`CELL` metres holds a stretch with probability ``rate * CELL``
    (``rate`` [1/m]), starting uniformly in the cell, of length uniform in [lo, hi].
    """
    c = math.floor(u / CELL)
    back = math.ceil(hi / CELL)
    p_cell = rate * CELL
    for cc in range(c - back, c + 1):
        if _uniform(key, j, cc, salt, 0) < p_cell:
            start = (cc + _uniform(key, j, cc, salt, 1)) * CELL
            length = lo + (hi - lo) * _uniform(key, j, cc, salt, 2)
            if start <= u < start + length:
                return True
    return False


_in_stretch = numba.njit(cache=True)(_in_stretch_py)


def _wear_py(
    ys: FloatArray,
    us: FloatArray,
    rows: IntArray,
    height: FloatArray,
    phase: FloatArray,
    period: FloatArray,
    broken: np.ndarray,
    paint: FloatArray,
    paint_start: IntArray,
    key: int,
    dash_rate: float,
    stretch_rate: float,
    stretch_lo: float,
    stretch_hi: float,
) -> None:
    """Hide worn paint in place: ``ys[r, p] = NaN`` where marking ``rows[r]`` is worn.

    A dash (or explicit painted interval) of a broken marking is missing with
    probability ``dash_rate``; any paint (continuous lines too) lies in a worn stretch
    per :func:`_in_stretch_py` (``stretch_rate`` [1/m], lengths [m]). Barriers
    (``height > 0``) do not wear. Draws are road-fixed (``key``, marking, dash or cell).

    :param ys: ``(R, K)`` lateral positions [m] (modified).
    :param us: ``(R, K)`` arc length along the marking [m].
    """
    m, k = ys.shape
    for r in range(m):
        j = rows[r]
        if height[j] > 0.0:
            continue
        dashes = dash_rate > 0.0 and broken[j]
        for p in range(k):
            u = us[r, p]
            if not (u == u) or not (ys[r, p] == ys[r, p]):
                continue
            worn = False
            if dashes:
                q = _piece(j, u, phase, period, broken, paint, paint_start)
                worn = _uniform(key, j, q, _SALT_DASH, 0) < dash_rate
            if not worn and stretch_rate > 0.0:
                worn = _in_stretch(key, j, u, _SALT_STRETCH, stretch_rate, stretch_lo, stretch_hi)
            if worn:
                ys[r, p] = np.nan


_wear = numba.njit(cache=True)(_wear_py)


# --------------------------------------------------------------------- clutter
def _clutter_py(
    ys: FloatArray,
    us: FloatArray,
    rows: IntArray,
    height: FloatArray,
    key: int,
    seam_rate: float,
    old_rate: float,
) -> tuple[FloatArray, IntArray]:
    """Tar seams and old markings near the painted markings, as extra rows.

    For every paint row (``height == 0``) and each kind, the cells of :data:`CELL`
    metres its visible arc lengths touch are asked (road-fixed) whether they hold a
    seam (probability ``seam_rate * CELL``, ``seam_rate`` [1/m]) or an old marking
    (``old_rate * CELL``). A seam runs parallel to the marking at a constant offset
    (:data:`SEAM_OFFSET`, :data:`SEAM_LENGTH`); an old marking starts beside it
    (:data:`OLD_START_OFFSET`) and diverges at a small angle (:data:`OLD_ANGLE`,
    :data:`OLD_LENGTH`). Each becomes one row of points at the sensor's x grid, whether
    or not the marking is painted there.

    :param ys: ``(R, K)`` noiseless lateral positions of the markings [m] (NaN: absent).
    :param us: ``(R, K)`` arc lengths along them [m].
    :return: ``(cy (V, K), source (V,))``: the rows' y [m] (NaN where absent) and the
        row of ``ys`` each one follows.
    """
    m, k = ys.shape
    n_max = 0
    lo_c = np.zeros(m, dtype=np.int64)
    hi_c = np.zeros(m, dtype=np.int64)
    back = math.ceil(max(SEAM_LENGTH[1], OLD_LENGTH[1]) / CELL)
    for r in range(m):
        umin = np.inf
        umax = -np.inf
        for p in range(k):
            u = us[r, p]
            if u == u and ys[r, p] == ys[r, p]:
                umin = min(umin, u)
                umax = max(umax, u)
        if umin <= umax and height[rows[r]] == 0.0:
            lo_c[r] = math.floor(umin / CELL) - back
            hi_c[r] = math.floor(umax / CELL)
            n_max += 2 * (hi_c[r] - lo_c[r] + 1)
    cy = np.full((n_max, k), np.nan)
    source = np.empty(n_max, dtype=np.int64)
    n = 0
    for r in range(m):
        j = rows[r]
        if height[j] != 0.0 or lo_c[r] > hi_c[r]:
            continue
        for kind in range(2):
            salt = _SALT_SEAM if kind == 0 else _SALT_OLD
            rate = seam_rate if kind == 0 else old_rate
            if rate <= 0.0:
                continue
            length_range = SEAM_LENGTH if kind == 0 else OLD_LENGTH
            for c in range(lo_c[r], hi_c[r] + 1):
                if not (_uniform(key, j, c, salt, 0) < rate * CELL):
                    continue
                start = (c + _uniform(key, j, c, salt, 1)) * CELL
                length = length_range[0] + (length_range[1] - length_range[0]) * _uniform(
                    key, j, c, salt, 2
                )
                side = 1.0 if _uniform(key, j, c, salt, 3) < 0.5 else -1.0
                u4 = _uniform(key, j, c, salt, 4)
                if kind == 0:
                    offset = SEAM_OFFSET[0] + (SEAM_OFFSET[1] - SEAM_OFFSET[0]) * u4
                    slope = 0.0
                else:
                    offset = OLD_START_OFFSET[0] + (OLD_START_OFFSET[1] - OLD_START_OFFSET[0]) * u4
                    angle = OLD_ANGLE[0] + (OLD_ANGLE[1] - OLD_ANGLE[0]) * _uniform(
                        key, j, c, salt, 5
                    )
                    slope = math.tan(angle)
                seen = False
                for p in range(k):
                    u = us[r, p]
                    y = ys[r, p]
                    if u == u and y == y and start <= u < start + length:
                        cy[n, p] = y + side * (offset + slope * (u - start))
                        seen = True
                if seen:
                    source[n] = r
                    n += 1
    return cy[:n], source[:n]


_clutter = numba.njit(cache=True)(_clutter_py)


# ------------------------------------------------------------------- occlusion
def vehicle_height(vehicle: Any) -> float:
    """A highway-env vehicle's height [m]: its ``HEIGHT``, else :data:`TRUCK_HEIGHT`
    when it is :data:`TRUCK_LENGTH` or longer, else :data:`CAR_HEIGHT`."""
    h = getattr(vehicle, "HEIGHT", None)
    if h:
        return float(h)
    return TRUCK_HEIGHT if vehicle.LENGTH >= TRUCK_LENGTH else CAR_HEIGHT


def occluder_array(vehicles: Any) -> FloatArray:
    """World footprints of ``vehicles`` as an ``(V, 6)`` array.

    :param vehicles: highway-env vehicles (``position``, ``heading``, ``LENGTH``,
        ``WIDTH``, optional ``HEIGHT`` > 0) or an ``(V, 6)`` array of world
        ``(x, y, heading, length, width, height)`` [m, rad] (returned as it is).
    :return: ``(V, 6)`` rows ``(x, y, heading, length, width, height)``, the height
        by :func:`vehicle_height`.
    :raises InputError: an array of another shape or with non-finite values.
    """
    if isinstance(vehicles, np.ndarray):
        arr = np.asarray(vehicles, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 6 or not np.isfinite(arr).all():
            raise InputError(
                "occluders must be vehicles or a (V, 6) array of finite "
                f"(x, y, heading, length, width, height), got shape {arr.shape}"
            )
        return arr
    flat: list[float] = []
    for v in vehicles:
        flat += (v.position[0], v.position[1], v.heading, v.LENGTH, v.WIDTH, vehicle_height(v))
    return np.array(flat, dtype=np.float64).reshape(-1, 6)


def _occlude_py(
    xs: FloatArray,
    ys: FloatArray,
    z: FloatArray,
    world: FloatArray,
    ox_w: float,
    oy_w: float,
    yaw: float,
    reach: float,
    sensor_height: float,
) -> None:
    """Hide, in place (``ys = NaN``), the points whose line of sight a vehicle blocks.

    The line of sight runs from the sensor, at height ``sensor_height`` above the
    origin, to the point ``(xs[p], ys[r, p], z[r])``. A vehicle is a box on the road:
    its footprint (centre, heading, half length, half width) up to its height. The
    sight is blocked when it passes through the box: its footprint interval (slab
    clipping of the segment against the footprint) is not empty and the sight's
    height there, lowest at one end of that interval, is at most the vehicle's
    height. A point under a vehicle is hidden; a vehicle whose footprint holds the
    sensor (the ego's own) hides nothing.

    :param xs: ``(K,)`` x grid [m]; ``ys`` ``(R, K)`` noiseless y [m] (modified);
        ``z`` ``(R,)`` each row's height [m].
    :param world: ``(V, 6)`` world footprints from :func:`occluder_array`.
    :param ox_w: the sensor's world x [m]; ``oy_w`` its world y [m].
    :param yaw: the sensor's world heading [rad].
    :param reach: vehicles whose centre is farther from the sensor are skipped [m].
    :param sensor_height: the sensor's height above the road [m].
    """
    m, k = ys.shape
    cyaw = math.cos(yaw)
    syaw = math.sin(yaw)
    for b in range(world.shape[0]):
        dx = world[b, 0] - ox_w
        dy = world[b, 1] - oy_w
        if dx * dx + dy * dy > reach * reach:
            continue
        # The box in the sensor frame (highway-env's world is mirrored: the sensor's
        # left is (sin yaw, -cos yaw), and a heading h becomes yaw - h).
        cx = dx * cyaw + dy * syaw
        cy = dx * syaw - dy * cyaw
        ch = math.cos(yaw - world[b, 2])
        sh = math.sin(yaw - world[b, 2])
        hl = 0.5 * world[b, 3]
        hw = 0.5 * world[b, 4]
        top = world[b, 5]
        # The sensor in the box's frame.
        ox = -cx * ch - cy * sh
        oy = cx * sh - cy * ch
        if abs(ox) <= hl and abs(oy) <= hw:
            continue
        # Cheap reject: a box wholly ahead spans slopes y/x in [s_lo, s_hi].
        ahead = True
        s_lo = np.inf
        s_hi = -np.inf
        near = np.inf
        for corner in range(4):
            a = hl if corner < 2 else -hl
            w = hw if corner % 2 == 0 else -hw
            px = cx + a * ch - w * sh
            py = cy + a * sh + w * ch
            if px <= 0.0:
                ahead = False
            else:
                s_lo = min(s_lo, py / px)
                s_hi = max(s_hi, py / px)
                near = min(near, px)
        for r in range(m):
            zr = z[r]
            for p in range(k):
                x = xs[p]
                y = ys[r, p]
                if not (y == y):
                    continue
                if ahead:
                    if x < near:
                        continue
                    slope = y / x
                    if slope < s_lo or slope > s_hi:
                        continue
                # The point in the box's frame, then slab clipping of the segment.
                qx = (x - cx) * ch + (y - cy) * sh
                qy = -(x - cx) * sh + (y - cy) * ch
                dxl = qx - ox
                dyl = qy - oy
                t0 = 0.0
                t1 = 1.0
                hit = True
                for axis in range(2):
                    o = ox if axis == 0 else oy
                    d = dxl if axis == 0 else dyl
                    half = hl if axis == 0 else hw
                    if d == 0.0:
                        if abs(o) > half:
                            hit = False
                            break
                    else:
                        ta = (-half - o) / d
                        tb = (half - o) / d
                        if ta > tb:
                            ta, tb = tb, ta
                        t0 = max(t0, ta)
                        t1 = min(t1, tb)
                        if t0 > t1:
                            hit = False
                            break
                if not hit:
                    continue
                # Sight height is linear in t: lowest at one end of [t0, t1].
                h0 = sensor_height + t0 * (zr - sensor_height)
                h1 = sensor_height + t1 * (zr - sensor_height)
                if min(h0, h1) <= top:
                    ys[r, p] = np.nan


_occlude = numba.njit(cache=True)(_occlude_py)


# ------------------------------------------------------------------ roadside sight
GROUND_BAND = 0.5
"""Rows of markings up to this height [m] lie on the road (curbs included) and can be
hidden by the roadside; higher ones (bridges) are seen over it."""


def sight_hidden(
    xs: FloatArray, ys: FloatArray, bounds: FloatArray, clearance: float
) -> np.ndarray:
    """Points hidden from the sensor by the roadside (barriers, cuttings, vegetation).

    Sight obstructions stand ``clearance`` beyond the outermost markings on either
    side: at grid x ``x_j`` the clear zone is ``right_j - clearance <= y <= left_j +
    clearance``, with ``left_j`` / ``right_j`` the largest / smallest y of the rows of
    ``bounds`` there and of the sensor's axis (y = 0), no bound where ``bounds`` has
    none. A point ``(x_k, y_k)`` is hidden
    when the straight sight line from the sensor (the origin) to it leaves the zone at
    an earlier grid x: ``y_k x_j / x_k > left_j + clearance`` or ``< right_j -
    clearance`` for some ``x_j < x_k``, i.e. its bearing ``y_k / x_k`` lies beyond the
    tightest earlier bound on the bearing. On a straight road nothing is hidden; in a
    bend of radius R the lines on the inside end where the chord's sagitta ``L² / (8R)``
    reaches the sensor's distance d to the inner edge of the zone, at ``L ≈ sqrt(8 R
    d)`` (R = 500 m, d = 10 m: 200 m; R = 250 m: 141 m).

    :param xs: ``(K,)`` x grid [m], increasing.
    :param ys: ``(R, K)`` y of the rows to test at ``xs`` [m], NaN where absent.
    :param bounds: ``(B, K)`` y of the road's markings at ``xs`` [m] (they set the zone).
    :param clearance: distance of the obstructions beyond the outermost markings [m].
    :return: ``(R, K)`` mask of the hidden points.
    """
    k = len(xs)
    left = np.fmax.reduce(bounds, axis=0) if len(bounds) else np.full(k, np.nan)
    right = np.fmin.reduce(bounds, axis=0) if len(bounds) else np.full(k, np.nan)
    # The sensor's own axis is always in the zone (a car on a shoulder, a road
    # painted on one side only).
    left = np.where(np.isnan(left), np.nan, np.maximum(left, 0.0))
    right = np.where(np.isnan(right), np.nan, np.minimum(right, 0.0))
    ahead = xs > 0.0
    safe = np.where(ahead, xs, 1.0)
    upper = np.where(ahead & ~np.isnan(left), (left + clearance) / safe, np.inf)
    lower = np.where(ahead & ~np.isnan(right), (right - clearance) / safe, -np.inf)
    upper_before = np.concatenate([[np.inf], np.minimum.accumulate(upper)[:-1]])
    lower_before = np.concatenate([[-np.inf], np.maximum.accumulate(lower)[:-1]])
    bearing = ys / safe
    return ahead & ((bearing > upper_before) | (bearing < lower_before))


# -------------------------------------------------------------------- overpass
OVERPASS_Z_STEP = 0.25
"""Largest height step between joined bridge segments of one sensor row [m]."""


def overpass_rows(
    lines: FloatArray, origin: FloatArray, yaw: float, xs: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The markings of bridges crossing above, sampled at the sensor's x grid.

    Consecutive segments that join end to start, run the same way along the sensor's
    x axis and differ in height by at most :data:`OVERPASS_Z_STEP` are one row (a map
    bridge's painted stretch is a chain of short segments); any other segment is a row
    of its own.

    :param lines: ``(B, 5)`` world segments ``(x0, y0, x1, y1, z)`` [m] of the bridge
        markings (the road's ``overpass_lines``).
    :param origin: the sensor's world position (2,) [m].
    :param yaw: the sensor's world heading [rad].
    :param xs: ``(K,)`` x grid [m].
    :return: ``(y (B', K), z (B',))``: each row that crosses the grid, its y at
        ``xs`` (NaN outside it) and its height [m] (its segments' heights weighted by
        the grid points each covers).
    """
    if len(lines) == 0:
        return np.zeros((0, len(xs))), np.zeros(0)
    c, s = math.cos(yaw), math.sin(yaw)
    ax = (lines[:, 0] - origin[0]) * c + (lines[:, 1] - origin[1]) * s
    ay = (lines[:, 0] - origin[0]) * s - (lines[:, 1] - origin[1]) * c
    bx = (lines[:, 2] - origin[0]) * c + (lines[:, 3] - origin[1]) * s
    by = (lines[:, 2] - origin[0]) * s - (lines[:, 3] - origin[1]) * c
    lo = np.minimum(ax, bx)
    hi = np.maximum(ax, bx)
    inside = (xs[None, :] >= lo[:, None]) & (xs[None, :] <= hi[:, None]) & (hi > lo)[:, None]
    way = np.sign(bx - ax)
    joined = np.zeros(len(lines), dtype=bool)
    joined[1:] = (
        (lines[1:, 0] == lines[:-1, 2])
        & (lines[1:, 1] == lines[:-1, 3])
        & (way[1:] == way[:-1])
        & (way[1:] != 0.0)
        & (np.abs(lines[1:, 4] - lines[:-1, 4]) <= OVERPASS_Z_STEP)
    )
    run = np.cumsum(~joined) - 1
    keep_run = np.zeros(run[-1] + 1, dtype=bool)
    keep_run[run[inside.any(axis=1)]] = True
    keep = keep_run[run]
    if not keep.any():
        return np.zeros((0, len(xs))), np.zeros(0)
    ax, ay, bx, by, inside = ax[keep], ay[keep], bx[keep], by[keep], inside[keep]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (xs[None, :] - ax[:, None]) / (bx - ax)[:, None]
    y = np.where(inside, ay[:, None] + t * (by - ay)[:, None], np.nan)
    z = lines[keep, 4].astype(np.float64)
    run = run[keep]
    first = np.flatnonzero(np.r_[True, run[1:] != run[:-1]])
    if len(first) == len(run):  # every row one segment (a generated road's bridges)
        return y, z
    # Segments of a run cover adjacent x intervals: at most two cover a grid point,
    # where they share an end point (and y).
    rows = np.fmax.reduceat(y, first, axis=0)
    count = inside.sum(axis=1)
    return rows, np.add.reduceat(z * count, first) / np.add.reduceat(count, first)
