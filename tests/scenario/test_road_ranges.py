"""A traffic area's ``RoadRange``s on a map: cursors on one road, on linked roads
(through road links and junctions), cursors without ``s``, and what is refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from aldm_gym.errors import ScenarioError
from aldm_gym.roads import OpenDriveRoad, shipped_map
from aldm_gym.scenario.traffic import road_ranges
from tests.scenario.corpus import split_road


@pytest.fixture(scope="module")
def motorway() -> OpenDriveRoad:
    """Roads 1-6 linked end to start (600, 1000, 900, 1040, 700, 1200 m), road 7 an
    exit ramp from road 5's exit lane."""
    return OpenDriveRoad.from_file(shipped_map("motorway"))


def test_cursors_on_one_road_and_without_s(motorway: OpenDriveRoad) -> None:
    one = [(1e9, [("2", 300.0, (-1,)), ("2", 100.0, ())])]
    assert road_ranges(motorway, one, "f:1") == (("2", 100.0, 300.0, (-1,)),)
    # without s: the first cursor is the road's start, the last its end
    whole = [(1e9, [("3", None, ()), ("3", None, ())])]
    assert road_ranges(motorway, whole, "f:1") == (("3", 0.0, 900.0, ()),)


def test_cursors_on_linked_roads_cover_the_roads_between(motorway: OpenDriveRoad) -> None:
    spec = [(1e9, [("1", 500.0, ()), ("4", 40.0, ())])]
    assert road_ranges(motorway, spec, "f:1") == (
        ("1", 500.0, 600.0, ()),
        ("2", 0.0, 1000.0000000000003, ()),
        ("3", 0.0, 900.0, ()),
        ("4", 0.0, 40.0, ()),
    )
    # the other way round: against s, the same roads
    back = [(1e9, [("4", 40.0, ()), ("1", 500.0, ())])]
    assert sorted(road_ranges(motorway, back, "f:1")) == sorted(road_ranges(motorway, spec, "f:1"))
    # the range's length cuts it from its first cursor on: 100 m of road 1, then 50 m
    # of road 2; against s, 40 m of road 4 and the last 110 m of road 3
    short = [(150.0, [("1", 500.0, ()), ("4", 40.0, ())])]
    assert road_ranges(motorway, short, "f:1") == (("1", 500.0, 600.0, ()), ("2", 0.0, 50.0, ()))
    back = [(150.0, [("4", 40.0, ()), ("1", 500.0, ())])]
    assert road_ranges(motorway, back, "f:1") == (("4", 0.0, 40.0, ()), ("3", 790.0, 900.0, ()))
    # the first cursor's lanes on its own road only; a cursor without s: its whole road
    lanes = [(1e9, [("1", 500.0, (-1,)), ("2", None, ())])]
    assert road_ranges(motorway, lanes, "f:1") == (
        ("1", 500.0, 600.0, (-1,)),
        ("2", 0.0, 1000.0000000000003, ()),
    )


def test_cursors_through_a_junction(tmp_path: Path) -> None:
    road = OpenDriveRoad.from_file(split_road(tmp_path))
    spec = [(1e9, [("0", 250.0, ()), ("2", 60.0, ())])]
    pieces = road_ranges(road, spec, "f:1")
    assert [p[0] for p in pieces] == ["0", "3", "2"]  # through the exit's connecting road
    assert pieces[0][1:3] == (250.0, 300.0) and pieces[-1][1:3] == (0.0, 60.0)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ([(1e9, [("9", 0.0, ()), ("1", 10.0, ())])], r"f:1: a road cursor names no road '9'"),
        ([(1e9, [("1", 700.0, ()), ("1", 10.0, ())])], r"s = 700 m is off road '1'"),
        ([(1e9, [("2", 10.0, ()), ("2", 10.0, ())])], r"cover no road"),
    ],
)
def test_bad_road_ranges_are_clear_errors(
    motorway: OpenDriveRoad, spec: list, message: str
) -> None:
    with pytest.raises(ScenarioError, match=message):
        road_ranges(motorway, spec, "f:1")


def test_roads_no_lane_links_are_refused(tmp_path: Path) -> None:
    road = OpenDriveRoad.from_file(split_road(tmp_path))
    # road 1 (straight on) and road 2 (the exit) are both reached from road 0, but
    # neither leads to the other without turning back at the fork
    spec = [(1e9, [("1", 10.0, ()), ("2", 10.0, ())])]
    with pytest.raises(ScenarioError, match=r"no lanes join road '1' and road '2'"):
        road_ranges(road, spec, "f:1")
    # against the traffic from the exit back onto road 0: through the exit's branch
    back = road_ranges(road, [(1e9, [("2", 60.0, ()), ("0", 250.0, ())])], "f:1")
    assert [p[0] for p in back] == ["2", "3", "0"]
    assert back[0][1:3] == (0.0, 60.0) and back[-1][1:3] == (250.0, 300.0)
