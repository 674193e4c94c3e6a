"""The OpenDRIVE parser (aldm_gym.roads.opendrive.parse): records, and errors that name
file, road, element and line."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from aldm_gym.roads.opendrive.parse import (
    Spiral,
    parse_file,
)

from ._xodr import geometry_xml, lane_xml, road_xml, section_xml, write_xodr

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
    with pytest.raises(ValueError, match=r"broken\.xodr:\d+: malformed XML"):
        parse_file(path)


def test_geometry_without_type_names_road(tmp_path: Path) -> None:
    road = road_xml("7", geometry_xml("", 100.0), 100.0, section_xml(right=lane_xml(-1)))
    path = write_xodr(tmp_path / "notype.xodr", road)
    with pytest.raises(ValueError, match=r"notype\.xodr:\d+ <geometry> \(road '7'\)"):
        parse_file(path)


@pytest.mark.parametrize(
    ("geometry", "message"),
    [
        ('<arc curvature="abc"/>', r"<arc> \(road '3'\): .*curvature='abc' is not a number"),
        ('<arc curvature="nan"/>', r"<arc> \(road '3'\): .*not finite"),
        ("<clothoid/>", r"<clothoid> \(road '3'\): .*unknown geometry type"),
        ("<arc/>", r"<arc> \(road '3'\): .*missing attribute 'curvature'"),
    ],
)
def test_bad_geometry_records(tmp_path: Path, geometry: str, message: str) -> None:
    road = road_xml("3", geometry_xml(geometry, 100.0), 100.0, section_xml(right=lane_xml(-1)))
    with pytest.raises(ValueError, match=message):
        parse_file(write_xodr(tmp_path / "bad.xodr", road))


def test_negative_length_and_bad_width(tmp_path: Path) -> None:
    road = road_xml("4", geometry_xml("<line/>", -1.0), 100.0, section_xml(right=lane_xml(-1)))
    with pytest.raises(ValueError, match=r"<geometry> \(road '4'\): .*length=-1.0 is negative"):
        parse_file(write_xodr(tmp_path / "neg.xodr", road))
    bad = lane_xml(-1, width='<width sOffset="0" a="3.x" b="0" c="0" d="0"/>')
    road = road_xml("5", geometry_xml("<line/>", 100.0), 100.0, section_xml(right=bad))
    with pytest.raises(ValueError, match=r"<width> \(road '5'\): .*a='3.x' is not a number"):
        parse_file(write_xodr(tmp_path / "width.xodr", road))


def test_skipped_elements_one_warning(tmp_path: Path) -> None:
    extra = (
        '<elevationProfile><elevation s="0" a="2" b="0" c="0" d="0"/></elevationProfile>'
        '<lateralProfile><superelevation s="0" a="0" b="0" c="0" d="0"/></lateralProfile>'
        '<objects><object id="1" s="3" t="0"/></objects>'
        '<signals><signal id="1" s="3" t="0"/><signal id="2" s="4" t="0"/></signals>'
    )
    roads = [
        road_xml(
            str(i),
            geometry_xml("<line/>", 50.0),
            50.0,
            section_xml(right=lane_xml(-1)),
            extra=extra,
        )
        for i in (1, 2)
    ]
    path = write_xodr(tmp_path / "extras.xodr", *roads)
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
    left = lane_xml(1, width=widths)
    right = lane_xml(
        -1, marks=mark, extra='<link><predecessor id="-2"/><successor id="-1"/></link>'
    )
    link = (
        '<predecessor elementType="junction" elementId="9"/>'
        '<successor elementType="road" elementId="2" contactPoint="end"/>'
    )
    offsets = '<laneOffset s="0" a="0.25" b="0" c="0" d="0"/>'
    road = road_xml(
        "1",
        geometry_xml('<spiral curvStart="0" curvEnd="0.01"/>', 40.0),
        40.0,
        section_xml(left=left, right=right),
        link,
        offsets,
        rule="LHT",
    )
    junction = (
        '<junction id="9" name="j">'
        '<connection id="0" incomingRoad="1" connectingRoad="5" contactPoint="start">'
        '<laneLink from="-1" to="-2"/></connection></junction>'
    )
    parsed = parse_file(write_xodr(tmp_path / "rec.xodr", road, junctions=junction))
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


def test_numbers_that_would_size_an_array_or_leave_the_world(tmp_path: Path) -> None:
    """Lengths, coordinates and lane widths are checked before a table is allocated:
    each a ``MapError`` naming file, road and element (or lane and s)."""
    from aldm_gym.errors import MapError
    from aldm_gym.roads.opendrive import OpenDriveMap

    def plain(geometry: str, width: str = '<width sOffset="0" a="3.5" b="0" c="0" d="0"/>') -> str:
        return road_xml("6", geometry, 100.0, section_xml(right=lane_xml(-1, width=width)))

    cases = [
        (
            plain(geometry_xml("<line/>", 1e308)),
            r"<geometry> \(road '6'\): .*length=1e\+308 is more",
        ),
        (plain(geometry_xml("<line/>", 100.0, x=1e300)), r"<geometry> .*x=1e\+300 is more than"),
        # 3.5 m - 1e-3 ds^3 is below zero from ds = 15.2 m
        (
            plain(
                geometry_xml("<line/>", 100.0),
                '<width sOffset="0" a="3.5" b="0" c="0" d="-1e-3"/>',
            ),
            r"road '6', laneSection s=0.0: lane -1: its width is negative at s=15\.",
        ),
        # 1000 km of a two-lane road at 0.5 m: 6e6 border samples, more than a map may need
        (
            road_xml(
                "6",
                geometry_xml("<line/>", 999_999.0),
                999_999.0,
                section_xml(right=lane_xml(-1) + lane_xml(-2)),
            ),
            r"border samples .*more than the 4e\+06",
        ),
    ]
    for k, (road, message) in enumerate(cases):
        path = write_xodr(tmp_path / f"bad{k}.xodr", road)
        with pytest.raises(MapError, match=rf"bad{k}\.xodr.*{message}"):
            OpenDriveMap.from_file(path)
    # a width that dips below zero by less than the tolerance reads as 0
    dip = '<width sOffset="0" a="3.5" b="-0.0351" c="0" d="0"/>'  # -0.01 m at s = 100 m
    odr = OpenDriveMap.from_file(
        write_xodr(tmp_path / "dip.xodr", plain(geometry_xml("<line/>", 100.0), dip))
    )
    assert min(w.min() for w in (rec.width for rec in odr.lanes.values())) >= 0.0


def test_two_files_with_one_content_name_themselves(tmp_path: Path) -> None:
    """The map cache keys by path too: an error or a map's path names its own file."""
    from aldm_gym.errors import MapError
    from aldm_gym.roads import OpenDriveRoad

    road = road_xml("1", geometry_xml("<line/>", 100.0), 100.0, section_xml())  # no lanes
    for name in ("first.xodr", "second.xodr"):
        with pytest.raises(MapError, match=rf"{name}: no driving lane"):
            OpenDriveRoad.from_file(write_xodr(tmp_path / name, road))


def test_a_centre_lane_width_is_skipped_with_a_warning(tmp_path: Path) -> None:
    """OpenDRIVE gives the centre lane no width; a file that does (esmini's own maps) is
    read as without it, with the skip in the one warning."""
    plain = section_xml(right=lane_xml(-1) + lane_xml(-2))
    width = '<width sOffset="0" a="0.2" b="0" c="0" d="0"/>'
    wide = plain.replace(
        '<lane id="0" type="none" level="false">', f'<lane id="0" type="none" level="false">{width}'
    )
    assert wide != plain
    geometry = geometry_xml("<line/>", 50.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        parsed = parse_file(write_xodr(tmp_path / "wide.xodr", road_xml("1", geometry, 50.0, wide)))
    assert any("center/lane/width x1" in str(w.message) for w in caught)
    reference = parse_file(
        write_xodr(tmp_path / "plain.xodr", road_xml("1", geometry, 50.0, plain))
    )
    assert parsed.roads[0].sections == reference.roads[0].sections
