"""Drives along map lanes (:mod:`aldm_gym.sensor.drives`): the path, the moving
vehicles, and a short drive scored for every detector."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from aldm_gym.errors import InputError
from aldm_gym.roads import OpenDriveRoad, shipped_map
from aldm_gym.sensor.drives import (
    CAR,
    CONDITIONS,
    DETECTORS,
    TRUCK,
    Condition,
    DriveScore,
    SeenPaint,
    drive,
    drive_starts,
    lane_path,
    path_length,
    path_poses,
    traffic,
)
from aldm_gym.sensor.lane_filter import FilterParams, LaneModelFilter
from aldm_gym.sensor.line_sensor import LineSensor

CURVATURE_STEP = Path(__file__).resolve().parents[2] / "benchmarks" / "data" / "curvature_step.xodr"


def test_path_poses_follow_a_polyline_with_its_segment_headings() -> None:
    # highway-env's frame: y down, so a left turn in the driver's view goes to -y
    xy = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, -10.0]])
    assert path_length(xy) == 20.0
    poses = path_poses(xy, np.array([-5.0, 5.0, 15.0, 30.0]))
    np.testing.assert_allclose(poses[:, :2], [[0, 0], [5, 0], [10, -5], [10, -10]])
    np.testing.assert_allclose(poses[:, 2], [0.0, 0.0, -math.pi / 2, -math.pi / 2])


def test_lane_path_runs_along_the_chain_in_driving_order() -> None:
    road = OpenDriveRoad.from_file(CURVATURE_STEP, marking_model="per_dash")
    starts = drive_starts(road)
    assert starts == [("1", 0, -1), ("1", 0, -2), ("1", 0, -3)]
    xy = lane_path(road, starts[1])
    # lane -2 starts 1.5 lanes right of the reference line (y down in highway-env)
    assert xy[0, 0] == pytest.approx(0.0) and xy[0, 1] == pytest.approx(1.5 * 3.75)
    # outside of the left arc, inside of the right one: as long as the reference line
    assert path_length(xy) == pytest.approx(1514.16, abs=0.5)
    pose = path_poses(xy, np.array([200.0, 700.0]))
    assert pose[0, 2] == pytest.approx(0.0, abs=1e-9)
    assert pose[1, 2] == pytest.approx(-math.pi / 2, abs=1e-9)  # heading +y in OpenDRIVE


def test_traffic_moves_wraps_and_keeps_its_lanes() -> None:
    xy = np.array([[0.0, 0.0], [5000.0, 0.0]])
    u = np.arange(600) * 2.5  # 60 s
    boxes = traffic(xy, u, 3.75, 4, 0.0, seed=0)
    assert boxes.shape == (600, 4, 6)
    gap = boxes[:, :, 0] - u[:, None]
    # the car ahead in the ego's lane breathes between 18 m and 60 m
    assert 17.9 < gap[:, 0].min() < 18.5 and 59.5 < gap[:, 0].max() < 60.1
    # lateral offsets: a lane left (y negative in highway-env's frame), a lane right
    np.testing.assert_allclose(boxes[:, :, 1], np.broadcast_to([0.0, -3.75, 3.75, -3.75], (600, 4)))
    # the overtaken car (2 m/s slower) falls behind and comes back 200 m ahead
    assert gap[:, 1].min() >= -40.0 and gap[:, 1].max() <= 200.0
    assert np.any(np.diff(gap[:, 1]) > 100.0)
    assert all(tuple(b[3:]) == CAR for b in boxes[0])
    trucks = traffic(xy, u, 3.75, 4, 1.0, seed=0)
    assert all(tuple(b[3:]) == TRUCK for b in trucks[0])


def test_a_short_drive_scores_every_detector_and_repeats_bit_for_bit() -> None:
    road = OpenDriveRoad.from_file(shipped_map("motorway"), marking_model="per_dash")
    start = drive_starts(road)[0]
    ideal = drive(road, start, CONDITIONS["ideal"], max_frames=60)
    assert set(ideal) == set(DETECTORS)
    for name, sc in ideal.items():
        assert sc.frames == 60 and sc.share == 1.0 and sc.longest_wrong == 0, name
        assert sc.observed == 60 and sc.longest_wrong_observed == 0, name
    runs = [drive(road, start, CONDITIONS["combined"], seed=3, max_frames=40) for _ in (0, 1)]
    assert {k: vars(v) for k, v in runs[0].items()} == {k: vars(v) for k, v in runs[1].items()}
    # a car ahead hides the ego's lines: no detector is always right with it, and in
    # some frames no detector could have measured them to the preview
    assert min(sc.share for sc in runs[0].values()) < 1.0
    for sc in runs[0].values():
        assert 0 < sc.observed < sc.frames
        assert sc.longest_wrong_observed <= sc.longest_wrong


def test_seen_paint_remembers_the_lines_a_car_hides_later() -> None:
    """What the sensor saw of the ego's lines stays where it is on the road: a frame
    in which a car close ahead hides the lines does not take back the reach an
    earlier frame measured, 10 m back along the lane (here heading across the map's
    axes: the memory is road-fixed in any direction). A drive that starts behind the
    car has seen nothing beyond it."""
    road = OpenDriveRoad.from_file(CURVATURE_STEP, marking_model="per_dash")
    xy = lane_path(road, drive_starts(road)[1])
    poses = path_poses(xy, np.array([700.0, 710.0]))
    assert abs(poses[0, 2]) > 1.0
    car = traffic(xy, np.array([710.0]), 3.75, 1, 1.0, seed=0)[0].copy()
    car[0, :3] = path_poses(xy, np.array([724.0]))[0]  # a truck 14 m ahead of the sensor
    sensor = LineSensor({"occlusion": True}, seed=0)
    names = ("ego_left", "ego_right")
    lane = road.lane_position(poses[1, :2]).lane
    clear = sensor.measure(road, tuple(poses[0]))
    hidden = sensor.measure(road, tuple(poses[1]), occluders=car)
    fresh = SeenPaint()
    fresh.add(hidden)
    short = fresh.reach(road, hidden, lane, names, 60.0)
    assert max(short.values()) < 30.0
    seen = SeenPaint()
    seen.add(clear)
    seen.add(hidden)
    far = seen.reach(road, hidden, lane, names, 60.0)
    assert min(far.values()) >= 42.0
    # nothing behind the sensor is kept
    assert len(seen) < 4 * 200 / 0.5 and all(v <= 60.0 for v in far.values())


def test_the_filter_follows_a_curvature_step() -> None:
    """Into the curvature-step map's first arc (a straight, then R 100 m with no
    transition curve), ideal sensor: the curvature-jump hypothesis bends the model
    where the arc comes into view. Without it (``jump_curvature=0``) the nominal
    model's gates and robust weights keep the straight far out, and its lines are
    wrong for longer."""
    road = OpenDriveRoad.from_file(CURVATURE_STEP, marking_model="per_dash")
    start = drive_starts(road)[0]

    def run(jump: float) -> dict[str, DriveScore]:
        params = {"filter": {"filt": FilterParams(jump_curvature=jump)}}
        return drive(
            road,
            start,
            CONDITIONS["ideal"],
            max_frames=180,
            detectors=("single_frame", "filter"),
            detector_params=params,
        )

    with_jump, without = run(0.005), run(0.0)
    assert with_jump["filter"].frames == 180
    assert with_jump["filter"].share >= 0.95
    assert with_jump["filter"].share > without["filter"].share
    assert with_jump["filter"].longest_wrong < without["filter"].longest_wrong
    assert with_jump["filter"].share > with_jump["single_frame"].share


def test_the_far_end_needs_no_extra_variance_with_six_nodes() -> None:
    """On the curvature-step map with vehicles (the ego lane's lines hidden beyond the
    car ahead, so the far nodes are measured on the lanes beside): with five nodes
    22.5 m apart the last node's extrapolation variance (``q_far_curvature_rate``)
    let the model bend as the road does out there. Six nodes 18 m apart follow the
    step without it, and the extra variance only lets the far end swing (1e-4 to
    1.5e-3 all measured worse): it stays off by default."""
    road = OpenDriveRoad.from_file(CURVATURE_STEP, marking_model="per_dash")
    start = drive_starts(road)[0]

    def run(q_far: float) -> DriveScore:
        params = {"filter": {"filt": FilterParams(q_far_curvature_rate=q_far)}}
        scores = drive(
            road, start, CONDITIONS["vehicles"], max_frames=300, detectors=("filter",),
            detector_params=params,
        )  # fmt: skip
        return scores["filter"]

    far, held = run(7e-4), run(FilterParams().q_far_curvature_rate)
    assert FilterParams().q_far_curvature_rate == 0.0
    assert far.frames == held.frames == 300
    assert held.share > far.share
    assert held.longest_wrong < far.longest_wrong


def test_the_filter_keeps_the_lines_where_an_arc_ends_in_a_straight() -> None:
    """Out of the curvature-step map's first arc (R 100 m, 90 degrees, then a straight
    with no transition curve), ideal sensor. In the bend, x up to ``model_range``
    reaches about 30 m farther along the road than the model's nodes: those points
    (on the straight beyond the arc's end) once bent the last node past zero, and
    the lines drawn there were 0.3-0.9 m off for about 1 s. Measured and drawn only
    within ``model_range`` along the road, every frame there is right; of the 260
    frames one is wrong, on the straight before the arc (frame 139: the far nodes
    overshoot the step coming into view, 0.37 m off at 88 m, until the curvature-jump
    hypothesis takes it the next frame)."""
    road = OpenDriveRoad.from_file(CURVATURE_STEP, marking_model="per_dash")
    start = drive_starts(road)[0]
    scores = drive(road, start, CONDITIONS["ideal"], max_frames=260, detectors=("filter",))
    assert scores["filter"].frames == 260
    assert scores["filter"].correct >= 259 and scores["filter"].longest_wrong <= 1


def test_a_bend_seen_on_one_line_past_the_cars_bends_the_model() -> None:
    """Towards the curvature-step map's first arc with vehicles: the car ahead and
    the cars beside hide every line beyond 20-60 m but the road's outer edge line,
    the only line that shows the arc coming. The jump hypothesis needs as many lines
    to gain as are seen that far (one here), not two; with two the model kept the
    straight and the lines were wrong for over 3 s."""
    road = OpenDriveRoad.from_file(CURVATURE_STEP, marking_model="per_dash")
    start = drive_starts(road)[0]
    score = drive(road, start, CONDITIONS["vehicles"], max_frames=170, detectors=("filter",))
    assert score["filter"].frames == 170
    assert score["filter"].share >= 0.9
    assert score["filter"].longest_wrong <= 10  # 1 s


def test_the_far_end_follows_a_spiral_across_the_view() -> None:
    """The shipped ``features`` map, lane 1 (against the reference line), ideal
    sensor, through its reverse spiral (the curvature changes across the whole view):
    with the last node step's trend carried on (``far_curvature_trend`` 0.5, the
    default) the far end follows the road; with the last node's curvature held it
    lags by a node step and the lines are off for 1.1 s. (Lane -1, which lagged 1.7 s
    when its far end took the other stripe of the double centre line, now follows the
    spiral either way.)"""
    road = OpenDriveRoad.from_file(shipped_map("features"), marking_model="per_dash")
    start = drive_starts(road)[1]
    assert start[2] == 1

    def run(trend: float) -> DriveScore:
        params = {"filter": {"filt": FilterParams(far_curvature_trend=trend)}}
        scores = drive(
            road, start, CONDITIONS["ideal"], detectors=("filter",), detector_params=params
        )  # fmt: skip
        return scores["filter"]

    trend, held = run(FilterParams().far_curvature_trend), run(0.0)
    assert FilterParams().far_curvature_trend == 0.5
    assert trend.frames == held.frames > 150
    assert trend.share == 1.0
    assert held.share < 0.95 and held.longest_wrong > 8


def _features_worn(start: int, condition: str = "worn", **params: float) -> DriveScore:
    """The filter along the ``features`` map's drive ``start`` with 30 % worn dashes
    (or another ``condition`` of :data:`CONDITIONS`)."""
    road = OpenDriveRoad.from_file(shipped_map("features"), marking_model="per_dash")
    scores = drive(
        road,
        drive_starts(road)[start],
        CONDITIONS[condition],
        detectors=("filter",),
        detector_params={"filter": {"filt": FilterParams(**params)}},
    )
    return scores["filter"]


def test_a_shoulder_edge_line_is_held_beside_the_lane_line() -> None:
    """``features``, lane -1: 0.75 m outside the ego lane's broken right line runs the
    shoulder's solid edge line. The filter holds both (a narrow strip: farther apart
    than ``min_spacing``, within ``lane_spacing``), so each takes its own points. With
    ``min_spacing`` 2.5 m the model can hold only one: with worn dashes, cars and
    noise (``combined``) the ego-right line sat on the edge line for most of the
    drive."""
    strip = _features_worn(0)
    assert strip.frames > 150
    assert strip.share >= 0.98 and strip.longest_wrong <= 3
    held = _features_worn(0, condition="combined")
    one = _features_worn(0, condition="combined", min_spacing=2.5)
    assert held.share > 0.7 and held.longest_wrong < 20
    assert one.share < 0.5 and one.longest_wrong > 30


def test_a_line_keeps_one_stripe_of_a_double_line(monkeypatch: pytest.MonkeyPatch) -> None:
    """``features``, lane 1 (the other way) with 30 % worn dashes: the ego-left line
    is the double centre line (solid and broken stripes 0.24 m apart). The line keeps
    the stripe it lies on near the sensor at every distance; taking whichever stripe
    the gate finds nearest, the far end took the other one where the shape lagged a
    bend, and the step bent the shape further off (0.9 s wrong)."""
    kept = _features_worn(1)
    assert kept.frames > 150
    assert kept.share >= 0.99 and kept.longest_wrong <= 1
    monkeypatch.setattr(LaneModelFilter, "_one_stripe", lambda _self, x, _y: np.ones(len(x), bool))
    both = _features_worn(1)
    assert both.share < 0.97 and both.longest_wrong >= 5


def test_drive_score_counts_runs_and_misses() -> None:
    sc = DriveScore()
    for ok in (True, False, False, True, False):
        sc.add(ok, True, ok, True)
    assert (sc.frames, sc.correct, sc.longest_wrong, sc.missed) == (5, 2, 2, 3)
    assert sc.share == 0.4 and sc.longest_wrong_s == pytest.approx(0.2)
    assert sc.missed_share == 0.3
    other = DriveScore()
    other.add(False, False, False, False)
    sc.merge(other)
    assert (sc.frames, sc.longest_wrong, sc.missed) == (6, 2, 5)
    assert math.isnan(DriveScore().share)


def test_an_unobserved_frame_ends_a_run_within_observed_frames() -> None:
    sc = DriveScore()
    for observed in (True, True, False, True, True, True):
        sc.add(False, True, True, True, observed)
    assert (sc.longest_wrong, sc.longest_wrong_observed, sc.observed) == (6, 3, 5)
    assert sc.observed_share == pytest.approx(5 / 6)
    assert sc.longest_wrong_observed_s == pytest.approx(0.3)
    other = DriveScore()
    for _ in range(4):
        other.add(False, False, True, True)
    sc.merge(other)
    assert (sc.longest_wrong, sc.longest_wrong_observed, sc.observed) == (6, 4, 9)


def test_bad_settings_are_refused_by_name() -> None:
    road = OpenDriveRoad.from_file(CURVATURE_STEP, marking_model="per_dash")
    with pytest.raises(InputError, match="unknown detectors"):
        drive(road, ("1", 0, -1), CONDITIONS["ideal"], detectors=("naive",))
    with pytest.raises(InputError, match=r"vehicles must be 0\.\.4"):
        Condition(vehicles=5)
    with pytest.raises(InputError, match="truck_share"):
        Condition(truck_share=1.5)


def test_frames_on_a_lane_narrower_than_a_lane_are_not_scored() -> None:
    """The 2+1 road's passing lane opens from nothing: a drive along it starts at the
    tip of its taper, where no detector is asked for a lane until it is 2.5 m wide."""
    road = OpenDriveRoad.from_file(shipped_map("two_plus_one"), marking_model="per_dash")
    start = ("1", 3, 1)
    frames = 60
    poses = path_poses(lane_path(road, start), np.arange(frames) * 2.5)
    widths = np.array([road.lane_position(p[:2]).width for p in poses])
    narrow = int(np.sum(widths < 2.5))
    assert 10 < narrow < frames  # the taper, then the lane
    scored = drive(road, start, CONDITIONS["ideal"], max_frames=frames, detectors=("filter",))
    assert 0 < scored["filter"].frames <= frames - narrow


def test_the_drive_benchmark_drives_a_map_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``benchmarks.lane_sequences --maps`` takes the path of any OpenDRIVE file; a path
    that is no map, or a map with no lane long enough for a drive, is a usage error."""
    from benchmarks import lane_sequences

    data = Path(__file__).resolve().parents[1] / "roads" / "opendrive" / "data"
    road = OpenDriveRoad.from_file(data / "straight_500m.xodr", marking_model="per_dash")
    n_drives = len(drive_starts(road))
    assert n_drives >= 1
    argv = ["--conditions", "ideal", "--max-frames", "4", "--jobs", "1"]
    lane_sequences.main(["--maps", str(data / "straight_500m.xodr"), *argv])
    rows = [r for r in capsys.readouterr().out.splitlines() if r.startswith("| straight_500m")]
    assert len(rows) == 1
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    assert cells[:3] == ["straight_500m.xodr", "ideal", str(4 * n_drives)]
    assert cells[4].startswith("1.000 / 0.0 s")  # the filter on a straight road

    short = tmp_path / "short.xodr"
    short.write_text((data / "straight_500m.xodr").read_text().replace('length="5', 'length="1'))
    for maps, message in (
        ("nowhere", "no map of the benchmark"),
        (str(tmp_path / "gone.xodr"), "gone.xodr: no such file"),
        (str(short), "no driving lane starts a lane chain of at least 400 m"),
    ):
        with pytest.raises(SystemExit) as exc:
            lane_sequences.main(["--maps", maps, *argv])
        assert exc.value.code == 2
        assert message in capsys.readouterr().err


def test_a_line_the_cars_partly_hide_is_missed_only_where_it_was_in_view(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``features``, lane 1, worn paint, noise and cars: for 5 s the cars leave 20-56 m
    of the ego-right line's 86 m in view and the sensor gives 0-4 points of its paint
    a frame, none a hit. A miss counts only for the share of the line the cars left in
    view, so the line is carried on. Counted whole whenever more than
    ``HIDDEN_LENGTH`` was left in view, the line was dropped after 60 m of travel and
    the ego lane lacked its right line for 1.5 s (15 of the drive's 350 ego lines)."""
    road = OpenDriveRoad.from_file(shipped_map("features"), marking_model="per_dash")
    start = drive_starts(road)[1]
    assert start[2] == 1

    def run() -> DriveScore:
        return drive(road, start, CONDITIONS["combined"], detectors=("filter",))["filter"]

    graded = run()
    original = LaneModelFilter._occlusion

    def whole(self: LaneModelFilter, points: object, beyond: object = None) -> tuple:
        seen, shadow = original(self, points, beyond)
        return np.where(seen > 0.0, 1.0, 0.0), shadow

    monkeypatch.setattr(LaneModelFilter, "_occlusion", whole)
    binary = run()
    assert graded.frames == binary.frames > 150
    assert graded.missed == 0
    assert binary.missed > 10
    assert graded.share > binary.share
    assert graded.longest_wrong < binary.longest_wrong
