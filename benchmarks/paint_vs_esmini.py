"""Where aldm-gym paints an OpenDRIVE map against where esmini's RoadManager paints it.

The reference is a small sampler written here from esmini's RoadManager (commit
``0056c240e7d8d8d6e34b03a61d080531e506a9ef``: ``OpenDrive::SetRoadMarkOSIPoints``, the
``<roadMark>`` reading in ``OpenDrive::LoadOpenDriveFile``, ``Position::SetRoadMarkPos``
and ``Position::RoadMark2Track``). It shares only the parsed file, the reference line
and the lane borders with aldm-gym (``parse``, ``plan_view``, ``lanes``), never the
dash logic of ``marks.py``:

* every ``<roadMark>`` record is painted from ``section.s + sOffset`` to the next
  record's start (or the section's end); each of its lines starts at the record's
  start plus the line's ``sOffset`` (the pattern restarts at every record and section);
* whether a line is broken follows the mark's ``type`` (``broken``, ``broken broken``;
  of ``solid broken`` / ``broken solid`` the line on the inside, by ``tOffset``, is the
  solid / broken one); a broken line steps dash ``length`` + ``space`` in the road's s,
  each dash a straight segment from s to ``min(s + length, record end)``, the first
  dash always, the next ones while they start before the record's end;
* ``botts dots`` put one dot every ``space`` in s; solid lines run from the line's
  start to the record's end along the curve;
* a mark without ``<type>`` lines gets esmini's stand-in: ``solid``/``curb`` one line,
  ``broken`` 4 m / 8 m, ``solid solid`` / ``broken broken`` two lines at ±w (w the
  mark's width, else 0.15 m, 0.20 m ``bold``); other types get none (esmini logs
  "No road mark created"), and ``none``, ``grass``, ``edge`` and ``custom`` are no paint;
* a line lies at the lane's outer border (the centre lane at the lane offset) plus the
  line's ``tOffset``.

aldm-gym's paint is :class:`~aldm_gym.roads.opendrive.OpenDriveMap`'s marking lines
(each painted interval) and its bridges' ``overpass_lines``; roads passing under the
driven level (``hidden``) are left out of the reference. Both are sampled every 0.5 m;
a point counts as on the other's paint within 0.15 m of it. Points of aldm-gym's that
lie on a record esmini paints nothing for (``solid broken`` / ``broken solid`` /
``botts dots`` without ``<type>``, ``custom``) are counted apart and left out of the
first share.

Run: ``.venv/bin/python -m benchmarks.paint_vs_esmini [maps ...]`` (default: the
shipped maps and the public maps in ``tests/roads/opendrive/data``).
"""

from __future__ import annotations

import argparse
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from aldm_gym.roads.opendrive import SHIPPED_MAPS, OpenDriveMap, parse_file, shipped_map
from aldm_gym.roads.opendrive.lanes import outer_borders, section_end
from aldm_gym.roads.opendrive.parse import Lane, LaneSection, Road, RoadMark
from aldm_gym.roads.opendrive.plan_view import PlanView
from aldm_gym.types import FloatArray

STEP = 0.5
"""Sampling step along the paint [m]."""

TOLERANCE = 0.15
"""A point lies on paint within this distance of it [m]."""

DECLINED_RADIUS = 0.5
"""A point lies on a record esmini leaves unpainted within this distance of its border [m]."""

PUBLIC_MAPS = Path(__file__).resolve().parents[1] / "tests" / "roads" / "opendrive" / "data"
"""Folder of the public OpenDRIVE maps (see its README)."""

_ESMINI_BROKEN = (4.0, 8.0)  # stand-in <line length space> of 'broken' marks [m]
_ESMINI_WIDTH = {"standard": 0.15, "bold": 0.20}  # width without a width attribute [m]
_ESMINI_EPS = 1e-9  # a record ends this much before the next one starts [m]
_PAINTED = ("solid", "curb", "broken", "solid solid", "broken broken", "solid broken",
            "broken solid", "botts dots")  # fmt: skip
_NO_STAND_IN = ("solid broken", "broken solid", "botts dots")

Segments = FloatArray
"""(M, 4) segments ``(x0, y0, x1, y1)`` [m]; a dot is a segment of length 0."""


def _stand_in(mark: RoadMark) -> list[tuple[float, float, float, float]]:
    """esmini's ``(length, space, tOffset, sOffset)`` lines of a mark without ``<type>``."""
    w = mark.width if mark.width is not None else _ESMINI_WIDTH.get(mark.weight or "", 0.15)
    dash, gap = _ESMINI_BROKEN
    return {
        "solid": [(0.0, 0.0, 0.0, 0.0)],
        "curb": [(0.0, 0.0, 0.0, 0.0)],
        "solid solid": [(0.0, 0.0, -w, 0.0), (0.0, 0.0, w, 0.0)],
        "broken": [(dash, gap, 0.0, 0.0)],
        "broken broken": [(dash, gap, -w, 0.0), (dash, gap, w, 0.0)],
    }.get(mark.type, [])


def _kinds(mark: RoadMark, lane_id: int, count: int) -> list[str]:
    """``"solid"``, ``"broken"`` or ``"dots"`` per line, from the mark's type as esmini does."""
    if mark.type == "botts dots":
        return ["dots"] * count
    if mark.type in ("broken", "broken broken"):
        return ["broken"] * count
    if mark.type in ("solid broken", "broken solid"):
        offsets = [ln.t_offset for ln in mark.lines]
        inner = int(np.argmax(offsets)) if lane_id <= 0 else int(np.argmin(offsets))
        inner_kind, outer_kind = (
            ("broken", "solid") if mark.type == "broken solid" else ("solid", "broken")
        )
        return [inner_kind if k == inner else outer_kind for k in range(count)]
    return ["solid"] * count


class _Line:
    """World position of one line of one record: its lane border plus ``tOffset``."""

    def __init__(
        self, road: Road, plan: PlanView, section: LaneSection, lane: Lane, t_offset: float
    ) -> None:
        self.road, self.plan, self.section, self.lane = road, plan, section, lane
        self.t_offset = t_offset

    def at(self, s: FloatArray) -> FloatArray:
        """(N, 2) world points at reference ``s`` (clipped to the road) [m]."""
        s = np.clip(np.asarray(s, dtype=np.float64), 0.0, self.plan.length)
        t = outer_borders(self.road, self.section, s)[self.lane.id][0] + self.t_offset
        x, y, h = self.plan.position(s)
        return np.stack([x - t * np.sin(h), y + t * np.cos(h)], axis=1)

    def along(self, s0: float, s1: float) -> Segments:
        """The line from ``s0`` to ``s1`` as segments of at most :data:`STEP` [m]."""
        n = max(1, int(np.ceil((s1 - s0) / STEP)))
        p = self.at(np.linspace(s0, s1, n + 1))
        return np.concatenate([p[:-1], p[1:]], axis=1)


def _chord(a: FloatArray, b: FloatArray) -> Segments:
    """The straight segment from ``a`` to ``b``, cut into pieces of at most :data:`STEP`."""
    n = max(1, int(np.ceil(float(np.hypot(*(b - a))) / STEP)))
    p = a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)
    return np.concatenate([p[:-1], p[1:]], axis=1)


def _record_paint(line: _Line, kind: str, length: float, space: float, s0: float, s1: float):
    """Segments of one line of one record, ``s0`` its start, ``s1`` the record's end."""
    if kind == "solid":
        return [line.along(s0, s1)] if s1 > s0 else []
    out, s = [], s0
    period = space if kind == "dots" else length + space
    while True:
        if kind == "dots":
            p = line.at(np.array([s]))
            out.append(np.concatenate([p, p], axis=1))
        else:
            ends = line.at(np.array([s, min(s + length, s1)]))
            out.append(_chord(ends[0], ends[1]))
        s += period
        if period <= 0.0 or s > s1 - _ESMINI_EPS:
            return out


def _mark_paint(
    road: Road, plan: PlanView, sec: LaneSection, lane: Lane, mark: RoadMark, span: tuple
) -> tuple[list[Segments], list[Segments]]:
    """Painted and declined segments of one record spanning ``span = (start, end)`` in s."""
    s_mark, s_end = span
    if mark.lines:
        lines = [(ln.length, ln.space, ln.t_offset, ln.s_offset) for ln in mark.lines]
    else:
        lines = _stand_in(mark)
    unpainted = (mark.type in _NO_STAND_IN and not mark.lines) or (
        mark.type == "custom" and bool(mark.lines)
    )
    declined = [_Line(road, plan, sec, lane, 0.0).along(s_mark, s_end)] if unpainted else []
    if mark.type not in _PAINTED or not lines:
        return [], declined
    if mark.type in ("solid broken", "broken solid") and len(lines) < 2:
        return [], declined  # esmini stops: such a mark needs two lines
    painted = []
    for (length, space, t_off, s_off), kind in zip(
        lines, _kinds(mark, lane.id, len(lines)), strict=True
    ):
        line = _Line(road, plan, sec, lane, t_off)
        painted += _record_paint(line, kind, length, space, s_mark + s_off, s_end)
    return painted, declined


def reference_paint(path: Path, skip: Iterable[str] = ()) -> tuple[Segments, Segments]:
    """esmini's paint of a map, and the borders of the records it leaves unpainted.

    :param skip: road ids left out.
    :returns: ``(painted, declined)`` segments [m].
    """
    painted, declined = [np.zeros((0, 4))], [np.zeros((0, 4))]
    skip = set(skip)
    for road in parse_file(path, warn=False).roads:
        if road.id in skip:
            continue
        plan = PlanView(road.geometries)
        for j, sec in enumerate(road.sections):
            end = section_end(road, j, plan.length)
            for lane in sec.lanes:
                marks = lane.road_marks
                for m, mark in enumerate(marks):
                    nxt = sec.s + marks[m + 1].s_offset if m + 1 < len(marks) else end
                    span = (sec.s + mark.s_offset, max(0.0, nxt - _ESMINI_EPS))
                    ours, theirs = _mark_paint(road, plan, sec, lane, mark, span)
                    painted += ours
                    declined += theirs
    return np.concatenate(painted), np.concatenate(declined)


def aldm_paint(odr: OpenDriveMap) -> Segments:
    """aldm-gym's paint: each painted interval of each marking line, and the bridges'."""
    out = [np.zeros((0, 4))]
    for m in odr.markings:
        for u0, u1 in m.painted:
            n = max(1, int(np.ceil((u1 - u0) / STEP)))
            u = np.linspace(u0, u1, n + 1)
            p = np.stack([np.interp(u, m.u, m.xy[:, 0]), np.interp(u, m.u, m.xy[:, 1])], axis=1)
            out.append(np.concatenate([p[:-1], p[1:]], axis=1))
    for x0, y0, x1, y1, _ in odr.overpass_lines:
        out.append(_chord(np.array([x0, y0]), np.array([x1, y1])))
    return np.concatenate(out)


def points(segments: Segments) -> FloatArray:
    """(P, 2) sample points of segments of at most :data:`STEP`: every start, and every
    end that does not start the next segment [m]."""
    if not len(segments):
        return np.zeros((0, 2))
    ends = segments[:, 2:]
    joined = np.zeros(len(segments), dtype=bool)
    joined[:-1] = np.all(np.abs(ends[:-1] - segments[1:, :2]) < 1e-9, axis=1)
    return np.concatenate([segments[:, :2], ends[~joined]])


def on_paint(pts: FloatArray, segments: Segments, radius: float = TOLERANCE) -> np.ndarray:
    """Whether each point lies within ``radius`` of a segment (segments of at most
    :data:`STEP`)."""
    hit = np.zeros(len(pts), dtype=bool)
    if not len(pts) or not len(segments):
        return hit
    a, b = segments[:, :2], segments[:, 2:]
    tree = cKDTree(0.5 * (a + b))
    reach = radius + 0.5 * STEP + 1e-6
    for k, near in enumerate(tree.query_ball_point(pts, reach)):
        if not near:
            continue
        d = b[near] - a[near]
        w = pts[k] - a[near]
        den = np.maximum((d * d).sum(axis=1), 1e-18)
        f = np.clip((w * d).sum(axis=1) / den, 0.0, 1.0)
        hit[k] = bool((np.hypot(*(w - f[:, None] * d).T) <= radius).any())
    return hit


def agreement(path: Path) -> dict[str, float]:
    """Shares of one map: aldm-gym's points on esmini's paint and the converse.

    :returns: ``aldm_points``, ``aldm_on_esmini`` (share of the points not on a record
        esmini leaves unpainted), ``declined`` (points left out so), ``esmini_points``,
        ``esmini_on_aldm``.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        odr = OpenDriveMap.from_file(path)
    ours = aldm_paint(odr)
    ref, declined = reference_paint(path, skip=odr.hidden)
    p_ours, p_ref = points(ours), points(ref)
    off = on_paint(p_ours, declined, DECLINED_RADIUS) & ~on_paint(p_ours, ref)
    kept = p_ours[~off]
    return {
        "aldm_points": float(len(p_ours)),
        "aldm_on_esmini": float(on_paint(kept, ref).mean()) if len(kept) else float("nan"),
        "declined": float(off.sum()),
        "esmini_points": float(len(p_ref)),
        "esmini_on_aldm": float(on_paint(p_ref, ours).mean()) if len(p_ref) else float("nan"),
    }


def default_maps() -> list[Path]:
    """The shipped maps, then the public maps in :data:`PUBLIC_MAPS`."""
    return [shipped_map(n) for n in SHIPPED_MAPS] + sorted(PUBLIC_MAPS.glob("*.xodr"))


def main(argv: list[str] | None = None) -> None:
    """Print a Markdown table, one row per map."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("maps", nargs="*", type=Path, help="OpenDRIVE files (default: all)")
    args = parser.parse_args(argv)
    print(
        "| map | aldm-gym points | on esmini's paint | on records esmini leaves unpainted "
        "| esmini points | on aldm-gym's paint |"
    )
    print("|---|---|---|---|---|---|")
    for path in args.maps or default_maps():
        r = agreement(path)
        print(
            f"| `{path.name}` | {r['aldm_points']:.0f} | {100 * r['aldm_on_esmini']:.1f} % "
            f"| {r['declined']:.0f} | {r['esmini_points']:.0f} "
            f"| {100 * r['esmini_on_aldm']:.1f} % |",
            flush=True,
        )


if __name__ == "__main__":
    main()
