"""An OpenDRIVE map as a road: sensor frames, detectors and ground truth on it."""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest

from aldm_gym.roads import OpenDriveRoad
from aldm_gym.roads.markings import MarkingChain
from aldm_gym.sensor import LineSensor, detect_lanes, naive_detect, score_detection
from aldm_gym.sensor.ground_truth import ground_truth_detect, true_line

xodr = pytest.importorskip("scenariogeneration.xodr")


def _road_file(
    factory: pytest.TempPathFactory, name: str, geometry: list, left: int, right: int, width: float
) -> Path:
    """One road of ``geometry`` with ``left`` and ``right`` lanes ``width`` wide, written
    to a temporary ``name.xodr``."""
    road = xodr.create_road(geometry, id=0, left_lanes=left, right_lanes=right, lane_width=width)
    odr = xodr.OpenDrive(name)
    odr.add_road(road)
    odr.adjust_roads_and_lanes()
    path = factory.mktemp("maps") / f"{name}.xodr"
    odr.write_xml(str(path))
    return path


@pytest.fixture(scope="module")
def curved_map(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3-lane one-way road: straight, clothoid, R = 500 m arc, clothoid, straight."""
    geometry = [
        xodr.Line(300),
        xodr.Spiral(0.0, -0.002, 100),
        xodr.Arc(-0.002, 400),
        xodr.Spiral(-0.002, 0.0, 100),
        xodr.Line(300),
    ]
    return _road_file(tmp_path_factory, "curved", geometry, 0, 3, 3.75)


def _shifted(pose: tuple[float, float, float], left: float) -> tuple[float, float, float]:
    x, y, h = pose
    return (x + left * math.sin(h), y - left * math.cos(h), h)  # highway-env's left


def test_lane_pose_on_the_straight_start(curved_map: Path) -> None:
    road = OpenDriveRoad.from_file(curved_map)
    # Road starts at the origin heading east; lane -2's centre is 1.5 widths right of
    # the reference line; highway-env's world mirrors OpenDRIVE's y.
    x, y, h = road.lane_pose("0", -2, 100.0)
    assert x == pytest.approx(100.0) and y == pytest.approx(1.5 * 3.75) and h == pytest.approx(0)
    with pytest.raises(ValueError, match="no lane -4"):
        road.lane_pose("0", -4, 100.0)
    with pytest.raises(ValueError, match="s must be finite"):
        road.lane_pose("0", -1, float("nan"))


def test_lane_position_is_the_ground_truth(curved_map: Path) -> None:
    road = OpenDriveRoad.from_file(curved_map)
    for s in (50.0, 450.0, 650.0, 1100.0):
        for k, lane in enumerate((-1, -2, -3)):
            pose = _shifted(road.lane_pose("0", lane, s), 0.4)
            pos = road.lane_position(pose[:2])
            assert pos.lane == ("0", 0, lane)
            assert pos.index == k and pos.lanes == 3
            assert pos.offset == pytest.approx(0.4, abs=1e-3)
            assert pos.width == pytest.approx(3.75)
            assert math.cos(pos.heading - pose[2]) > 0.9999
            assert 0.0 < pos.s < pos.end
    with pytest.raises(ValueError, match="driving lane"):
        road.lane_position((5000.0, 5000.0))
    with pytest.raises(ValueError, match="position"):
        road.lane_position((np.nan, 0.0))


@pytest.fixture(scope="module")
def two_way_map(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 1 km straight two-way road: one 3.5 m lane each way, with an R 500 m arc."""
    geometry = [xodr.Line(400), xodr.Arc(0.002, 200), xodr.Line(400)]
    return _road_file(tmp_path_factory, "two_way", geometry, 1, 1, 3.5)


def test_with_a_heading_the_oncoming_lane_is_not_the_cars_lane(two_way_map: Path) -> None:
    """A car overtaking in the oncoming lane is on its own lane's side, a lane width
    to the left, with the road ahead the way it drives: without the heading it is on
    the oncoming lane, whose road ahead is the way the car came."""
    road = OpenDriveRoad.from_file(two_way_map)
    for s in (100.0, 500.0, 900.0):
        x, y, h = road.lane_pose("0", -1, s)
        # in the middle of the oncoming lane, heading the ego lane's way
        xy = _shifted((x, y, h), 3.5)[:2]
        theirs = road.lane_position(xy)
        assert theirs.lane == ("0", 0, 1) and abs(theirs.offset) < 1e-3
        ours = road.lane_position(xy, heading=h)
        assert ours.lane == ("0", 0, -1)
        assert ours.offset == pytest.approx(3.5, abs=1e-3)
        # the road ahead: the rest of the road on its own lane, what it has driven on
        # the oncoming one
        assert road.road_left(ours) == pytest.approx(1000.0 - s, abs=2.0)
        assert road.road_left(theirs) == pytest.approx(s, abs=2.0)
        # heading the other way: the oncoming lane is the car's
        assert road.lane_position(xy, heading=h + math.pi).lane == ("0", 0, 1)
    with pytest.raises(ValueError, match="heading"):
        road.lane_position(xy, heading=float("nan"))


def test_with_no_lane_running_its_way_near_the_nearest_lane_counts(curved_map: Path) -> None:
    """On a one-way road, a car heading against the lanes is on the nearest lane."""
    road = OpenDriveRoad.from_file(curved_map)
    for s in (50.0, 650.0):
        x, y, h = _shifted(road.lane_pose("0", -2, s), 0.4)
        assert road.lane_position((x, y), heading=h + math.pi) == road.lane_position((x, y))


@pytest.mark.parametrize(("model", "naive_ok"), [("per_dash", 0.0), ("editor", 1.0)])
def test_the_papers_contrast_on_a_map(curved_map: Path, model: str, naive_ok: float) -> None:
    """Naive fails on per-dash objects, works on editor objects; the ALDM works on both."""
    road = OpenDriveRoad.from_file(curved_map, marking_model=model)
    sensor = LineSensor()
    both = {"naive": [], "aldm": [], "truth": []}
    for s in np.linspace(30.0, 1050.0, 25):
        for lane in (-1, -2, -3):
            pose = _shifted(road.lane_pose("0", lane, float(s)), 0.3)
            lane_key = road.lane_position(pose[:2]).lane
            frame = sensor.measure(road, pose)
            assert frame.n_lines > 0
            # every sensor point lies on its marking's true position
            for i in range(frame.n_lines):
                pts = frame.line_points(i)
                truth = true_line(road, frame, int(frame.line_marking[i]), pts[:, 0])
                assert np.nanmax(np.abs(truth - pts[:, 1])) < 1e-9
            dets = {
                "naive": naive_detect(frame, road.lane_width),
                "aldm": detect_lanes(frame),
                "truth": ground_truth_detect(road, frame, lane_key),
            }
            for name, det in dets.items():
                sc = score_detection(det, road, frame, lane_key)
                both[name].append(sc["ego_left"].correct and sc["ego_right"].correct)
    assert np.mean(both["aldm"]) == 1.0
    assert np.mean(both["truth"]) == 1.0
    assert np.mean(both["naive"]) == naive_ok


def test_per_dash_objects_are_dashes_editor_objects_are_lines(curved_map: Path) -> None:
    per_dash = OpenDriveRoad.from_file(curved_map)
    editor = per_dash.with_marking_model("editor")
    pose = per_dash.lane_pose("0", -2, 200.0)
    a, b = LineSensor().measure(per_dash, pose), LineSensor().measure(editor, pose)
    assert np.array_equal(np.sort(a.all_points, axis=0), np.sort(b.all_points, axis=0))
    assert b.n_lines == 4  # two edge lines and two dashed lane lines
    assert a.n_lines > 4 * 5
    dashed = a.line_type == 2
    lengths = [np.ptp(a.line_points(i)[:, 0]) for i in np.flatnonzero(dashed)]
    assert max(lengths) <= 6.0 + 1e-9  # no object longer than a 6 m dash


def test_boundary_markings(curved_map: Path) -> None:
    road = OpenDriveRoad.from_file(curved_map)
    pose = road.lane_pose("0", -1, 200.0)
    lane = road.lane_position(pose[:2]).lane
    marks = road.boundary_markings(lane, pose[:2])
    assert marks["left_adjacent"] is None
    assert marks["right_adjacent"] is not None
    assert len({marks["ego_left"], marks["ego_right"], marks["right_adjacent"]}) == 3
    with pytest.raises(ValueError, match="unknown driving lane"):
        road.boundary_markings(("9", 0, -1))


def test_a_marking_chain_knows_where_each_marking_takes_over() -> None:
    """Its starts project onto the sensor's x axis; it survives pickling and compares
    as the tuple of its markings."""
    chain = MarkingChain((4, 7, 2), np.array([[0.0, 0.0], [30.0, 40.0], [-10.0, 80.0]]))
    assert chain == (4, 7, 2) and isinstance(chain, tuple)
    # from (10, 0) facing along +y (90 degrees): 40 m and 80 m ahead
    assert chain.switch_x(np.array([10.0, 0.0]), math.pi / 2) == pytest.approx([40.0, 80.0])
    back = pickle.loads(pickle.dumps(chain))
    assert back == chain and np.array_equal(back.starts, chain.starts)
    with pytest.raises(ValueError, match="3 markings but 2 start points"):
        MarkingChain((4, 7, 2), np.zeros((2, 2)))


def test_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"nope\.xodr"):
        OpenDriveRoad.from_file(tmp_path / "nope.xodr")


def test_successors_list_every_continuing_lane_and_the_first_is_the_successor() -> None:
    """On the shipped motorway the exit lane (road 5, lane -4) continues onto the ramp
    (road 7) and the through lanes onto road 6; no lane splits there."""
    from aldm_gym.errors import InputError
    from aldm_gym.roads import shipped_map

    road = OpenDriveRoad.from_file(shipped_map("motorway"))
    assert road.successors(("5", 2, -4)) == [("7", 0, -1)]
    assert road.successors(("5", 2, -3)) == [("6", 0, -3)]
    for lane in road.lanes:
        following = road.successors(lane)
        assert road.successor(lane) == (following[0] if following else None), lane
    with pytest.raises(InputError, match="unknown driving lane"):
        road.successors(("5", 2, -9))
