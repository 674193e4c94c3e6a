"""OpenDRIVE reader: parsing, reference-line geometry, lanes, road marks, the map."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from aldm_gym.roads.opendrive.geometry import PlanView
from aldm_gym.roads.opendrive.parse import (
    Arc,
    Geometry,
    Line,
    ParamPoly3,
    Poly3,
    Spiral,
    parse_file,
)

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
        '<elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/></elevationProfile>'
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
    assert dict(parsed.skipped)["road/elevationProfile"] == 2


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
