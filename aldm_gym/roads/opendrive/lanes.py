"""Lane borders of an OpenDRIVE road as lateral offsets t(s) from its reference line.

t is positive to the left of the reference direction. The centre lane (id 0) lies at
the ``laneOffset``; left lanes (ids 1, 2, ...) stack their widths outward to +t, right
lanes (ids -1, -2, ...) to -t. A lane's ``border`` records, used only when it has no
``width`` records (the standard's rule), give its outer border's t directly, measured
from the reference line. Every polynomial is evaluated at ``ds = s - start`` of its
record (``start = section.s + sOffset`` for widths and borders).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aldm_gym.errors import MapError
from aldm_gym.roads.opendrive.parse import Cubic, Lane, LaneSection, Road
from aldm_gym.roads.opendrive.plan_view import PlanView
from aldm_gym.types import FloatArray

_GRID_TOLERANCE = 1e-9
"""Sample positions closer than this are one sample [m]."""


def cubic_at(
    records: Sequence[Cubic], x: FloatArray, base: float = 0.0
) -> tuple[FloatArray, FloatArray]:
    """Piecewise cubic value and slope at ``x`` [m].

    Record ``i`` is valid from ``base + records[i].s`` to the next record's start and is
    evaluated at ``ds = x - base - records[i].s``; before the first record the first one
    is used. No records: zeros.

    :returns: ``(value [m], d value / dx [1])``, shaped like ``x``.
    """
    x = np.asarray(x, dtype=np.float64)
    if not records:
        return np.zeros_like(x), np.zeros_like(x)
    starts = np.array([r.s for r in records]) + base
    index = np.clip(np.searchsorted(starts, x, side="right") - 1, 0, None)
    coef = np.array([(r.a, r.b, r.c, r.d) for r in records])[index]
    ds = x - starts[index]
    a, b, c, d = coef[..., 0], coef[..., 1], coef[..., 2], coef[..., 3]
    value = a + ds * (b + ds * (c + ds * d))
    slope = b + ds * (2.0 * c + 3.0 * d * ds)
    return value, slope


def section_end(road: Road, index: int, plan_length: float) -> float:
    """Reference s where lane section ``index`` ends [m] (the next start or the road's end)."""
    if index + 1 < len(road.sections):
        return road.sections[index + 1].s
    return max(plan_length, road.sections[index].s)


def outer_borders(
    road: Road, section: LaneSection, s: FloatArray, where: str = ""
) -> dict[int, tuple[FloatArray, FloatArray]]:
    """Outer border of every lane of a section, and the centre lane (id 0).

    :param s: (N,) reference arc lengths inside the section [m].
    :param where: text naming the file in errors.
    :returns: lane id -> ``(t (N,) [m], dt/ds (N,) [1])``.
    :raises MapError: a lane has neither width nor border records, or a width
        that is negative (beyond :data:`WIDTH_TOLERANCE`), not finite or more than
        :data:`MAX_OFFSET` at one of ``s``.
    """
    offset = cubic_at(road.lane_offsets, s)
    borders = {0: offset}
    for side in (1, -1):
        inner = offset
        for lane in sorted(
            (ln for ln in section.lanes if ln.id * side > 0), key=lambda ln: abs(ln.id)
        ):
            here = f"{where}, road {road.id!r}, laneSection s={section.s}: lane {lane.id}"
            if lane.widths:
                w, dw = cubic_at(lane.widths, s, section.s)
            elif lane.borders:
                t, dt = cubic_at(lane.borders, s, section.s)
                w, dw = side * (t - inner[0]), side * (dt - inner[1])
            else:
                raise MapError(f"{here} has neither <width> nor <border> records")
            _check_width(w, s, here)
            w = np.maximum(w, 0.0)
            outer = (inner[0] + side * w, inner[1] + side * dw)
            borders[lane.id] = outer
            inner = outer
    return borders


WIDTH_TOLERANCE = 0.01
"""A lane's width may dip this far below zero [m] (rounding at a lane's end); it is
read as 0 there. A larger negative width is an error."""

MAX_OFFSET = 1e4
"""Largest distance of a lane border from the reference line [m]."""


def _check_width(w: FloatArray, s: FloatArray, here: str) -> None:
    """Raise :class:`MapError` unless the width ``w`` (N,) [m] at ``s`` (N,) [m] is
    finite, at least ``-WIDTH_TOLERANCE`` and at most ``MAX_OFFSET``."""
    bad = ~np.isfinite(w) | (w < -WIDTH_TOLERANCE) | (w > MAX_OFFSET)
    if bad.any():
        k = int(np.argmax(bad))
        what = "negative" if w[k] < 0.0 else "not finite" if not np.isfinite(w[k]) else "too wide"
        raise MapError(
            f"{here}: its width is {what} at s={s[k]:.3f} m ({w[k]:.6g} m; a lane is 0 "
            f"to {MAX_OFFSET:g} m wide)"
        )


def inner_border_id(lane_id: int) -> int:
    """Id of the lane whose outer border is this lane's inner border (0: centre lane)."""
    return lane_id - 1 if lane_id > 0 else lane_id + 1


def side_border_ids(lane_id: int) -> tuple[int, int]:
    """Border owners of a lane on its ``(+t side, -t side)`` (left, right of the reference)."""
    if lane_id > 0:
        return lane_id, inner_border_id(lane_id)
    return inner_border_id(lane_id), lane_id


def driving_direction(road: Road, lane: Lane) -> int:
    """+1 if traffic in the lane drives along increasing s, -1 against.

    Right-hand traffic (``rule="RHT"``, the default) drives the right lanes (ids < 0)
    along s, left-hand traffic the left lanes. An OpenDRIVE 1.8 ``direction="reversed"``
    on the lane flips this; ``"both"`` keeps the rule's direction.
    """
    along = lane.id < 0 if road.rule == "RHT" else lane.id > 0
    sign = 1 if along else -1
    return -sign if lane.direction == "reversed" else sign


def sample_positions(road: Road, plan: PlanView, step: float) -> FloatArray:
    """Reference s samples of a road: every ``step`` [m] plus each record's start.

    Starts of geometries, lane sections, lane offsets, widths, borders and road marks
    are included exactly, so no polyline cuts a corner of a piecewise definition.

    :returns: (N,) increasing s from 0 to the road's plan-view length [m].
    """
    length = plan.length
    marks = [plan.starts, [sec.s for sec in road.sections], [o.s for o in road.lane_offsets]]
    for sec in road.sections:
        for lane in sec.lanes:
            marks.append([sec.s + r.s for r in (*lane.widths, *lane.borders)])
            marks.append([sec.s + m.s_offset for m in lane.road_marks])
    n = max(1, int(np.ceil(length / step)))
    grid = np.concatenate([np.linspace(0.0, length, n + 1), *[np.asarray(m, float) for m in marks]])
    grid = np.unique(np.clip(grid, 0.0, length))
    keep = np.concatenate(([True], np.diff(grid) > _GRID_TOLERANCE))
    grid = grid[keep]
    grid[-1] = length
    return grid


@dataclass(frozen=True, eq=False)  # arrays: compared by identity
class SectionSamples:
    """A lane section sampled along its reference line.

    :ivar road_id: the road.
    :ivar index: the section's index in the road.
    :ivar s: (N,) reference arc lengths from the section's start to its end [m].
    :ivar x: (N,) reference-line x [m].
    :ivar y: (N,) reference-line y [m].
    :ivar hdg: (N,) reference-line heading [rad].
    :ivar borders: lane id -> (N,) outer-border t [m] (0: the centre lane).
    """

    road_id: str
    index: int
    s: FloatArray
    x: FloatArray
    y: FloatArray
    hdg: FloatArray
    borders: dict[int, FloatArray]

    def world(self, t: FloatArray) -> FloatArray:
        """World points at lateral offsets ``t`` (N,) [m] from the reference: (N, 2) [m]."""
        return np.stack([self.x - t * np.sin(self.hdg), self.y + t * np.cos(self.hdg)], axis=1)


def sample_sections(
    road: Road, plan: PlanView, step: float, where: str = ""
) -> list[SectionSamples]:
    """Sample every lane section of a road (sections shorter than 1 nm are dropped).

    :param step: sampling step along the reference line [m].
    """
    grid = sample_positions(road, plan, step)
    x, y, hdg = plan.position(grid)
    out = []
    for k, sec in enumerate(road.sections):
        s0, s1 = sec.s, section_end(road, k, plan.length)
        mask = (grid >= s0 - _GRID_TOLERANCE) & (grid <= s1 + _GRID_TOLERANCE)
        if s1 - s0 <= _GRID_TOLERANCE or mask.sum() < 2:
            continue
        s = grid[mask]
        borders = {i: t for i, (t, _) in outer_borders(road, sec, s, where).items()}
        out.append(SectionSamples(road.id, k, s, x[mask], y[mask], hdg[mask], borders))
    return out
