"""Write the example OpenDRIVE maps shipped in ``aldm_gym/roads/maps/``.

Needs the ``dev`` extra (``scenariogeneration`` writes the files). Run from the
repository root::

    python scripts/make_maps.py

Maps (right-hand traffic, lane width 3.75 m on the motorway, 3.5 m elsewhere):

- ``motorway.xodr``: a curved 3-lane motorway carriageway of 5.4 km in six
  linked road records (radii 1000 m and 800 m, clothoids between lines and arcs), with
  an on-ramp lane that opens from 0 to 3.75 m and later closes, and an exit lane that
  opens and leaves through a direct junction onto an exit road (which curves away).
  Lane lines are ``broken`` with an explicit 6 m / 12 m ``<type><line>`` pattern.
- ``two_plus_one.xodr``: a 2.1 km 2+1 road whose middle (passing) lane alternates
  direction; ``laneOffset`` keeps the outer edges fixed while the passing lane
  changes sides. Lane lines are ``broken`` without a pattern (the reader's default).
- ``bridges.xodr``: a 2.1 km 3-lane carriageway (straight, a right bend of R = 900 m
  between clothoids, straight) under two bridges: a level one crossing at 60°, 6.5 m
  up, and one climbing at 2 % across at 75°, 7 m up where it crosses (the reader tells
  them from flat crossings by their ``elevationProfile``).
- ``features.xodr``: one 640 m road with spirals (including one between two curved
  arcs), ``paramPoly3``, a ``laneOffset`` shift, a lane-width change and double
  (``solid broken``) and ``botts dots`` marks.

And, for the detectors' sequence benchmark (``benchmarks/lane_sequences.py``; not a
shipped map), ``benchmarks/data/curvature_step.xodr``: a 3-lane carriageway that joins
straights and R = 100 m arcs with no transition curve, as OpenDRIVE allows (400 m
straight, a left arc of 90°, 400 m straight, a right arc of 90°, 400 m straight).

scenariogeneration writes everything here; the only post-processing (with lxml) fixes
the header's date so that the files are reproducible.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from lxml import etree
from scenariogeneration import xodr

OUT = Path(__file__).resolve().parents[1] / "aldm_gym" / "roads" / "maps"
BENCH_DATA = Path(__file__).resolve().parents[1] / "benchmarks" / "data"
W = 3.75  # motorway lane width [m]


def solid(
    width: float = 0.15, color: xodr.RoadMarkColor = xodr.RoadMarkColor.white
) -> xodr.RoadMark:
    """A continuous line."""
    return xodr.RoadMark(xodr.RoadMarkType.solid, width, color=color)


def broken(pattern: bool = True) -> xodr.RoadMark:
    """A broken line: explicit 6 m / 12 m pattern, or none (the reader's default)."""
    if pattern:
        return xodr.RoadMark(xodr.RoadMarkType.broken, 0.15, length=6.0, space=12.0, toffset=0.0)
    return xodr.RoadMark(xodr.RoadMarkType.broken, 0.15, color=xodr.RoadMarkColor.white)


def lane(
    width: float | tuple[float, float, float, float],
    mark: xodr.RoadMark,
    kind: xodr.LaneType = xodr.LaneType.driving,
) -> xodr.Lane:
    """A lane with a constant width or cubic width coefficients (a, b, c, d)."""
    a, b, c, d = (width, 0.0, 0.0, 0.0) if isinstance(width, float) else width
    out = xodr.Lane(kind, a=a, b=b, c=c, d=d)
    out.add_roadmark(mark)
    return out


def smooth(w0: float, w1: float, length: float) -> tuple[float, float, float, float]:
    """Cubic from w0 to w1 over length with zero slope at both ends."""
    dw = w1 - w0
    return (w0, 0.0, 3.0 * dw / length**2, -2.0 * dw / length**3)


def centre(mark: xodr.RoadMark | None = None) -> xodr.Lane:
    """The centre lane with its mark."""
    out = xodr.Lane(a=0.0)
    out.add_roadmark(mark if mark is not None else solid())
    return out


def section(
    s: float, right: list[xodr.Lane], left: list[xodr.Lane] = (), mark=None
) -> xodr.LaneSection:
    """A lane section; lanes listed from the centre outward."""
    sec = xodr.LaneSection(s, centre(mark))
    for ln in right:
        sec.add_right_lane(ln)
    for ln in left:
        sec.add_left_lane(ln)
    return sec


def link(pairs: list[tuple[xodr.Lane, xodr.Lane]]) -> xodr.LaneLinker:
    """Lane links between consecutive sections."""
    linker = xodr.LaneLinker()
    for pred, succ in pairs:
        linker.add_link(pred, succ)
    return linker


def road(road_id: int, geometries: list, lanes: xodr.Lanes, junction: int = -1) -> xodr.Road:
    """A road from its geometries and lanes."""
    plan = xodr.PlanView()
    for g in geometries:
        plan.add_geometry(g)
    return xodr.Road(road_id, plan, lanes, road_type=junction)


def simple_lanes(n: int, outer_mark: xodr.RoadMark | None = None) -> xodr.Lanes:
    """One section of n motorway lanes on the right, broken lines, solid edges."""
    lanes = xodr.Lanes()
    right = [lane(W, broken()) for _ in range(n - 1)] + [lane(W, outer_mark or solid())]
    lanes.add_lanesection(section(0.0, right))
    return lanes


def motorway() -> xodr.OpenDrive:
    """Curved 3-lane carriageway with an on-ramp lane and an exit through a junction."""
    odr = xodr.OpenDrive("motorway")
    r1 = road(1, [xodr.Line(600.0)], simple_lanes(3))
    bend_left = [
        xodr.Spiral(0.0, 1 / 1000, 150.0),
        xodr.Arc(1 / 1000, 700.0),
        xodr.Spiral(1 / 1000, 0.0, 150.0),
    ]
    r2 = road(2, bend_left, simple_lanes(3))
    # Road 3: the on-ramp lane -4 opens (0 -> 3.75 m), runs 250 m, and closes.
    lanes = xodr.Lanes()
    a = [lane(W, broken()), lane(W, broken()), lane(W, solid())]
    b = [
        lane(W, broken()),
        lane(W, broken()),
        lane(W, solid()),
        lane(smooth(0.0, W, 150.0), solid(), xodr.LaneType.entry),
    ]
    c = [
        lane(W, broken()),
        lane(W, broken()),
        lane(W, broken()),
        lane(W, solid(), xodr.LaneType.entry),
    ]
    d = [
        lane(W, broken()),
        lane(W, broken()),
        lane(W, broken()),
        lane(smooth(W, 0.0, 150.0), solid(), xodr.LaneType.entry),
    ]
    e = [lane(W, broken()), lane(W, broken()), lane(W, solid())]
    secs = [
        section(0.0, a),
        section(200.0, b),
        section(350.0, c),
        section(600.0, d),
        section(750.0, e),
    ]
    lanes.add_lanesection(secs[0])
    for nxt, (p_lanes, n_lanes) in zip(secs[1:], [(a, b), (b, c), (c, d), (d, e)], strict=True):
        lanes.add_lanesection(nxt, link(list(zip(p_lanes, n_lanes, strict=False))))
    r3 = road(3, [xodr.Line(900.0)], lanes)
    bend_right = [
        xodr.Spiral(0.0, -1 / 800, 120.0),
        xodr.Arc(-1 / 800, 800.0),
        xodr.Spiral(-1 / 800, 0.0, 120.0),
    ]
    r4 = road(4, bend_right, simple_lanes(3))
    # Road 5: the exit lane -4 opens and leaves at the road's end.
    lanes = xodr.Lanes()
    a = [lane(W, broken()), lane(W, broken()), lane(W, solid())]
    b = [
        lane(W, broken()),
        lane(W, broken()),
        lane(W, solid()),
        lane(smooth(0.0, W, 120.0), solid(), xodr.LaneType.exit),
    ]
    c = [
        lane(W, broken()),
        lane(W, broken()),
        lane(W, broken()),
        lane(W, solid(), xodr.LaneType.exit),
    ]
    lanes.add_lanesection(section(0.0, a))
    lanes.add_lanesection(section(300.0, b), link(list(zip(a, b, strict=False))))
    lanes.add_lanesection(section(420.0, c), link(list(zip(b, c, strict=True))))
    r5 = road(5, [xodr.Line(700.0)], lanes)
    r6 = road(
        6,
        [xodr.Line(500.0), xodr.Spiral(0.0, 1 / 1200, 100.0), xodr.Arc(1 / 1200, 600.0)],
        simple_lanes(3),
    )
    exit_lanes = xodr.Lanes()
    exit_lanes.add_lanesection(
        section(0.0, [lane(W, solid(), xodr.LaneType.offRamp)], mark=solid())
    )
    r7 = road(
        7,
        [xodr.Line(60.0), xodr.Spiral(0.0, -1 / 250, 80.0), xodr.Arc(-1 / 250, 200.0)],
        exit_lanes,
    )

    for prev, nxt in ((r1, r2), (r2, r3), (r3, r4), (r4, r5)):
        prev.add_successor(xodr.ElementType.road, nxt.id, xodr.ContactPoint.start)
        nxt.add_predecessor(xodr.ElementType.road, prev.id, xodr.ContactPoint.end)
    for rd in (r1, r2, r3, r4, r5, r6, r7):
        odr.add_road(rd)
    r5.add_successor(xodr.ElementType.junction, 100)
    r6.add_predecessor(xodr.ElementType.junction, 100)
    r7.add_predecessor(xodr.ElementType.junction, 100)
    junction = xodr.DirectJunctionCreator(100, "exit")
    junction.add_connection(r5, r6, [-1, -2, -3], [-1, -2, -3])
    junction.add_connection(r5, r7, -4, -1)
    odr.add_junction_creator(junction)
    return odr


def two_plus_one() -> xodr.OpenDrive:
    """A 2+1 road: the passing lane alternates direction; laneOffset keeps the edges."""
    w, t_len = 3.5, 150.0
    grow, shrink = smooth(0.0, w, t_len), smooth(w, 0.0, t_len)
    lanes = xodr.Lanes()

    def plus_section(s: float) -> tuple[xodr.LaneSection, list, list]:
        right = [lane(w, broken(False)), lane(w, solid())]  # -1 passing, -2
        left = [lane(w, solid())]
        return section(s, right, left), right, left

    def minus_section(s: float) -> tuple[xodr.LaneSection, list, list]:
        right = [lane(w, solid())]
        left = [lane(w, broken(False)), lane(w, solid())]  # 1 passing, 2
        return section(s, right, left), right, left

    def to_minus(s: float) -> tuple[xodr.LaneSection, list, list]:
        right = [lane(shrink, broken(False)), lane(w, solid())]
        left = [lane(grow, broken(False)), lane(w, solid())]
        return section(s, right, left), right, left

    def to_plus(s: float) -> tuple[xodr.LaneSection, list, list]:
        right = [lane(grow, broken(False)), lane(w, solid())]
        left = [lane(shrink, broken(False)), lane(w, solid())]
        return section(s, right, left), right, left

    a, ar, al = plus_section(0.0)
    t1, t1r, t1l = to_minus(600.0)
    b, br, bl = minus_section(750.0)
    t2, t2r, t2l = to_plus(1350.0)
    c, cr, cl = plus_section(1500.0)
    lanes.add_lanesection(a)
    lanes.add_lanesection(t1, link([(ar[0], t1r[0]), (ar[1], t1r[1]), (al[0], t1l[1])]))
    lanes.add_lanesection(b, link([(t1r[1], br[0]), (t1l[0], bl[0]), (t1l[1], bl[1])]))
    lanes.add_lanesection(t2, link([(br[0], t2r[1]), (bl[0], t2l[0]), (bl[1], t2l[1])]))
    lanes.add_lanesection(c, link([(t2r[0], cr[0]), (t2r[1], cr[1]), (t2l[1], cl[0])]))
    # Centre line at t = +1.75 with two lanes on the right, -1.75 with two on the left;
    # in the transitions it follows the shrinking lane so both outer edges stay put.
    h = 0.5 * w
    lanes.add_laneoffset(xodr.LaneOffset(0.0, h, 0.0, 0.0, 0.0))
    lanes.add_laneoffset(xodr.LaneOffset(600.0, *smooth(h, -h, t_len)))
    lanes.add_laneoffset(xodr.LaneOffset(750.0, -h, 0.0, 0.0, 0.0))
    lanes.add_laneoffset(xodr.LaneOffset(1350.0, *smooth(-h, h, t_len)))
    lanes.add_laneoffset(xodr.LaneOffset(1500.0, h, 0.0, 0.0, 0.0))
    geometries = [
        xodr.Line(300.0),
        xodr.Spiral(0.0, 1 / 600, 100.0),
        xodr.Arc(1 / 600, 400.0),
        xodr.Spiral(1 / 600, 0.0, 100.0),
        xodr.Line(400.0),
        xodr.Arc(-1 / 1000, 500.0),
        xodr.Line(300.0),
    ]
    odr = xodr.OpenDrive("two_plus_one")
    odr.add_road(road(1, geometries, lanes))
    return odr


def features() -> xodr.OpenDrive:
    """Spirals, paramPoly3, laneOffset, a width change, double and dotted marks."""
    lanes = xodr.Lanes()
    double = xodr.RoadMark(xodr.RoadMarkType.solid_broken, 0.12, color=xodr.RoadMarkColor.yellow)
    dots = xodr.RoadMark(xodr.RoadMarkType.botts_dots, 0.1)
    a_r = [lane(3.5, broken()), lane(0.75, solid(), xodr.LaneType.shoulder)]
    a_l = [lane(3.5, solid())]
    b_r = [lane(smooth(3.5, 4.0, 200.0), broken()), lane(0.75, solid(), xodr.LaneType.shoulder)]
    b_l = [lane(3.5, dots)]
    c_r = [lane(4.0, broken()), lane(0.75, solid(), xodr.LaneType.shoulder)]
    c_l = [lane(3.5, solid())]
    lanes.add_lanesection(section(0.0, a_r, a_l, mark=double))
    lanes.add_lanesection(
        section(200.0, b_r, b_l, mark=double),
        link([*zip(a_r, b_r, strict=True), *zip(a_l, b_l, strict=True)]),
    )
    lanes.add_lanesection(
        section(400.0, c_r, c_l, mark=solid()),
        link([*zip(b_r, c_r, strict=True), *zip(b_l, c_l, strict=True)]),
    )
    lanes.add_laneoffset(xodr.LaneOffset(0.0, 0.0, 0.0, 0.0, 0.0))
    lanes.add_laneoffset(xodr.LaneOffset(250.0, *smooth(0.0, 0.6, 100.0)))
    lanes.add_laneoffset(xodr.LaneOffset(350.0, 0.6, 0.0, 0.0, 0.0))
    geometries = [
        xodr.Line(100.0),
        xodr.Spiral(0.0, 1 / 150, 60.0),
        xodr.Arc(1 / 150, 80.0),
        xodr.Spiral(1 / 150, -1 / 250, 90.0),
        xodr.Arc(-1 / 250, 60.0),
        xodr.Spiral(-1 / 250, 0.0, 50.0),
        xodr.ParamPoly3(0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.002, -1.5e-5, "arcLength", 100.0),
        xodr.Line(100.0),
    ]
    odr = xodr.OpenDrive("features")
    odr.add_road(road(1, geometries, lanes))
    return odr


def bridge(
    road_id: int, centre: tuple[float, float], heading: float, z: tuple[float, float]
) -> xodr.Road:
    """A 160 m two-lane road crossing above, its middle at ``centre`` heading
    ``heading``, at height ``z[0] + z[1] s`` (s along it)."""
    lanes = xodr.Lanes()
    lanes.add_lanesection(section(0.0, [lane(3.5, solid())], [lane(3.5, solid())], mark=broken()))
    out = road(road_id, [xodr.Line(160.0)], lanes)
    out.planview.set_start_point(
        centre[0] - 80.0 * math.cos(heading), centre[1] - 80.0 * math.sin(heading), heading
    )
    out.add_elevation(0.0, z[0], z[1], 0.0, 0.0)
    return out


def bridges() -> xodr.OpenDrive:
    """A 3-lane motorway carriageway (straight, a 900 m bend, straight) under two bridges."""

    def carriageway() -> tuple[xodr.Road, xodr.Road]:
        bend = [
            xodr.Line(600.0),
            xodr.Spiral(0.0, -1 / 900, 120.0),
            xodr.Arc(-1 / 900, 400.0),
            xodr.Spiral(-1 / 900, 0.0, 120.0),
        ]
        r1 = road(1, bend, simple_lanes(3))
        r1.planview.set_start_point(0.0, 0.0, 0.0)
        r2 = road(2, [xodr.Line(900.0)], simple_lanes(3))
        r1.add_successor(xodr.ElementType.road, 2, xodr.ContactPoint.start)
        r2.add_predecessor(xodr.ElementType.road, 1, xodr.ContactPoint.end)
        return r1, r2

    # Where the last straight starts: scenariogeneration places it (a scratch copy).
    scratch = xodr.OpenDrive("scratch")
    for r in carriageway():
        scratch.add_road(r)
    scratch.adjust_roads_and_lanes()
    x, y, h = scratch.roads["2"].planview.get_start_point()
    odr = xodr.OpenDrive("bridges")
    for r in carriageway():
        odr.add_road(r)
    # A level bridge at 60° over the first straight, 6.5 m above it.
    odr.add_road(bridge(3, (350.0, -1.5 * W), math.radians(60.0), (6.5, 0.0)))
    # A climbing bridge (2 %) at 75° over the last straight, 7 m up where it crosses.
    at = (
        x + 400.0 * math.cos(h) + 1.5 * W * math.sin(h),
        y + 400.0 * math.sin(h) - 1.5 * W * math.cos(h),
    )
    odr.add_road(bridge(4, at, h - math.radians(75.0), (7.0 - 0.02 * 80.0, 0.02)))
    return odr


def curvature_step() -> xodr.OpenDrive:
    """A 3-lane carriageway whose straights and R 100 m arcs meet with no clothoid: the
    curvature steps from 0 to 1/100 m and back, four times."""
    quarter = math.pi / 2 * 100.0  # a 90° arc of R 100 m [m]
    geometries = [
        xodr.Line(400.0),
        xodr.Arc(1 / 100, quarter),
        xodr.Line(400.0),
        xodr.Arc(-1 / 100, quarter),
        xodr.Line(400.0),
    ]
    odr = xodr.OpenDrive("curvature_step")
    r1 = road(1, geometries, simple_lanes(3))
    r1.planview.set_start_point(0.0, 0.0, 0.0)
    odr.add_road(r1)
    return odr


def write(odr: xodr.OpenDrive, name: str, out: Path = OUT) -> Path:
    """Adjust and write a map; fix the header date for reproducible files."""
    odr.adjust_roads_and_lanes()
    path = out / name
    odr.write_xml(str(path))
    tree = etree.parse(str(path))
    tree.getroot().find("header").set("date", "2025-01-01T00:00:00")
    tree.write(str(path), xml_declaration=True, encoding="utf-8", pretty_print=True)
    return path


def main() -> int:
    """Write all example maps."""
    OUT.mkdir(parents=True, exist_ok=True)
    for odr, name in (
        (motorway(), "motorway.xodr"),
        (two_plus_one(), "two_plus_one.xodr"),
        (features(), "features.xodr"),
        (bridges(), "bridges.xodr"),
    ):
        print(write(odr, name))
    BENCH_DATA.mkdir(parents=True, exist_ok=True)
    print(write(curvature_step(), "curvature_step.xodr", BENCH_DATA))
    return 0


if __name__ == "__main__":
    sys.exit(main())
