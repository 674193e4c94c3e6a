"""Bridges in an OpenDRIVE map: which roads pass over the driven ones, and their paint.

highway-env's roads are flat, so a map is driven on one level. Two roads whose
reference lines cross without a link between them are a flat crossing when their
heights there (``elevationProfile``) differ by less than :data:`BRIDGE_CLEARANCE`, and
one road passing over the other otherwise. At such a crossing the road of the larger
linked network (total reference-line length of the roads joined to it by road links
and junction connections; on a tie, the lower road) is *driven*, and the other one is
*off the level*:

- above the driven road it is a **bridge**: not driven, and its painted markings become
  overpass lines (:attr:`~aldm_gym.roads.opendrive.OpenDriveMap.overpass_lines`) that
  the line sensor reports at their height above the driven road (the ALDM's ``z_band``
  ignores them, the naive detection does not);
- below it, the road is **hidden**: not driven and not seen (the deck covers it).

A road is off the level as soon as one crossing puts it there. Roads linked to a
bridge (its ramps) stay on the driven level: they are flattened like every map road.
The height of a bridge's paint is taken against the driven road at the nearest
crossing along the bridge, so a bridge that climbs or falls keeps its true height
over the road below it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aldm_gym.roads.opendrive.geometry import PlanView
from aldm_gym.roads.opendrive.lanes import cubic_at
from aldm_gym.roads.opendrive.marks import MarkPiece, piece_line
from aldm_gym.roads.opendrive.parse import Road
from aldm_gym.types import FloatArray

BRIDGE_CLEARANCE = 3.0
"""Height difference of two crossing reference lines from which one passes over the
other [m]; below it the crossing is flat."""

CROSSING_STEP = 2.0
"""Sampling step of the reference lines when looking for crossings [m]."""

OVERPASS_STEP = 2.0
"""Longest segment of a bridge's painted markings [m] (chord error < 5 mm down to a
100 m radius)."""

_CHUNK = 64
"""Segments per bounding box when pairing two reference lines."""


@dataclass(frozen=True)
class Crossing:
    """Two roads' reference lines crossing with at least the clearance between them.

    :ivar upper: id of the higher road.
    :ivar s_upper: its reference arc length at the crossing [m].
    :ivar z_upper: its height there [m].
    :ivar lower: id of the lower road.
    :ivar s_lower: its reference arc length at the crossing [m].
    :ivar z_lower: its height there [m].
    """

    upper: str
    s_upper: float
    z_upper: float
    lower: str
    s_lower: float
    z_lower: float


def elevation(road: Road, s: FloatArray) -> FloatArray:
    """Height of a road's reference line at arc lengths ``s`` [m] (0 without a profile)."""
    return cubic_at(road.elevation, np.asarray(s, dtype=np.float64))[0]


def _samples(road: Road, plan: PlanView) -> tuple[FloatArray, FloatArray]:
    n = max(1, math.ceil(plan.length / CROSSING_STEP))
    s = np.linspace(0.0, plan.length, n + 1)
    x, y, _ = plan.position(s)
    return s, np.stack([x, y], axis=1)


def _boxes(xy: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per chunk of segments: (lo (C, 2), hi (C, 2)) of their vertices."""
    n = len(xy) - 1
    starts = np.arange(0, n, _CHUNK)
    lo = np.array([xy[a : min(a + _CHUNK, n) + 1].min(axis=0) for a in starts])
    hi = np.array([xy[a : min(a + _CHUNK, n) + 1].max(axis=0) for a in starts])
    return lo, hi


def _intersections(p: FloatArray, q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Crossings of polylines ``p`` (N, 2) and ``q`` (M, 2).

    :returns: ``(i + t, j + u)``: fractional vertex indices on ``p`` and ``q``, one entry
        per crossing (parallel overlaps are not crossings).
    """
    p_lo, p_hi = _boxes(p)
    q_lo, q_hi = _boxes(q)
    overlap = np.all(p_lo[:, None] <= q_hi[None], axis=2) & np.all(
        q_lo[None] <= p_hi[:, None], axis=2
    )
    found_p, found_q = [], []
    for a, b in zip(*np.nonzero(overlap), strict=True):
        i0, j0 = a * _CHUNK, b * _CHUNK
        p0 = p[i0 : min(i0 + _CHUNK, len(p) - 1)]
        p1 = p[i0 + 1 : min(i0 + _CHUNK, len(p) - 1) + 1]
        q0 = q[j0 : min(j0 + _CHUNK, len(q) - 1)]
        q1 = q[j0 + 1 : min(j0 + _CHUNK, len(q) - 1) + 1]
        r = p1 - p0
        d = q1 - q0
        w = q0[None] - p0[:, None]  # (P, Q, 2)
        den = r[:, None, 0] * d[None, :, 1] - r[:, None, 1] * d[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[..., 0] * d[None, :, 1] - w[..., 1] * d[None, :, 0]) / den
            u = (w[..., 0] * r[:, None, 1] - w[..., 1] * r[:, None, 0]) / den
        # Half-open on both: a crossing exactly at a shared vertex counts once.
        hit = (den != 0.0) & (t >= 0.0) & (t < 1.0) & (u >= 0.0) & (u < 1.0)
        ii, jj = np.nonzero(hit)
        found_p.append(i0 + ii + t[ii, jj])
        found_q.append(j0 + jj + u[ii, jj])
    if not found_p:
        return np.zeros(0), np.zeros(0)
    return np.concatenate(found_p), np.concatenate(found_q)


def crossings(
    roads: dict[str, Road],
    plan_views: dict[str, PlanView],
    linked: set[frozenset[str]],
    clearance: float = BRIDGE_CLEARANCE,
) -> list[Crossing]:
    """Every place where two unlinked roads' reference lines cross ``clearance`` apart.

    :param linked: unordered pairs of road ids joined by a road link or a junction
        connection (their meeting is not a crossing).
    :returns: crossings in the roads' file order, each pair's along the first road.
        Without any ``elevationProfile`` in the map there are none (checked first).
    """
    if not any(road.elevation for road in roads.values()):
        return []  # every road level at 0 m: no crossing can be a bridge
    ids = list(roads)
    sampled = {rid: _samples(roads[rid], plan_views[rid]) for rid in ids}
    lo = np.array([sampled[rid][1].min(axis=0) for rid in ids])
    hi = np.array([sampled[rid][1].max(axis=0) for rid in ids])
    overlap = np.all(lo[:, None] <= hi[None], axis=2) & np.all(lo[None] <= hi[:, None], axis=2)
    out = []
    for a, b in zip(*np.nonzero(np.triu(overlap, k=1)), strict=True):
        ra, rb = ids[a], ids[b]
        if frozenset((ra, rb)) in linked:
            continue
        (sa, pa), (sb, pb) = sampled[ra], sampled[rb]
        fa, fb = _intersections(pa, pb)
        at_a = np.interp(fa, np.arange(len(sa)), sa)
        at_b = np.interp(fb, np.arange(len(sb)), sb)
        za = elevation(roads[ra], at_a)
        zb = elevation(roads[rb], at_b)
        for k in np.argsort(at_a, kind="stable"):
            if abs(za[k] - zb[k]) < clearance:
                continue
            hi_a = za[k] > zb[k]
            out.append(
                Crossing(
                    upper=ra if hi_a else rb,
                    s_upper=float(at_a[k] if hi_a else at_b[k]),
                    z_upper=float(za[k] if hi_a else zb[k]),
                    lower=rb if hi_a else ra,
                    s_lower=float(at_b[k] if hi_a else at_a[k]),
                    z_lower=float(zb[k] if hi_a else za[k]),
                )
            )
    return out


def levels(
    lengths: dict[str, float],
    linked: set[frozenset[str]],
    found: Sequence[Crossing],
) -> tuple[dict[str, tuple[Crossing, ...]], frozenset[str]]:
    """Which roads are bridges and which are hidden (see the module docstring).

    :param lengths: road id -> reference-line length [m].
    :returns: ``(bridges, hidden)``: bridge road id -> the crossings where it passes
        over a driven road; the ids of the roads passing under one.
    """
    parent = {rid: rid for rid in lengths}

    def root(r: str) -> str:
        while parent[r] != r:
            parent[r] = parent[parent[r]]
            r = parent[r]
        return r

    for pair in sorted(linked, key=sorted):
        a, b = sorted(pair)
        if a in parent and b in parent:
            parent[root(a)] = root(b)
    size: dict[str, float] = {}
    for rid, length in lengths.items():
        size[root(rid)] = size.get(root(rid), 0.0) + length
    bridges: dict[str, list[Crossing]] = {}
    hidden: set[str] = set()
    for c in found:
        if size[root(c.upper)] > size[root(c.lower)]:
            hidden.add(c.lower)
        else:
            bridges.setdefault(c.upper, []).append(c)
    # A road off the level is off it everywhere: a bridge crossing a hidden road, or
    # a hidden road under a bridge, is not seen there either.
    bridges = {
        rid: [c for c in cs if c.lower not in hidden and c.lower not in bridges]
        for rid, cs in bridges.items()
        if rid not in hidden
    }
    return {rid: tuple(cs) for rid, cs in bridges.items() if cs}, frozenset(hidden)


def overpass_segments(
    pieces: Sequence[MarkPiece], road: Road, over: Sequence[Crossing]
) -> FloatArray:
    """A bridge road's painted markings as world segments at their height.

    :param pieces: the bridge road's marking pieces.
    :param road: the bridge road.
    :param over: the crossings where it passes over the driven level (at least one).
    :returns: ``(B, 5)`` rows ``(x0, y0, x1, y1, z)`` [m] in OpenDRIVE's frame; ``z`` is
        the segment's mean height above the driven road at the nearest crossing along
        the bridge. Consecutive segments of one painted stretch share their end points.
    """
    s_cross = np.array([c.s_upper for c in over])
    z_cross = np.array([c.z_lower for c in over])
    rows = []
    for p in pieces:
        line = piece_line(p)
        for u0, u1 in line.painted:
            n = max(1, math.ceil((u1 - u0) / OVERPASS_STEP))
            u = np.linspace(u0, u1, n + 1)
            x = np.interp(u, p.u, p.xy[:, 0])
            y = np.interp(u, p.u, p.xy[:, 1])
            s = np.interp(u, p.u, p.s)
            near = np.abs(s[:, None] - s_cross[None]).argmin(axis=1)
            z = elevation(road, s) + p.height - z_cross[near]
            rows.append(np.stack([x[:-1], y[:-1], x[1:], y[1:], 0.5 * (z[:-1] + z[1:])], axis=1))
    return np.concatenate(rows) if rows else np.zeros((0, 5))
