"""The OpenDRIVE map (aldm_gym.roads.opendrive.map): markings chained across roads,
junctions, lane poses, files of scenariogeneration, the shipped maps."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

import aldm_gym
from aldm_gym.errors import MapError
from aldm_gym.roads.markings import MarkingType
from aldm_gym.roads.opendrive import MarkingLine, OpenDriveMap
from aldm_gym.roads.opendrive.parse import (
    Arc,
    Spiral,
    parse_file,
)
from aldm_gym.roads.opendrive.plan_view import PlanView

from ._xodr import (
    broken_mark,
    geometry_xml,
    lane_xml,
    marking_at,
    road_xml,
    section_xml,
    write_xodr,
)

# ---------------------------------------------------------------- the map


def _link(kind: str, element: str, contact: str = "") -> str:
    cp = f' contactPoint="{contact}"' if contact else ""
    return f'<{kind} elementType="road" elementId="{element}"{cp}/>'


def test_markings_chain_across_linked_roads_forward_and_reversed(tmp_path: Path) -> None:
    lanes1 = lane_xml(-1, marks=broken_mark(), extra='<link><successor id="1"/></link>')
    lanes2 = lane_xml(
        1, marks=broken_mark(), extra='<link><predecessor id="-1"/><successor id="-1"/></link>'
    )
    lanes3 = lane_xml(-1, marks=broken_mark(), extra='<link><predecessor id="1"/></link>')
    # Road 2 runs backwards (end meets end with road 1); road 3 continues road 2's start.
    r1 = road_xml(
        "1",
        geometry_xml("<line/>", 100.0),
        100.0,
        section_xml(right=lanes1),
        _link("successor", "2", "end"),
    )
    r2 = road_xml(
        "2",
        geometry_xml("<line/>", 100.0, x=200.0, hdg=math.pi),
        100.0,
        section_xml(left=lanes2),
        _link("successor", "1", "end") + _link("predecessor", "3", "start"),
    )
    r3 = road_xml(
        "3",
        geometry_xml("<line/>", 55.0, x=200.0),
        55.0,
        section_xml(right=lanes3),
        _link("predecessor", "2", "start"),
    )
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "linked.xodr", r1, r2, r3))
    m = marking_at(odr, 10.0, -3.5)
    assert m.road_ids == ("1", "2", "3")
    assert m.u[-1] == pytest.approx(255.0)
    np.testing.assert_allclose(m.xy[[0, -1]], [[0.0, -3.5], [255.0, -3.5]], atol=1e-9)
    # Each road restarts the pattern at its own s = 0 (road 2 from x = 200, westward);
    # road 2's last dash (x = 194 to 200) and road 3's first touch: one interval.
    starts = np.concatenate([18.0 * np.arange(6), 104.0 + 18.0 * np.arange(5)])
    expected = np.concatenate(
        [np.stack([starts, starts + 6.0], 1), [[194, 206], [218, 224], [236, 242], [254, 255]]]
    )
    np.testing.assert_allclose(m.painted, expected, atol=1e-9)
    assert len(odr.markings) == 2  # that line and the centre line
    assert odr.successors("1", -1, 0) == [("2", 0, 1)]
    assert odr.successors("2", 1, 0) == [("3", 0, -1)]
    assert odr.successors("3", -1, 0) == []
    lane = odr.lanes[("2", 0, 1)]
    assert lane.direction == -1
    centre = next(i for i, mk in enumerate(odr.markings) if mk is not m)
    # Driving east on road 2 (against its s): the centre line is on the driver's left.
    assert (lane.left == centre).all()
    assert (lane.right == next(i for i, mk in enumerate(odr.markings) if mk is m)).all()


def test_successors_through_a_junction(tmp_path: Path) -> None:
    r1 = road_xml(
        "1",
        geometry_xml("<line/>", 100.0),
        100.0,
        section_xml(right=lane_xml(-1) + lane_xml(-2)),
        '<successor elementType="junction" elementId="9"/>',
    )
    conn = [
        road_xml(
            "5",
            geometry_xml("<line/>", 20.0, x=100.0),
            20.0,
            section_xml(right=lane_xml(-1)),
            _link("predecessor", "1", "end"),
            junction="9",
        ),
        road_xml(
            "6",
            geometry_xml('<arc curvature="-0.01"/>', 20.0, x=100.0, y=-3.5),
            20.0,
            section_xml(right=lane_xml(-1)),
            _link("predecessor", "1", "end"),
            junction="9",
        ),
    ]
    junction = (
        '<junction id="9">'
        '<connection id="0" incomingRoad="1" connectingRoad="5" contactPoint="start">'
        '<laneLink from="-1" to="-1"/></connection>'
        '<connection id="1" incomingRoad="1" connectingRoad="6" contactPoint="start">'
        '<laneLink from="-2" to="-1"/></connection></junction>'
    )
    odr = OpenDriveMap.from_file(
        write_xodr(tmp_path / "junction.xodr", r1, *conn, junctions=junction)
    )
    assert odr.successors("1", -1, 0) == [("5", 0, -1)]
    assert odr.successors("1", -2, 0) == [("6", 0, -1)]
    with pytest.raises(ValueError, match="no lane 1 in section 0 of road '1'"):
        odr.successors("1", 1, 0)


def test_opendrive_1_8_leaves_out_the_centre_lane_type_and_the_contact_point(
    tmp_path: Path,
) -> None:
    """OpenDRIVE 1.8 files (ASAM's qc-opendrive examples) give the centre lane no type
    and a junction connection no ``contactPoint``: the connecting road's own link to
    the incoming road says which end joins. A connection that names an unknown road,
    or whose road links to the incoming road at neither end, is refused by name."""
    centre = '<lane id="0"><roadMark sOffset="0" type="solid" width="0.15"/></lane>'

    sec = f'<laneSection s="0"><center>{centre}</center><right>{lane_xml(-1)}</right></laneSection>'

    def road(rid: str, x: float, link: str, junction: str = "-1") -> str:
        return road_xml(rid, geometry_xml("<line/>", 50.0, x=x), 50.0, sec, link, junction=junction)

    def write(connecting: str, connection: str) -> Path:
        incoming = road("1", 0.0, '<successor elementType="junction" elementId="9"/>')
        junction = (
            f'<junction id="9"><connection id="0" incomingRoad="1" {connection}>'
            '<laneLink from="-1" to="-1"/></connection></junction>'
        )
        return write_xodr(tmp_path / "j.xodr", incoming, connecting, junctions=junction)

    at_start = road("5", 50.0, _link("predecessor", "1", "end"), junction="9")
    odr = OpenDriveMap.from_file(write(at_start, 'connectingRoad="5"'))
    assert odr.roads["1"].sections[0].lane(0).type == "none"
    assert odr.junctions["9"].connections[0].contact_point == "start"
    assert odr.successors("1", -1, 0) == [("5", 0, -1)]

    at_end = road("5", 50.0, _link("successor", "1", "end"), junction="9")
    odr = OpenDriveMap.from_file(write(at_end, 'connectingRoad="5"'))
    assert odr.junctions["9"].connections[0].contact_point == "end"

    unlinked = road("5", 50.0, "", junction="9")
    with pytest.raises(MapError, match="links to road '1' or junction '9' at neither end"):
        OpenDriveMap.from_file(write(unlinked, 'connectingRoad="5"'))
    with pytest.raises(MapError, match="junction '9', connection '0': unknown road '7'"):
        OpenDriveMap.from_file(write(at_start, 'connectingRoad="7" contactPoint="start"'))

    # a direct junction: the linked road links to the junction, not to the road
    shipped = aldm_gym.roads.shipped_map("motorway")
    lines = shipped.read_text().splitlines(keepends=True)
    bare = "".join(
        ln.replace(' contactPoint="start"', "") if "<connection" in ln else ln for ln in lines
    )
    connections = [ln for ln in bare.splitlines() if "<connection" in ln]
    assert connections and not any("contactPoint" in ln for ln in connections)
    (tmp_path / "direct.xodr").write_text(bare)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = OpenDriveMap.from_file(shipped).junctions
        got = OpenDriveMap.from_file(tmp_path / "direct.xodr").junctions
    assert got == want


def test_lane_pose_straight_arc_and_left_hand_traffic(tmp_path: Path) -> None:
    widen = lane_xml(-1, width='<width sOffset="0" a="3" b="0.02" c="0" d="0"/>')
    straight = road_xml(
        "s",
        geometry_xml("<line/>", 100.0, x=5.0, y=7.0),
        100.0,
        section_xml(left=lane_xml(1), right=widen),
    )
    radius = 100.0
    arc = road_xml(
        "a",
        geometry_xml(f'<arc curvature="{1 / radius}"/>', 150.0, y=-50.0),
        150.0,
        section_xml(left=lane_xml(1), right=lane_xml(-1)),
    )
    lht = road_xml(
        "l",
        geometry_xml("<line/>", 100.0, y=50.0),
        100.0,
        section_xml(left=lane_xml(1), right=lane_xml(-1)),
        rule="LHT",
    )
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "pose.xodr", straight, arc, lht))
    # Straight: lane -1's centre at t = -(3 + 0.02 s)/2, its heading follows the widening.
    x, y, h = odr.lane_pose("s", -1, 10.0)
    assert (x, y) == pytest.approx((15.0, 7.0 - 1.6)) and h == pytest.approx(math.atan(-0.01))
    x, y, h = odr.lane_pose("s", 1, 10.0)
    assert (x, y, h) == pytest.approx((15.0, 7.0 + 1.75, math.pi))
    # Arc centred at (0, -50 + R): lane -1 on the outside, lane 1 inside and reversed.
    theta = 50.0 / radius
    for lane_id, r, heading in ((-1, radius + 1.75, theta), (1, radius - 1.75, theta - math.pi)):
        x, y, h = odr.lane_pose("a", lane_id, 50.0)
        assert x == pytest.approx(r * math.sin(theta), abs=1e-9)
        assert y == pytest.approx(-50.0 + radius - r * math.cos(theta), abs=1e-9)
        assert h == pytest.approx(heading, abs=1e-12)
    # Left-hand traffic: the left lane drives along s.
    assert odr.lane_pose("l", 1, 20.0) == pytest.approx((20.0, 51.75, 0.0))
    assert odr.lane_pose("l", -1, 20.0) == pytest.approx((20.0, 48.25, math.pi))
    assert odr.lanes[("l", 0, 1)].direction == 1 and odr.lanes[("s", 0, 1)].direction == -1
    with pytest.raises(ValueError, match=r"no lane -2 on road 's' at s=10"):
        odr.lane_pose("s", -2, 10.0)
    with pytest.raises(ValueError, match=r"no lane -1 on road 'x'"):
        odr.lane_pose("x", -1, 10.0)
    with pytest.raises(ValueError, match=r"no lane -1 on road 's' at s=101"):
        odr.lane_pose("s", -1, 101.0)


def test_scenariogeneration_file_reads_back(tmp_path: Path) -> None:
    xodr = pytest.importorskip("scenariogeneration.xodr")
    geometries = [
        xodr.Line(100.0),
        xodr.Spiral(0.0, 0.004, 80.0),
        xodr.Arc(0.004, 120.0),
        xodr.Spiral(0.004, -0.002, 90.0),
        xodr.ParamPoly3(0, 1, 0, 0, 0, 0, 0.002, -1e-5, "arcLength", 40.0),
        xodr.Line(50.0),
    ]
    road = xodr.create_road(geometries, id=1, left_lanes=1, right_lanes=2, lane_width=3.5)
    odr_out = xodr.OpenDrive("roundtrip")
    odr_out.add_road(road)
    odr_out.adjust_roads_and_lanes()
    path = tmp_path / "sg.xodr"
    odr_out.write_xml(str(path))

    parsed = parse_file(path)
    (r,) = parsed.roads
    kinds = [type(g.shape).__name__ for g in r.geometries]
    assert kinds == ["Line", "Spiral", "Arc", "Spiral", "ParamPoly3", "Line"]
    assert r.geometries[1].shape == Spiral(0.0, 0.004) and r.geometries[2].shape == Arc(0.004)
    assert r.geometries[4].shape.v == (0.0, 0.0, 0.002, -1e-5)
    widths = {ln.id: ln.widths[0].a for ln in r.sections[0].lanes if ln.id}
    assert widths == {1: 3.5, -1: 3.5, -2: 3.5}
    broken = r.sections[0].lane(-1).road_marks[0]
    assert broken.type == "broken" and (broken.lines[0].length, broken.lines[0].space) == (3.0, 9.0)
    # Each written geometry start (computed by scenariogeneration) is where our
    # evaluation of the previous geometry ends.
    plan = PlanView(r.geometries)
    for g in r.geometries[1:]:
        x, y, h = plan.position(np.array([g.s - 1e-12]))
        assert (x[0], y[0]) == pytest.approx((g.x, g.y), abs=1e-6)
        assert math.remainder(h[0] - g.hdg, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    odr = OpenDriveMap.from_file(path)
    m = marking_at(odr, 1.0, -3.5)
    assert m.type == MarkingType.DASHED and len(odr.markings) == 4
    # 3 m / 9 m stepped in the road's s (the line is off-centre in curves).
    np.testing.assert_allclose(np.diff(np.interp(m.painted[:, 0], m.u, m.s)), 12.0, atol=1e-6)


# ---------------------------------------------------------------- shipped maps

MAPS = Path(aldm_gym.__file__).parent / "roads" / "maps"


def _dash_lengths_in_s(m: MarkingLine) -> np.ndarray:
    """Reference-s length of each painted interval that lies within one road."""
    jump = np.flatnonzero(np.abs(np.diff(m.s)) > 1.0)  # the line passes onto another road
    lo, hi = m.u[jump], m.u[jump + 1]
    within = ~((m.painted[:, :1] < hi) & (m.painted[:, 1:] > lo)).any(axis=1)
    s_ends = np.interp(m.painted[within], m.u, m.s)
    return np.abs(s_ends[:, 1] - s_ends[:, 0])


@pytest.mark.parametrize(
    ("name", "dashes"),
    [("motorway.xodr", (6.0,)), ("two_plus_one.xodr", (4.0,)), ("features.xodr", (4.0, 6.0))],
)
def test_shipped_map_loads(name: str, dashes: tuple[float, ...]) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        odr = OpenDriveMap.from_file(MAPS / name)
    assert odr.markings and odr.lanes
    for m in odr.markings:
        assert m.xy.shape == (len(m.u), 2) and (np.diff(m.u) > 0).all()
        assert (m.painted[:, 0] >= -1e-9).all() and (m.painted[:, 1] <= m.u[-1] + 1e-9).all()
        if m.type == MarkingType.DASHED:
            # Explicit 6 m dashes or the default 4 m ones in the road's s; the last one
            # of a record is cut at its end, and one cut there and the next record's
            # first, touching it, are one painted interval.
            ds = _dash_lengths_in_s(m)
            whole = np.isclose(ds[:, None], dashes, atol=1e-6).any(axis=1)
            assert whole.mean() > 0.9 and (ds <= 2 * max(dashes) + 1e-6).all()
    for key, lane in odr.lanes.items():
        mid = 0.5 * (lane.s0 + lane.s1)
        x, y, _ = odr.lane_pose(key[0], key[2], mid)
        assert np.hypot(*(lane.xy - (x, y)).T).min() < 0.3


def test_shipped_motorway_topology() -> None:
    odr = OpenDriveMap.from_file(MAPS / "motorway.xodr")
    assert sum(odr.lengths[r] for r in "123456") >= 5000.0
    opening = odr.lanes[("3", 1, -4)]
    assert opening.type == "entry" and opening.width[0] == pytest.approx(0.0)
    assert opening.width[-1] == pytest.approx(3.75)
    # Where the ramp lane opens (width 0), the edge line continues along lane -3's border.
    assert odr.lanes[("3", 0, -3)].right[-1] == odr.lanes[("3", 1, -3)].right[0]
    assert odr.successors("5", -4, 2) == [("7", 0, -1)]
    assert odr.successors("5", -1, 2) == [("6", 0, -1)]
    # Lane lines and the left edge run the whole carriageway as single marking lines.
    long_lines = [m for m in odr.markings if m.road_ids == ("1", "2", "3", "4", "5", "6")]
    assert len(long_lines) == 3
