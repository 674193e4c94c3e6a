"""Lanes and road marks of OpenDRIVE maps (aldm_gym.roads.opendrive.lanes, marks):
borders, dash patterns, marks across sections."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aldm_gym.roads.markings import MarkingType
from aldm_gym.roads.opendrive import OpenDriveMap

from ._xodr import (
    broken_mark,
    geometry_xml,
    lane_xml,
    marking_at,
    road_xml,
    section_xml,
    write_xodr,
)

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
    m = marking_at(OpenDriveMap.from_file(path), 50.0, -3.5)
    np.testing.assert_allclose(m.painted[:3], [[0, 6], [18, 24], [36, 42]], atol=1e-9)
    m = marking_at(OpenDriveMap.from_file(path, broken_pattern=(3.0, 6.0)), 50.0, -3.5)
    np.testing.assert_allclose(m.painted[:3], [[0, 3], [9, 12], [18, 21]], atol=1e-9)
    with pytest.raises(ValueError, match="broken_pattern"):
        OpenDriveMap.from_file(path, broken_pattern=(6.0, -1.0))


def test_dashes_measured_along_the_painted_line_in_a_curve(tmp_path: Path) -> None:
    right = lane_xml(-1, marks=broken_mark()) + lane_xml(-2, marks=broken_mark())
    road = road_xml(
        "1", geometry_xml('<arc curvature="0.01"/>', 300.0), 300.0, section_xml(right=right)
    )
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "curve.xodr", road))
    for t in (-3.5, -7.0):  # outside of the left-hand curve
        m = marking_at(odr, 0.0, t)
        assert m.u[-1] == pytest.approx(300.0 * (1.0 - 0.01 * t), abs=1e-3)
        np.testing.assert_allclose(np.diff(m.painted, axis=1)[:-1, 0], 6.0, atol=1e-9)
        np.testing.assert_allclose(np.diff(m.painted[:, 0]), 18.0, atol=1e-9)


def test_marking_continues_across_lane_sections_without_jump(tmp_path: Path) -> None:
    # The second section restarts the pattern at its start (s = 110, mid-dash of the
    # first pattern); the painted line continues the first section's phase.
    right = lane_xml(-1, marks=broken_mark()) + lane_xml(-2)
    sections = section_xml(0.0, right=right) + section_xml(110.0, right=right)
    road = road_xml("1", geometry_xml('<arc curvature="0.002"/>', 250.0), 250.0, sections)
    odr = OpenDriveMap.from_file(write_xodr(tmp_path / "sections.xodr", road))
    m = marking_at(odr, 0.0, -3.5)
    assert m.u[-1] == pytest.approx(250.0 * (1 + 0.002 * 3.5), abs=1e-3)
    steps = np.hypot(*np.diff(m.xy, axis=0).T)
    assert steps.max() < 0.51 and steps.min() > 1e-6
    np.testing.assert_allclose(np.diff(m.u), steps, atol=1e-9)
    np.testing.assert_allclose(np.diff(m.painted[:, 0]), 18.0, atol=1e-9)
    np.testing.assert_allclose(np.diff(m.painted, axis=1)[:-1, 0], 6.0, atol=1e-9)
    # Centre, lane -1 (dashed) and lane -2: each one object over both sections.
    assert len(odr.markings) == 3


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
