"""Lanes and road marks of OpenDRIVE maps (aldm_gym.roads.opendrive.lanes, marks):
borders, dash patterns stepped in reference s as esmini steps them, marks across
records and sections."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from aldm_gym.roads import HighwayRoad
from aldm_gym.roads.markings import MarkingType
from aldm_gym.roads.opendrive import DEFAULT_BROKEN_PATTERN, OpenDriveMap
from aldm_gym.roads.opendrive.marks import record_dashes
from aldm_gym.roads.paint import painted_pieces

from ._xodr import (
    broken_mark,
    geometry_xml,
    lane_xml,
    marking_at,
    road_xml,
    section_xml,
    write_xodr,
)

DATA = Path(__file__).parent / "data"
"""Public OpenDRIVE maps (see the README there)."""

# ---------------------------------------------------------------- lanes and road marks


def test_lane_offset_and_width_polynomials_give_borders(tmp_path: Path) -> None:
    offsets = (
        '<laneOffset s="0" a="0.5" b="0.01" c="0" d="0"/>'
        '<laneOffset s="60" a="1.1" b="0" c="0" d="0"/>'
    )
    widths = (
        '<width sOffset="0" a="3.0" b="0.002" c="1e-5" d="0"/>'
        '<width sOffset="50" a="3.125" b="0.01" c="0" d="0"/>'
    )
    right = lane_xml(-1, width=widths) + lane_xml(-2)
    left = lane_xml(1, width='<width sOffset="0" a="3.25" b="0" c="0" d="0"/>')
    road = road_xml(
        "1",
        geometry_xml("<line/>", 100.0),
        100.0,
        section_xml(left=left, right=right),
        offsets=offsets,
    )
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "widths.xodr", road), sample_step=1.0)
    s = np.linspace(0.0, 100.0, 101)
    offset = np.where(s < 60.0, 0.5 + 0.01 * s, 1.1)
    w1 = np.where(s < 50.0, 3.0 + 0.002 * s + 1e-5 * s**2, 3.125 + 0.01 * (s - 50.0))
    expected = {0: offset, 1: offset + 3.25, -1: offset - w1, -2: offset - w1 - 3.5}
    for t in expected.values():
        m = marking_at(odr, 30.0, float(np.interp(30.0, s, t)))
        np.testing.assert_allclose(np.interp(s, m.xy[:, 0], m.xy[:, 1]), t, atol=1e-9)
    lane = odr.lanes[("1", 0, -1)]
    np.testing.assert_allclose(lane.width, np.interp(lane.s, s, w1), atol=1e-9)


def test_explicit_pattern_dashes_start_at_s_offset(tmp_path: Path) -> None:
    right = lane_xml(
        -1, marks=broken_mark(s_offset=4.0, length=3.0, space=9.0, line_s=2.0)
    ) + lane_xml(-2)
    road = road_xml("1", geometry_xml("<line/>", 200.0), 200.0, section_xml(right=right))
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "pattern.xodr", road))
    m = marking_at(odr, 100.0, -3.5)
    assert m.type == MarkingType.DASHED and m.xy[0, 0] == pytest.approx(4.0)
    # u starts at the record's start (s = 4): first dash at u = 2 (s = 6), 3 m, 9 m gaps.
    starts = 2.0 + 12.0 * np.arange(len(m.painted))
    np.testing.assert_allclose(m.painted[:, 0], starts, atol=1e-9)
    np.testing.assert_allclose(np.diff(m.painted, axis=1)[:-1, 0], 3.0, atol=1e-9)
    assert m.painted[-1, 1] <= m.u[-1] + 1e-9


def test_default_broken_pattern_and_option(tmp_path: Path) -> None:
    plain = '<roadMark sOffset="0" type="broken" color="standard" width="0.15"/>'
    right = lane_xml(-1, marks=plain) + lane_xml(-2)
    path = write_xodr(
        tmp_path / "default.xodr",
        road_xml("1", geometry_xml("<line/>", 100.0), 100.0, section_xml(right=right)),
    )
    # esmini's stand-in pattern: 4 m dashes, 8 m gaps, from the record's start.
    assert DEFAULT_BROKEN_PATTERN == (4.0, 8.0)
    m = marking_at(OpenDriveMap.from_file(path), 50.0, -3.5)
    np.testing.assert_allclose(m.painted[:3], [[0, 4], [12, 16], [24, 28]], atol=1e-9)
    m = marking_at(OpenDriveMap.from_file(path, broken_pattern=(3.0, 6.0)), 50.0, -3.5)
    np.testing.assert_allclose(m.painted[:3], [[0, 3], [9, 12], [18, 21]], atol=1e-9)
    with pytest.raises(ValueError, match="broken_pattern"):
        OpenDriveMap.from_file(path, broken_pattern=(6.0, -1.0))


def test_dashes_are_stepped_in_reference_s_on_a_curve(tmp_path: Path) -> None:
    # A dash at lateral offset t of a reference line of curvature κ is 6 (1 − κ t) m
    # long on the ground: its ends lie at s and s + 6 of the reference line.
    right = lane_xml(-1, marks=broken_mark()) + lane_xml(-2, marks=broken_mark())
    road = road_xml(
        "1", geometry_xml('<arc curvature="0.01"/>', 300.0), 300.0, section_xml(right=right)
    )
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "curve.xodr", road))
    for t in (-3.5, -7.0):  # outside of the left-hand curve
        m = marking_at(odr, 0.0, t)
        stretch = 1.0 - 0.01 * t
        assert m.u[-1] == pytest.approx(300.0 * stretch, abs=1e-3)
        assert len(m.painted) == 17  # dashes start at s = 0, 18, ..., 288
        np.testing.assert_allclose(np.diff(m.painted, axis=1)[:, 0], 6.0 * stretch, atol=1e-4)
        np.testing.assert_allclose(np.diff(m.painted[:, 0]), 18.0 * stretch, atol=1e-4)
        s_ends = np.interp(m.painted, m.u, m.s)
        np.testing.assert_allclose(s_ends[:, 0], 18.0 * np.arange(17), atol=1e-6)
        np.testing.assert_allclose(s_ends[:, 1], 18.0 * np.arange(17) + 6.0, atol=1e-6)
        # The dash's ends on the ground: the reference line's normal at those s.
        x, y = np.interp(m.painted[3], m.u, m.xy[:, 0]), np.interp(m.painted[3], m.u, m.xy[:, 1])
        phi = 0.01 * s_ends[3]
        np.testing.assert_allclose(x, (100.0 - t) * np.sin(phi), atol=1e-4)
        np.testing.assert_allclose(y, 100.0 - (100.0 - t) * np.cos(phi), atol=1e-4)


def test_pattern_restarts_at_a_new_lane_section(tmp_path: Path) -> None:
    # The second section restarts the pattern at its start (s = 110): the dash being
    # painted there (from s = 108) is cut at 110 and the next starts at 110 (the two
    # touch and are one painted interval), then every 18 m from 110.
    right = lane_xml(-1, marks=broken_mark()) + lane_xml(-2)
    sections = section_xml(0.0, right=right) + section_xml(110.0, right=right)
    road = road_xml("1", geometry_xml('<arc curvature="0.002"/>', 250.0), 250.0, sections)
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "sections.xodr", road))
    m = marking_at(odr, 0.0, -3.5)
    assert m.u[-1] == pytest.approx(250.0 * (1 + 0.002 * 3.5), abs=1e-3)
    steps = np.hypot(*np.diff(m.xy, axis=0).T)
    assert steps.max() < 0.51 and steps.min() > 1e-6
    np.testing.assert_allclose(np.diff(m.u), steps, atol=1e-9)
    first = 18.0 * np.arange(6)
    second = 110.0 + 18.0 * np.arange(1, 8)
    expected = np.concatenate(
        [np.stack([first, first + 6.0], 1), [[108.0, 116.0]], np.stack([second, second + 6.0], 1)]
    )
    np.testing.assert_allclose(np.interp(m.painted, m.u, m.s), expected, atol=1e-6)
    # Centre, lane -1 (dashed) and lane -2: each one object over both sections.
    assert len(odr.markings) == 3


def test_pattern_restarts_at_a_new_record(tmp_path: Path) -> None:
    # Two records of the same pattern: the second one starts its own dashes at its
    # sOffset (s = 100) instead of carrying the first one's phase (next dash at 108).
    marks = broken_mark() + broken_mark(s_offset=100.0)
    right = lane_xml(-1, marks=marks) + lane_xml(-2)
    road = road_xml("1", geometry_xml("<line/>", 200.0), 200.0, section_xml(right=right))
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "records.xodr", road))
    m = marking_at(odr, 50.0, -3.5)
    assert len([mk for mk in odr.markings if abs(mk.xy[0, 1] + 3.5) < 1e-9]) == 1
    starts = np.concatenate([18.0 * np.arange(6), 100.0 + 18.0 * np.arange(6)])
    np.testing.assert_allclose(m.painted, np.stack([starts, starts + 6.0], 1), atol=1e-9)


def test_last_dash_of_a_record_is_cut_at_its_end(tmp_path: Path) -> None:
    # Record 1 ends at s = 40 inside the dash from 36; record 2 (solid) takes over.
    marks = broken_mark() + '<roadMark sOffset="40" type="solid" color="standard" width="0.15"/>'
    right = lane_xml(-1, marks=marks) + lane_xml(-2)
    road = road_xml("1", geometry_xml("<line/>", 60.0), 60.0, section_xml(right=right))
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "cut.xodr", road))
    dashed = next(m for m in odr.markings if m.type == MarkingType.DASHED)
    np.testing.assert_allclose(dashed.painted, [[0, 6], [18, 24], [36, 40]], atol=1e-9)


def test_line_s_offset_moves_dashes_and_solid_lines(tmp_path: Path) -> None:
    solid = (
        '<roadMark sOffset="10" type="solid" color="standard" width="0.15">'
        '<type name="s" width="0.15"><line length="0" space="0" tOffset="0" sOffset="5" '
        'width="0.15"/></type></roadMark>'
    )
    right = lane_xml(-1, marks=broken_mark(line_s=2.5)) + lane_xml(-2, marks=solid)
    road = road_xml("1", geometry_xml("<line/>", 50.0), 50.0, section_xml(right=right))
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "offset.xodr", road))
    dashed = marking_at(odr, 25.0, -3.5)
    np.testing.assert_allclose(dashed.painted, [[2.5, 8.5], [20.5, 26.5], [38.5, 44.5]])
    # The solid line's piece covers its record (s = 10 to 50), painted from s = 15.
    line = marking_at(odr, 25.0, -7.0)
    assert line.xy[0, 0] == pytest.approx(10.0)
    np.testing.assert_allclose(line.painted, [[5.0, 40.0]], atol=1e-9)


@pytest.mark.parametrize(
    ("start", "record", "pattern", "expected"),
    [
        (0.0, (0.0, 40.0), (6.0, 12.0), [[0, 6], [18, 24], [36, 40]]),
        (0.0, (0.0, 36.0), (6.0, 12.0), [[0, 6], [18, 24]]),  # a dash at the end: none
        (2.0, (0.0, 10.0), (3.0, 1.0), [[2, 5], [6, 9]]),
        (-4.0, (0.0, 10.0), (6.0, 12.0), [[0, 2]]),  # paint before the record is cut
        (12.0, (0.0, 10.0), (6.0, 12.0), np.zeros((0, 2))),
        (3.0, (0.0, 10.0), None, [[3, 10]]),
    ],
)
def test_record_dashes(start, record, pattern, expected) -> None:
    np.testing.assert_allclose(record_dashes(start, record, pattern), np.reshape(expected, (-1, 2)))


def test_generated_highway_paint_is_unchanged() -> None:
    # The generator's roads keep their own periodic paint (aldm_gym.roads.highway),
    # whatever the OpenDRIVE reader does: pinned painted pieces of one seeded road.
    road = HighwayRoad({"seed": 3, "length": 2000.0})
    digest = hashlib.sha256()
    count = 0
    for s in (100.0, 700.0, 1300.0):
        for piece in painted_pieces(road, road.reference.position(s, 0.0), 150.0):
            digest.update(np.round(piece.xy, 6).tobytes())
            digest.update(bytes([piece.marking, piece.type]))
            count += 1
    assert count == 156
    assert digest.hexdigest() == "0fdedfacf95125e62fdd8c89c4f950d6967a8f1242b2d34baa6f250663dacec2"


def test_mark_type_change_starts_a_new_marking(tmp_path: Path) -> None:
    marks = broken_mark() + '<roadMark sOffset="60" type="solid" color="standard" width="0.15"/>'
    right = lane_xml(-1, marks=marks) + lane_xml(-2)
    road = road_xml("1", geometry_xml("<line/>", 100.0), 100.0, section_xml(right=right))
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "change.xodr", road))
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
    right = lane_xml(-1, marks=double) + lane_xml(-2, marks=none)
    left = lane_xml(1, marks='<roadMark sOffset="0" type="curb"/>')
    road = road_xml(
        "1",
        geometry_xml("<line/>", 50.0),
        50.0,
        section_xml(left=left, right=right, centre_mark=centre),
    )
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "double.xodr", road))
    half = 0.1  # the lines at ±w from the border, as esmini's stand-in double lines
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


def test_public_map_broken_lines_get_the_stand_in_pattern() -> None:
    # esmini's e6mini.xodr (tests/roads/opendrive/data): 'broken' marks without <type>
    # at up to 7 m from a gently curved reference line: 4 m dashes every 12 m of s.
    with pytest.warns(UserWarning):  # its userData, objects and signals are skipped
        odr = OpenDriveMap.from_file(DATA / "e6mini.xodr")
    dashed = [m for m in odr.markings if m.type == MarkingType.DASHED]
    assert len(dashed) == 4
    for m in dashed:
        s_ends = np.interp(m.painted, m.u, m.s)
        starts = 12.0 * np.arange(len(m.painted))
        np.testing.assert_allclose(s_ends[:, 0], starts, atol=1e-6)
        np.testing.assert_allclose(s_ends[:, 1], np.minimum(starts + 4.0, m.s[-1]), atol=1e-6)
