"""OpenDRIVE reader: parsing, reference-line geometry, lanes, road marks, the map."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from aldm_gym.roads.markings import MarkingType
from aldm_gym.roads.opendrive import MarkingLine, OpenDriveMap
from aldm_gym.roads.opendrive.parse import (
    Arc,
    Geometry,
    Line,
    ParamPoly3,
    Poly3,
    Spiral,
    parse_file,
)
from aldm_gym.roads.opendrive.plan_view import PlanView

# ---------------------------------------------------------------- tiny file writer

_SOLID = '<roadMark sOffset="0" type="solid" color="standard" width="0.15"/>'


def _lane(
    lane_id: int,
    width: str = '<width sOffset="0" a="3.5" b="0" c="0" d="0"/>',
    marks: str = _SOLID,
    extra: str = "",
) -> str:
    return f'<lane id="{lane_id}" type="driving" level="false">{extra}{width}{marks}</lane>'


def _section(s: float = 0.0, left: str = "", right: str = "", centre_mark: str = _SOLID) -> str:
    parts = [f'<laneSection s="{s}">']
    if left:
        parts.append(f"<left>{left}</left>")
    parts.append(f'<center><lane id="0" type="none" level="false">{centre_mark}</lane></center>')
    if right:
        parts.append(f"<right>{right}</right>")
    parts.append("</laneSection>")
    return "".join(parts)


def _road(
    road_id: str,
    geometry: str,
    length: float,
    sections: str,
    link: str = "",
    offsets: str = "",
    rule: str = "RHT",
    junction: str = "-1",
    extra: str = "",
) -> str:
    return (
        f'<road id="{road_id}" length="{length}" junction="{junction}" rule="{rule}">'
        f"<link>{link}</link><planView>{geometry}</planView>{extra}"
        f"<lanes>{offsets}{sections}</lanes></road>"
    )


def _geometry(
    kind: str, length: float, s: float = 0.0, x: float = 0.0, y: float = 0.0, hdg: float = 0.0
) -> str:
    return f'<geometry s="{s}" x="{x}" y="{y}" hdg="{hdg}" length="{length}">{kind}</geometry>'


def _write(path: Path, *roads: str, junctions: str = "") -> Path:
    path.write_text(
        '<?xml version="1.0"?>\n<OpenDRIVE>\n<header revMajor="1" revMinor="6" name="t"/>\n'
        + "\n".join(roads)
        + junctions
        + "\n</OpenDRIVE>\n"
    )
    return path


def _plan(*geometries: Geometry) -> PlanView:
    return PlanView(geometries, "test")


# ---------------------------------------------------------------- geometry


def test_line_and_arc_closed_form() -> None:
    radius, hdg = 500.0, 0.3
    plan = _plan(
        Geometry(0.0, 10.0, -5.0, hdg, 100.0, Line()),
        Geometry(
            100.0,
            10.0 + 100.0 * math.cos(hdg),
            -5.0 + 100.0 * math.sin(hdg),
            hdg,
            400.0,
            Arc(1.0 / radius),
        ),
    )
    s = np.linspace(0.0, 100.0, 11)
    x, y, h = plan.position(s)
    np.testing.assert_allclose(x, 10.0 + s * math.cos(hdg), atol=1e-9)
    np.testing.assert_allclose(y, -5.0 + s * math.sin(hdg), atol=1e-9)
    g = plan.geometries[1]
    centre = (g.x - radius * math.sin(hdg), g.y + radius * math.cos(hdg))
    s = np.linspace(100.0, 500.0, 801)
    x, y, h = plan.position(s)
    np.testing.assert_allclose(np.hypot(x - centre[0], y - centre[1]), radius, atol=1e-9)
    np.testing.assert_allclose(h, hdg + (s - 100.0) / radius, atol=1e-12)
    np.testing.assert_allclose(plan.curvature(s), 1.0 / radius)


@pytest.mark.parametrize(
    ("k0", "k1"), [(0.0, 1 / 500), (1 / 800, -1 / 600), (-0.002, -0.002 + 1e-15)]
)
def test_spiral_curvature_linear_and_position(k0: float, k1: float) -> None:
    length, hdg = 150.0, -0.7
    plan = _plan(Geometry(0.0, 3.0, 4.0, hdg, length, Spiral(k0, k1)))
    s = np.linspace(0.0, length, 3001)
    h = plan.position(s)[2]
    # Heading finite differences: curvature linear in s from k0 to k1.
    mid = 0.5 * (s[1:] + s[:-1])
    np.testing.assert_allclose(np.diff(h) / np.diff(s), k0 + (k1 - k0) * mid / length, atol=1e-9)

    # Position against numerical integration of the heading.
    def head(t: float) -> float:
        return hdg + k0 * t + 0.5 * (k1 - k0) / length * t * t

    for t in (37.0, length):
        ex = 3.0 + quad(lambda v: math.cos(head(v)), 0.0, t, epsabs=1e-12)[0]
        ey = 4.0 + quad(lambda v: math.sin(head(v)), 0.0, t, epsabs=1e-12)[0]
        px, py, _ = plan.position(np.array([t]))
        assert abs(px[0] - ex) < 1e-8 and abs(py[0] - ey) < 1e-8


def test_poly3_on_its_polynomial_with_arc_length_spacing() -> None:
    shape = Poly3(0.0, 0.05, 2e-3, -4e-6)
    x0, y0, hdg, length = 5.0, 1.0, 0.4, 200.0
    plan = _plan(Geometry(0.0, x0, y0, hdg, length, shape))
    s = np.linspace(0.0, length, 2001)
    x, y, _ = plan.position(s)
    c, sn = math.cos(hdg), math.sin(hdg)
    u = c * (x - x0) + sn * (y - y0)
    v = -sn * (x - x0) + c * (y - y0)
    np.testing.assert_allclose(v, shape.a + u * (shape.b + u * (shape.c + u * shape.d)), atol=1e-9)
    # s is arc length: chord lengths match ds (chords of 0.1 m are the arc within 1e-7).
    np.testing.assert_allclose(np.hypot(np.diff(x), np.diff(y)), np.diff(s), atol=1e-5)
    # Arc length from the start, by quadrature, at the last point.
    u_end = u[-1]
    arc = quad(
        lambda q: math.hypot(1.0, shape.b + 2 * shape.c * q + 3 * shape.d * q * q), 0.0, u_end
    )[0]
    assert abs(arc - length) < 1e-3


def test_param_poly3_normalized_equals_arc_length() -> None:
    # A curve with p in [0, length] (arcLength), and the same curve rescaled to p in [0, 1].
    bu, cu, du = 1.0, -2e-4, 1e-7
    bv, cv, dv = 0.0, 3e-3, -1e-5
    length = 120.0
    arc = ParamPoly3((0.0, bu, cu, du), (0.0, bv, cv, dv), "arcLength")
    L = length
    norm = ParamPoly3(
        (0.0, bu * L, cu * L**2, du * L**3), (0.0, bv * L, cv * L**2, dv * L**3), "normalized"
    )
    a = _plan(Geometry(0.0, 1.0, 2.0, 0.2, length, arc))
    b = _plan(Geometry(0.0, 1.0, 2.0, 0.2, length, norm))
    s = np.linspace(0.0, length, 777)
    for va, vb in zip(a.position(s), b.position(s), strict=True):
        np.testing.assert_allclose(va, vb, atol=1e-6)
    # The geometry ends at the curve's end, p = length.
    x, y, _ = a.position(np.array([length]))
    u_end = bu * L + cu * L**2 + du * L**3
    v_end = bv * L + cv * L**2 + dv * L**3
    c, sn = math.cos(0.2), math.sin(0.2)
    assert abs(x[0] - (1.0 + c * u_end - sn * v_end)) < 1e-9
    assert abs(y[0] - (2.0 + sn * u_end + c * v_end)) < 1e-9
    # s runs proportionally to the curve's arc length: equal chords for equal ds.
    x, y, _ = a.position(s)
    chords = np.hypot(np.diff(x), np.diff(y))
    np.testing.assert_allclose(chords, chords.mean(), rtol=1e-4)


def test_plan_view_continuous_and_bounded() -> None:
    plan = _plan(
        Geometry(0.0, 0.0, 0.0, 0.0, 50.0, Line()),
        Geometry(50.0, 50.0, 0.0, 0.0, 30.0, Spiral(0.0, 0.01)),
    )
    x, y, _ = plan.position(np.array([50.0 - 1e-9, 50.0]))
    assert abs(x[0] - x[1]) < 1e-6 and abs(y[0] - y[1]) < 1e-6
    with pytest.raises(ValueError, match="outside the plan view"):
        plan.position(np.array([80.5]))


# ---------------------------------------------------------------- parsing and errors


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nothere.xodr"
    with pytest.raises(FileNotFoundError, match=r"nothere\.xodr"):
        parse_file(path)


def test_shipped_maps_by_name_from_anywhere(tmp_path: Path) -> None:
    """``shipped_map`` names every ``.xodr`` of the package's maps folder (the tuple
    stays in step with the files), and a missing path whose file name is a shipped
    map's says where that map is."""
    from aldm_gym.roads import SHIPPED_MAPS, OpenDriveRoad, shipped_map
    from aldm_gym.roads.opendrive.parse import MAPS_DIR

    assert sorted(SHIPPED_MAPS) == sorted(p.stem for p in MAPS_DIR.glob("*.xodr"))
    for name in SHIPPED_MAPS:
        assert shipped_map(name) == shipped_map(name + ".xodr")
        assert shipped_map(name).is_absolute() and shipped_map(name).is_file()
    with pytest.raises(ValueError, match=r"no shipped map 'motorways'.*'motorway'"):
        shipped_map("motorways")
    elsewhere = tmp_path / "aldm_gym" / "roads" / "maps" / "motorway.xodr"
    for load in (parse_file, OpenDriveRoad.from_file):
        with pytest.raises(FileNotFoundError) as err:
            load(elsewhere)
        assert str(elsewhere) in str(err.value)
        assert str(shipped_map("motorway")) in str(err.value)
        assert "relative to" not in str(err.value)  # an absolute path
    with pytest.raises(FileNotFoundError, match="relative to"):
        parse_file("no/such/folder/motorway.xodr")
    with pytest.raises(FileNotFoundError) as err:
        parse_file(tmp_path / "nothere.xodr")
    assert "the shipped map" not in str(err.value)


def test_malformed_xml_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "broken.xodr"
    path.write_text('<?xml version="1.0"?>\n<OpenDRIVE>\n<header/>\n<road id="1">\n</OpenDRIVE>\n')
    with pytest.raises(ValueError, match=r"broken\.xodr: malformed XML at line \d"):
        parse_file(path)


def test_geometry_without_type_names_road(tmp_path: Path) -> None:
    road = _road("7", _geometry("", 100.0), 100.0, _section(right=_lane(-1)))
    path = _write(tmp_path / "notype.xodr", road)
    with pytest.raises(ValueError, match=r"notype\.xodr, road '7', <geometry> at line \d+"):
        parse_file(path)


@pytest.mark.parametrize(
    ("geometry", "message"),
    [
        ('<arc curvature="abc"/>', r"road '3', <arc> .*curvature='abc' is not a number"),
        ('<arc curvature="nan"/>', r"road '3', <arc> .*not finite"),
        ("<clothoid/>", r"road '3', <clothoid> .*unknown geometry type"),
        ("<arc/>", r"road '3', <arc> .*missing attribute 'curvature'"),
    ],
)
def test_bad_geometry_records(tmp_path: Path, geometry: str, message: str) -> None:
    road = _road("3", _geometry(geometry, 100.0), 100.0, _section(right=_lane(-1)))
    with pytest.raises(ValueError, match=message):
        parse_file(_write(tmp_path / "bad.xodr", road))


def test_negative_length_and_bad_width(tmp_path: Path) -> None:
    road = _road("4", _geometry("<line/>", -1.0), 100.0, _section(right=_lane(-1)))
    with pytest.raises(ValueError, match=r"road '4', <geometry> .*length=-1.0 is negative"):
        parse_file(_write(tmp_path / "neg.xodr", road))
    bad = _lane(-1, width='<width sOffset="0" a="3.x" b="0" c="0" d="0"/>')
    road = _road("5", _geometry("<line/>", 100.0), 100.0, _section(right=bad))
    with pytest.raises(ValueError, match=r"road '5', <width> .*a='3.x' is not a number"):
        parse_file(_write(tmp_path / "width.xodr", road))


def test_skipped_elements_one_warning(tmp_path: Path) -> None:
    extra = (
        '<elevationProfile><elevation s="0" a="2" b="0" c="0" d="0"/></elevationProfile>'
        '<lateralProfile><superelevation s="0" a="0" b="0" c="0" d="0"/></lateralProfile>'
        '<objects><object id="1" s="3" t="0"/></objects>'
        '<signals><signal id="1" s="3" t="0"/><signal id="2" s="4" t="0"/></signals>'
    )
    roads = [
        _road(str(i), _geometry("<line/>", 50.0), 50.0, _section(right=_lane(-1)), extra=extra)
        for i in (1, 2)
    ]
    path = _write(tmp_path / "extras.xodr", *roads)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        parsed = parse_file(path)
    assert len(caught) == 1
    text = str(caught[0].message)
    assert "extras.xodr" in text and "road/signals x2" in text and "road/objects x2" in text
    assert dict(parsed.skipped)["road/lateralProfile"] == 2
    # The elevation is read (it tells bridges from flat crossings), not skipped.
    assert "road/elevationProfile" not in dict(parsed.skipped)
    assert [r.elevation[0].a for r in parsed.roads] == [2.0, 2.0]


def test_parse_records(tmp_path: Path) -> None:
    mark = (
        '<roadMark sOffset="1.5" type="broken" weight="bold" color="yellow" width="0.2" '
        'height="0.01" laneChange="both"><type name="dash" width="0.2">'
        '<line length="3" space="9" tOffset="0.1" sOffset="2" rule="caution" width="0.12"/>'
        "</type></roadMark>"
    )
    widths = (
        '<width sOffset="0" a="3" b="0.1" c="0" d="0"/>'
        '<width sOffset="20" a="5" b="0" c="0" d="0"/>'
    )
    left = _lane(1, width=widths)
    right = _lane(-1, marks=mark, extra='<link><predecessor id="-2"/><successor id="-1"/></link>')
    link = (
        '<predecessor elementType="junction" elementId="9"/>'
        '<successor elementType="road" elementId="2" contactPoint="end"/>'
    )
    offsets = '<laneOffset s="0" a="0.25" b="0" c="0" d="0"/>'
    road = _road(
        "1",
        _geometry('<spiral curvStart="0" curvEnd="0.01"/>', 40.0),
        40.0,
        _section(left=left, right=right),
        link,
        offsets,
        rule="LHT",
    )
    junction = (
        '<junction id="9" name="j">'
        '<connection id="0" incomingRoad="1" connectingRoad="5" contactPoint="start">'
        '<laneLink from="-1" to="-2"/></connection></junction>'
    )
    parsed = parse_file(_write(tmp_path / "rec.xodr", road, junctions=junction))
    r = parsed.roads[0]
    assert (r.id, r.rule, r.length) == ("1", "LHT", 40.0)
    assert r.predecessor.element_type == "junction" and r.predecessor.element_id == "9"
    assert (r.successor.element_id, r.successor.contact_point) == ("2", "end")
    assert r.geometries[0].shape == Spiral(0.0, 0.01)
    assert r.lane_offsets[0].a == 0.25
    sec = r.sections[0]
    assert [ln.id for ln in sec.lanes] == [1, 0, -1]
    assert [w.s for w in sec.lane(1).widths] == [0.0, 20.0]
    lane = sec.lane(-1)
    assert (lane.predecessors, lane.successors) == ((-2,), (-1,))
    rm = lane.road_marks[0]
    assert (rm.s_offset, rm.type, rm.weight, rm.color, rm.width, rm.height, rm.lane_change) == (
        1.5,
        "broken",
        "bold",
        "yellow",
        0.2,
        0.01,
        "both",
    )
    ln = rm.lines[0]
    assert (ln.length, ln.space, ln.t_offset, ln.s_offset, ln.rule, ln.width) == (
        3.0,
        9.0,
        0.1,
        2.0,
        "caution",
        0.12,
    )
    c = parsed.junctions[0].connections[0]
    assert (c.incoming_road, c.connecting_road, c.contact_point) == ("1", "5", "start")
    assert (c.lane_links[0].from_id, c.lane_links[0].to_id) == (-1, -2)


# ---------------------------------------------------------------- lanes and road marks


def _broken(
    s_offset: float = 0.0, length: float = 6.0, space: float = 12.0, line_s: float = 0.0
) -> str:
    return (
        f'<roadMark sOffset="{s_offset}" type="broken" color="standard" width="0.15">'
        f'<type name="b" width="0.15"><line length="{length}" space="{space}" tOffset="0" '
        f'sOffset="{line_s}" width="0.15"/></type></roadMark>'
    )


def _marking_at(odr: OpenDriveMap, x: float, y: float) -> MarkingLine:
    """The marking line passing closest to a world point."""
    dist = [np.hypot(m.xy[:, 0] - x, m.xy[:, 1] - y).min() for m in odr.markings]
    return odr.markings[int(np.argmin(dist))]


def test_lane_offset_and_width_polynomials_give_borders(tmp_path: Path) -> None:
    offsets = (
        '<laneOffset s="0" a="0.5" b="0.01" c="0" d="0"/>'
        '<laneOffset s="60" a="1.1" b="0" c="0" d="0"/>'
    )
    widths = (
        '<width sOffset="0" a="3.0" b="0.002" c="1e-5" d="0"/>'
        '<width sOffset="50" a="3.125" b="0.01" c="0" d="0"/>'
    )
    right = _lane(-1, width=widths) + _lane(-2)
    left = _lane(1, width='<width sOffset="0" a="3.25" b="0" c="0" d="0"/>')
    road = _road(
        "1", _geometry("<line/>", 100.0), 100.0, _section(left=left, right=right), offsets=offsets
    )
    odr = OpenDriveMap.from_file(_write(tmp_path / "widths.xodr", road), sample_step=1.0)
    s = np.linspace(0.0, 100.0, 101)
    offset = np.where(s < 60.0, 0.5 + 0.01 * s, 1.1)
    w1 = np.where(s < 50.0, 3.0 + 0.002 * s + 1e-5 * s**2, 3.125 + 0.01 * (s - 50.0))
    expected = {0: offset, 1: offset + 3.25, -1: offset - w1, -2: offset - w1 - 3.5}
    for t in expected.values():
        m = _marking_at(odr, 30.0, float(np.interp(30.0, s, t)))
        np.testing.assert_allclose(np.interp(s, m.xy[:, 0], m.xy[:, 1]), t, atol=1e-9)
    lane = odr.lanes[("1", 0, -1)]
    np.testing.assert_allclose(lane.width, np.interp(lane.s, s, w1), atol=1e-9)


def test_explicit_pattern_dashes_start_at_s_offset(tmp_path: Path) -> None:
    right = _lane(-1, marks=_broken(s_offset=4.0, length=3.0, space=9.0, line_s=2.0)) + _lane(-2)
    road = _road("1", _geometry("<line/>", 200.0), 200.0, _section(right=right))
    odr = OpenDriveMap.from_file(_write(tmp_path / "pattern.xodr", road))
    m = _marking_at(odr, 100.0, -3.5)
    assert m.type == MarkingType.DASHED and m.xy[0, 0] == pytest.approx(4.0)
    # u starts at the record's start (s = 4): first dash at u = 2 (s = 6), 3 m, 9 m gaps.
    starts = 2.0 + 12.0 * np.arange(len(m.painted))
    np.testing.assert_allclose(m.painted[:, 0], starts, atol=1e-9)
    np.testing.assert_allclose(np.diff(m.painted, axis=1)[:-1, 0], 3.0, atol=1e-9)
    assert m.painted[-1, 1] <= m.u[-1] + 1e-9


def test_default_broken_pattern_and_option(tmp_path: Path) -> None:
    plain = '<roadMark sOffset="0" type="broken" color="standard" width="0.15"/>'
    right = _lane(-1, marks=plain) + _lane(-2)
    path = _write(
        tmp_path / "default.xodr",
        _road("1", _geometry("<line/>", 100.0), 100.0, _section(right=right)),
    )
    m = _marking_at(OpenDriveMap.from_file(path), 50.0, -3.5)
    np.testing.assert_allclose(m.painted[:3], [[0, 6], [18, 24], [36, 42]], atol=1e-9)
    m = _marking_at(OpenDriveMap.from_file(path, broken_pattern=(3.0, 6.0)), 50.0, -3.5)
    np.testing.assert_allclose(m.painted[:3], [[0, 3], [9, 12], [18, 21]], atol=1e-9)
    with pytest.raises(ValueError, match="broken_pattern"):
        OpenDriveMap.from_file(path, broken_pattern=(6.0, -1.0))


def test_dashes_measured_along_the_painted_line_in_a_curve(tmp_path: Path) -> None:
    right = _lane(-1, marks=_broken()) + _lane(-2, marks=_broken())
    road = _road("1", _geometry('<arc curvature="0.01"/>', 300.0), 300.0, _section(right=right))
    odr = OpenDriveMap.from_file(_write(tmp_path / "curve.xodr", road))
    for t in (-3.5, -7.0):  # outside of the left-hand curve
        m = _marking_at(odr, 0.0, t)
        assert m.u[-1] == pytest.approx(300.0 * (1.0 - 0.01 * t), abs=1e-3)
        np.testing.assert_allclose(np.diff(m.painted, axis=1)[:-1, 0], 6.0, atol=1e-9)
        np.testing.assert_allclose(np.diff(m.painted[:, 0]), 18.0, atol=1e-9)


def test_marking_continues_across_lane_sections_without_jump(tmp_path: Path) -> None:
    # The second section restarts the pattern at its start (s = 110, mid-dash of the
    # first pattern); the painted line continues the first section's phase.
    right = _lane(-1, marks=_broken()) + _lane(-2)
    sections = _section(0.0, right=right) + _section(110.0, right=right)
    road = _road("1", _geometry('<arc curvature="0.002"/>', 250.0), 250.0, sections)
    odr = OpenDriveMap.from_file(_write(tmp_path / "sections.xodr", road))
    m = _marking_at(odr, 0.0, -3.5)
    assert m.u[-1] == pytest.approx(250.0 * (1 + 0.002 * 3.5), abs=1e-3)
    steps = np.hypot(*np.diff(m.xy, axis=0).T)
    assert steps.max() < 0.51 and steps.min() > 1e-6
    np.testing.assert_allclose(np.diff(m.u), steps, atol=1e-9)
    np.testing.assert_allclose(np.diff(m.painted[:, 0]), 18.0, atol=1e-9)
    np.testing.assert_allclose(np.diff(m.painted, axis=1)[:-1, 0], 6.0, atol=1e-9)
    # Centre, lane -1 (dashed) and lane -2: each one object over both sections.
    assert len(odr.markings) == 3


def test_mark_type_change_starts_a_new_marking(tmp_path: Path) -> None:
    marks = _broken() + '<roadMark sOffset="60" type="solid" color="standard" width="0.15"/>'
    right = _lane(-1, marks=marks) + _lane(-2)
    road = _road("1", _geometry("<line/>", 100.0), 100.0, _section(right=right))
    odr = OpenDriveMap.from_file(_write(tmp_path / "change.xodr", road))
    near = sorted(
        (m for m in odr.markings if abs(m.xy[0, 1] + 3.5) < 1e-6), key=lambda m: m.xy[0, 0]
    )
    assert [m.type for m in near] == [MarkingType.DASHED, MarkingType.CONTINUOUS]
    assert near[0].xy[-1, 0] == pytest.approx(60.0) and near[1].xy[0, 0] == pytest.approx(60.0)
    np.testing.assert_allclose(near[1].painted, [[0.0, 40.0]], atol=1e-9)


def test_double_marks_and_no_paint(tmp_path: Path) -> None:
    double = '<roadMark sOffset="0" type="solid broken" color="yellow" width="0.1"/>'
    centre = '<roadMark sOffset="0" type="broken solid" color="yellow" width="0.1"/>'
    none = '<roadMark sOffset="0" type="none"/>'
    right = _lane(-1, marks=double) + _lane(-2, marks=none)
    left = _lane(1, marks='<roadMark sOffset="0" type="curb"/>')
    road = _road(
        "1", _geometry("<line/>", 50.0), 50.0, _section(left=left, right=right, centre_mark=centre)
    )
    odr = OpenDriveMap.from_file(_write(tmp_path / "double.xodr", road))
    half = 0.5 * (0.1 + 0.12)
    lines = {round(float(m.xy[0, 1]), 6): m for m in odr.markings}
    # Lane -1's border at t = -3.5: solid inside (towards the centre), broken outside.
    assert lines[round(-3.5 + half, 6)].type == MarkingType.CONTINUOUS
    assert lines[round(-3.5 - half, 6)].type == MarkingType.DASHED
    # The centre lane's double mark from left to right.
    assert lines[round(half, 6)].type == MarkingType.DASHED
    assert lines[round(-half, 6)].type == MarkingType.CONTINUOUS
    assert lines[round(half, 6)].colour == 1
    curb = lines[3.5]
    assert curb.type == MarkingType.CONTINUOUS and curb.height > 0.0
    assert len(odr.markings) == 5  # none at t = -7
    lane = odr.lanes[("1", 0, -2)]
    outer = next(i for i, m in enumerate(odr.markings) if m is lines[round(-3.5 - half, 6)])
    assert (lane.right == -1).all() and (lane.left == outer).all()


# ---------------------------------------------------------------- the map


def _link(kind: str, element: str, contact: str = "") -> str:
    cp = f' contactPoint="{contact}"' if contact else ""
    return f'<{kind} elementType="road" elementId="{element}"{cp}/>'


def test_markings_chain_across_linked_roads_forward_and_reversed(tmp_path: Path) -> None:
    lanes1 = _lane(-1, marks=_broken(), extra='<link><successor id="1"/></link>')
    lanes2 = _lane(
        1, marks=_broken(), extra='<link><predecessor id="-1"/><successor id="-1"/></link>'
    )
    lanes3 = _lane(-1, marks=_broken(), extra='<link><predecessor id="1"/></link>')
    # Road 2 runs backwards (end meets end with road 1); road 3 continues road 2's start.
    r1 = _road(
        "1",
        _geometry("<line/>", 100.0),
        100.0,
        _section(right=lanes1),
        _link("successor", "2", "end"),
    )
    r2 = _road(
        "2",
        _geometry("<line/>", 100.0, x=200.0, hdg=math.pi),
        100.0,
        _section(left=lanes2),
        _link("successor", "1", "end") + _link("predecessor", "3", "start"),
    )
    r3 = _road(
        "3",
        _geometry("<line/>", 55.0, x=200.0),
        55.0,
        _section(right=lanes3),
        _link("predecessor", "2", "start"),
    )
    odr = OpenDriveMap.from_file(_write(tmp_path / "linked.xodr", r1, r2, r3))
    m = _marking_at(odr, 10.0, -3.5)
    assert m.road_ids == ("1", "2", "3")
    assert m.u[-1] == pytest.approx(255.0)
    np.testing.assert_allclose(m.xy[[0, -1]], [[0.0, -3.5], [255.0, -3.5]], atol=1e-9)
    np.testing.assert_allclose(np.diff(m.painted[:, 0]), 18.0, atol=1e-9)  # phase carried
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
    r1 = _road(
        "1",
        _geometry("<line/>", 100.0),
        100.0,
        _section(right=_lane(-1) + _lane(-2)),
        '<successor elementType="junction" elementId="9"/>',
    )
    conn = [
        _road(
            "5",
            _geometry("<line/>", 20.0, x=100.0),
            20.0,
            _section(right=_lane(-1)),
            _link("predecessor", "1", "end"),
            junction="9",
        ),
        _road(
            "6",
            _geometry('<arc curvature="-0.01"/>', 20.0, x=100.0, y=-3.5),
            20.0,
            _section(right=_lane(-1)),
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
    odr = OpenDriveMap.from_file(_write(tmp_path / "junction.xodr", r1, *conn, junctions=junction))
    assert odr.successors("1", -1, 0) == [("5", 0, -1)]
    assert odr.successors("1", -2, 0) == [("6", 0, -1)]
    with pytest.raises(ValueError, match="no lane 1 in section 0 of road '1'"):
        odr.successors("1", 1, 0)


def test_lane_pose_straight_arc_and_left_hand_traffic(tmp_path: Path) -> None:
    widen = _lane(-1, width='<width sOffset="0" a="3" b="0.02" c="0" d="0"/>')
    straight = _road(
        "s", _geometry("<line/>", 100.0, x=5.0, y=7.0), 100.0, _section(left=_lane(1), right=widen)
    )
    radius = 100.0
    arc = _road(
        "a",
        _geometry(f'<arc curvature="{1 / radius}"/>', 150.0, y=-50.0),
        150.0,
        _section(left=_lane(1), right=_lane(-1)),
    )
    lht = _road(
        "l",
        _geometry("<line/>", 100.0, y=50.0),
        100.0,
        _section(left=_lane(1), right=_lane(-1)),
        rule="LHT",
    )
    odr = OpenDriveMap.from_file(_write(tmp_path / "pose.xodr", straight, arc, lht))
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
    m = _marking_at(odr, 1.0, -3.5)
    assert m.type == MarkingType.DASHED and len(odr.markings) == 4
    np.testing.assert_allclose(np.diff(m.painted[:, 0]), 12.0, atol=1e-9)


# ---------------------------------------------------------------- shipped maps

MAPS = Path(__file__).resolve().parents[1] / "aldm_gym" / "roads" / "maps"


@pytest.mark.parametrize("name", ["motorway.xodr", "two_plus_one.xodr", "features.xodr"])
def test_shipped_map_loads(name: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        odr = OpenDriveMap.from_file(MAPS / name)
    assert odr.markings and odr.lanes
    for m in odr.markings:
        assert m.xy.shape == (len(m.u), 2) and (np.diff(m.u) > 0).all()
        assert (m.painted[:, 0] >= -1e-9).all() and (m.painted[:, 1] <= m.u[-1] + 1e-9).all()
        if m.type == MarkingType.DASHED:
            # 6 m / 12 m along the painted line, explicit or by default.
            np.testing.assert_allclose(np.diff(m.painted[:, 0]), 18.0, atol=1e-6)
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
