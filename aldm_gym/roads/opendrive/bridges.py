"""Bridges in an OpenDRIVE map: which roads pass over the driven ones, and their paint.

highway-env's roads are flat, so a map is driven on one level. Two roads whose
reference lines cross without a link between them are a flat crossing when their
heights there (``elevationProfile``) differ by less than :data:`BRIDGE_CLEARANCE`, and
one road passing over the other otherwise. Which roads make up the driven level is
decided road by road in order of rank (:func:`levels`): first the total
reference-line length of the road's linked network (the roads joined to it by road
links and junction connections), then its own lane-metres (within one network, e.g. an
interchange whose ramps join both roads, the motorway before the road it crosses),
then the lower road first. A road is

- **hidden** when it passes under a road already driven: not driven and not seen (the
  deck covers it);
- a **bridge** when it passes over a road already driven: not driven, and its painted
  markings become overpass lines
  (:attr:`~aldm_gym.roads.opendrive.OpenDriveMap.overpass_lines`) that the line sensor
  reports at their height above the driven road (the ALDM's ``z_band`` ignores them,
  the naive detection does not);
- **driven** otherwise, also when it passes under a bridge (a road beside the motorway
  that the same bridge spans).

Roads linked to a bridge (its ramps) stay on the driven level: they are flattened like
every map road. The height of a bridge's paint is taken against the driven road at the
nearest crossing along the bridge, so a bridge that climbs or falls keeps its true
height over the road below it.

Limitation: the sensor samples each line at its x grid, so a bridge marking at right
angles to the sensor's axis (within about atan(dx / length) of it, under 1° for a 2 m
grid and a 160 m bridge) has no point; at 75° a bridge gives about 15 points per line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aldm_gym.roads.opendrive.lanes import cubic_at, section_end
from aldm_gym.roads.opendrive.marks import MarkPiece, chain_pieces
from aldm_gym.roads.opendrive.parse import Road
from aldm_gym.roads.opendrive.plan_view import PlanView
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


def lane_metres(road: Road, length: float) -> float:
    """Sum over the road's lane sections of lanes (centre lane excluded) times length [m]."""
    total = 0.0
    for k, sec in enumerate(road.sections):
        lanes = sum(1 for lane in sec.lanes if lane.id != 0)
        total += lanes * max(0.0, section_end(road, k, length) - sec.s)
    return total


def levels(
    lengths: dict[str, float],
    linked: set[frozenset[str]],
    found: Sequence[Crossing],
    weights: dict[str, float] | None = None,
) -> tuple[dict[str, tuple[Crossing, ...]], frozenset[str]]:
    """Which roads are bridges and which are hidden (see the module docstring).

    Roads are taken in order of rank: the total length of their linked network, then
    their own ``weights`` (lane-metres, :func:`lane_metres`; default: their length),
    then the lower one first (their least height at a crossing). A road passing under a
    driven road is hidden, one passing over a driven road is a bridge, any other road
    is driven. So a road of a small network under a bridge stays driven when that
    bridge is not itself driven, and within one network (an interchange whose ramps
    join both roads) the road with more lane-metres is driven.

    :param lengths: road id -> reference-line length [m], in file order.
    :param weights: road id -> the tie-break within a network (larger: driven first).
    :returns: ``(bridges, hidden)``: bridge road id -> the crossings where it passes
        over a driven road; the ids of the roads passing under a driven one.
    """
    parent = {rid: rid for rid in lengths}

    def root(r: str) -> str:
        while parent[r] != r:
            parent[r] = parent[parent[r]]
            r = parent[r]
        return r

    for pair in sorted(linked, key=sorted):
        if len(pair) < 2:
            continue  # a road linked to itself (a ring): nothing to join
        a, b = sorted(pair)
        if a in parent and b in parent:
            parent[root(a)] = root(b)
    size: dict[str, float] = {}
    for rid, length in lengths.items():
        size[root(rid)] = size.get(root(rid), 0.0) + length
    weight = weights if weights is not None else lengths
    by_road: dict[str, list[Crossing]] = {rid: [] for rid in lengths}
    height: dict[str, float] = {rid: math.inf for rid in lengths}
    for c in found:
        by_road[c.upper].append(c)
        by_road[c.lower].append(c)
        height[c.upper] = min(height[c.upper], c.z_upper)
        height[c.lower] = min(height[c.lower], c.z_lower)
    order = sorted(
        lengths, key=lambda r: (size[root(r)], weight.get(r, 0.0), -height[r]), reverse=True
    )
    driven: set[str] = set()
    bridges: dict[str, list[Crossing]] = {}
    hidden: set[str] = set()
    for r in order:
        if any(c.lower == r and c.upper in driven for c in by_road[r]):
            hidden.add(r)
        elif any(c.upper == r and c.lower in driven for c in by_road[r]):
            bridges[r] = []
        else:
            driven.add(r)
    for r in bridges:
        bridges[r] = [c for c in by_road[r] if c.upper == r and c.lower in driven]
    return {rid: tuple(cs) for rid, cs in bridges.items()}, frozenset(hidden)


def overpass_segments(
    pieces: Sequence[MarkPiece], road: Road, length: float, over: Sequence[Crossing]
) -> FloatArray:
    """A bridge road's painted markings as world segments at their height.

    :param pieces: the bridge road's marking pieces (chained here across its lane
        sections and road-mark records, as the map chains its ground markings).
    :param road: the bridge road.
    :param length: its reference-line length [m].
    :param over: the crossings where it passes over the driven level (at least one).
    :returns: ``(B, 5)`` rows ``(x0, y0, x1, y1, z)`` [m] in OpenDRIVE's frame; ``z`` is
        the segment's mean height above the driven road at the nearest crossing along
        the bridge. The segments of one painted stretch follow each other, each
        starting where the one before ends.
    """
    s_cross = np.array([c.s_upper for c in over])
    z_cross = np.array([c.z_lower for c in over])
    rows = []
    for line in chain_pieces(pieces, {road.id: length}, set())[0]:
        for u0, u1 in line.painted:
            n = max(1, math.ceil((u1 - u0) / OVERPASS_STEP))
            u = np.linspace(u0, u1, n + 1)
            x = np.interp(u, line.u, line.xy[:, 0])
            y = np.interp(u, line.u, line.xy[:, 1])
            s = np.interp(u, line.u, line.s)
            near = np.abs(s[:, None] - s_cross[None]).argmin(axis=1)
            z = elevation(road, s) + line.height - z_cross[near]
            rows.append(np.stack([x[:-1], y[:-1], x[1:], y[1:], 0.5 * (z[:-1] + z[1:])], axis=1))
    return np.concatenate(rows) if rows else np.zeros((0, 5))
