"""``ALDMHighway-v0`` on OpenDRIVE maps: config, start, ground truth, traffic, truncation."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from highway_env.road.road import Road

import aldm_gym  # also registers the env
from aldm_gym.envs.scene import MAP_START_WIDTH
from aldm_gym.envs.traffic.vehicles import STEPS_ENDING_WITH_UPDATE
from aldm_gym.envs.vehicle import MapIDMVehicle
from aldm_gym.roads import OpenDriveRoad
from aldm_gym.roads.map_network import (
    CentreLine,
    MapLane,
    MapNetwork,
    _closest_lane,
    _closest_lane_py,
    _closest_lanes,
    _closest_lanes_py,
    _neighbour_table,
    _neighbour_table_py,
)
from aldm_gym.roads.reference_line import ReferenceLine, project_point_near, project_point_near_py
from aldm_gym.sensor.aldm import ALDMParams

xodr = pytest.importorskip("scenariogeneration.xodr")


def _write(odr: object, path: Path) -> Path:
    odr.adjust_roads_and_lanes()  # type: ignore[attr-defined]
    odr.write_xml(str(path))  # type: ignore[attr-defined]
    return path


def _one_way(
    factory: pytest.TempPathFactory, name: str, geometry: list, lanes: object, width: float
) -> Path:
    """A one-way road of ``geometry`` whose right lanes change as ``lanes`` (a
    ``LaneDef``) says, written to a temporary ``name.xodr``."""
    road = xodr.create_road(geometry, id=0, left_lanes=0, right_lanes=[lanes], lane_width=width)
    odr = xodr.OpenDrive(name)
    odr.add_road(road)
    return _write(odr, factory.mktemp("maps") / f"{name}.xodr")


@pytest.fixture(scope="module")
def curved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 2.4 km one-way 3-lane road: straight, clothoid, R = 600 m arc, clothoid, straight."""
    road = xodr.create_road(
        [
            xodr.Line(500),
            xodr.Spiral(0.0, -1 / 600, 100),
            xodr.Arc(-1 / 600, 700),
            xodr.Spiral(-1 / 600, 0.0, 100),
            xodr.Line(1000),
        ],
        id=0,
        left_lanes=0,
        right_lanes=3,
        lane_width=3.75,
    )
    odr = xodr.OpenDrive("curved")
    odr.add_road(road)
    return _write(odr, tmp_path_factory.mktemp("maps") / "curved.xodr")


@pytest.fixture(scope="module")
def lane_end(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 1.6 km one-way road whose rightmost of 3 lanes tapers out between 600 and 700 m."""
    geometry = [xodr.Line(300), xodr.Arc(1 / 800, 400), xodr.Line(900)]
    lanes = xodr.LaneDef(600, 700, 3, 2, -3)
    return _one_way(tmp_path_factory, "lane_end", geometry, lanes, 3.75)


def _ring_xodr(lead_in: float = 0.0) -> str:
    """A 300 m circle of two one-way lanes whose road is its own predecessor and
    successor (a test track, as esmini's ``circle_300m.xodr``), and a straight road of
    ``lead_in`` [m] that runs into it (none for 0)."""
    lane = (
        '<lane id="{}" type="driving" level="false"><link>{}</link>'
        '<width sOffset="0" a="3.5" b="0" c="0" d="0"/>'
        '<roadMark sOffset="0" type="{}" color="standard" width="0.15"/></lane>'
    )
    both = '<predecessor id="{0}"/><successor id="{0}"/>'
    centre = (
        '<center><lane id="0" type="none" level="false">'
        '<roadMark sOffset="0" type="solid" color="standard" width="0.15"/></lane></center>'
    )

    def road(rid: str, length: float, link: str, geometry: str, lanes: str) -> str:
        return (
            f'<road id="{rid}" length="{length}" junction="-1"><link>{link}</link>'
            f'<planView>{geometry}</planView><lanes><laneSection s="0">{centre}'
            f"<right>{lanes}</right></laneSection></lanes></road>"
        )

    ring = road(
        "1",
        300.0,
        '<predecessor elementType="road" elementId="1" contactPoint="end"/>'
        '<successor elementType="road" elementId="1" contactPoint="start"/>',
        '<geometry s="0" x="0" y="0" hdg="0" length="300">'
        f'<arc curvature="{2.0 * math.pi / 300.0!r}"/></geometry>',
        lane.format(-1, both.format(-1), "broken") + lane.format(-2, both.format(-2), "solid"),
    )
    roads = [ring]
    if lead_in > 0.0:
        roads.append(
            road(
                "2",
                lead_in,
                '<successor elementType="road" elementId="1" contactPoint="start"/>',
                f'<geometry s="0" x="{-lead_in}" y="0" hdg="0" length="{lead_in}">'
                "<line/></geometry>",
                lane.format(-1, '<successor id="-1"/>', "broken")
                + lane.format(-2, '<successor id="-2"/>', "solid"),
            )
        )
    return (
        '<?xml version="1.0"?>\n<OpenDRIVE><header revMajor="1" revMinor="6" name="ring"/>'
        + "".join(roads)
        + "</OpenDRIVE>\n"
    )


@pytest.fixture(scope="module")
def ring(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """:func:`_ring_xodr` without a lead-in."""
    path = tmp_path_factory.mktemp("maps") / "ring.xodr"
    path.write_text(_ring_xodr())
    return path


@pytest.fixture(scope="module")
def opening(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 1.5 km one-way road whose third lane opens from nothing over its first 150 m."""
    lanes = xodr.LaneDef(0, 150, 2, 3, -3)
    return _one_way(tmp_path_factory, "opening", [xodr.Line(1500)], lanes, 3.5)


def _make(path: Path, **config: object) -> gym.Env:
    cfg = {"road": {"xodr": str(path)}, "vehicles_count": 0, "duration": 30.0}
    cfg.update(config)
    return gym.make("ALDMHighway-v0", config=cfg)


def test_closest_lane_kernel_matches_its_python_reference(curved: Path) -> None:
    road = OpenDriveRoad.from_file(curved)
    net = road.network
    c = road._centres
    chunks = (c.chunk_mark, c.chunk_i0, c.chunk_i1, c.chunk_centre, c.chunk_radius)
    for p, h, reach in (
        ((100.0, 4.0), 0.0, 15.0),
        ((900.0, -300.0), -0.5, 15.0),
        ((50.0, 9.0), 3.0, 15.0),
        ((5e3, 5e3), 0.0, 15.0),
        ((5e3, 5e3), 0.0, math.inf),
    ):
        args = (*chunks, len(road.lanes), c.xy, net._seg_heading, *p, h, 1.0, reach)
        assert _closest_lane(*args) == _closest_lane_py(*args)
    assert (
        _closest_lane(*chunks, len(road.lanes), c.xy, net._seg_heading, 5e3, 5e3, 0.0, 1.0, 15.0)
        == -1
    )


def test_centre_line_inverts_its_positions() -> None:
    t = np.linspace(0.0, 1.0, 400)
    xy = np.column_stack([300.0 * np.sin(t), 300.0 * (1.0 - np.cos(t))])
    line = CentreLine(xy)
    for s in (0.0, 77.7, 150.0, line.length):
        for d in (-3.0, 0.0, 2.5):
            got = line.project(line.position(s, d))
            assert got == pytest.approx((s, d), abs=2e-3)


def test_reset_step_and_check_env(curved: Path) -> None:
    env = _make(curved, vehicles_count=5)
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert env.unwrapped.config["lanes_count"] == 3
    for _ in range(3):
        obs, _reward, _terminated, _truncated, info = env.step(1)
    assert math.isinf(info["lane_ends_in"])  # no lane ends on this map
    assert 0 <= info["lane_index"] < 3


def test_seeded_runs_repeat(curved: Path) -> None:
    def run(seed: int) -> list:
        env = _make(curved, vehicles_count=6)
        obs, _info = env.reset(seed=seed)
        out = [env.unwrapped.vehicle.position.copy(), obs["lines"].copy()]
        for _ in range(3):
            obs, *_ = env.step(1)
            out += [v.position.copy() for v in env.unwrapped.road.vehicles]
        return out

    a, b, c = run(7), run(7), run(8)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0], c[0])


def test_ground_truth_comes_from_the_map(curved: Path) -> None:
    env = _make(curved, initial_lane_id=1)
    road = OpenDriveRoad.from_file(curved)
    _, info = env.reset(seed=0)
    u = env.unwrapped
    truth = road.lane_position(u.vehicle.position)
    assert info["lane_index"] == 1 == truth.index
    assert info["lateral_offset"] == pytest.approx(truth.offset) and abs(truth.offset) < 0.05
    s = [info["arc_length"]]
    for _ in range(5):
        _, _, _, _, info = env.step(1)
        s.append(info["arc_length"])
        assert info["lane_departure"] is False
    assert np.all(np.diff(s) > 20.0)  # ~25 m/s along the lane chain


def test_start_leaves_enough_road_ahead(curved: Path) -> None:
    env = _make(curved, duration=20.0)
    for seed in range(5):
        env.reset(seed=seed)
        pos = env.unwrapped.lane_position
        assert pos.end - pos.s >= 500.0 + 250.0 - 1.0


def test_short_map_warns_and_truncates_at_the_end(lane_end: Path) -> None:
    env = _make(lane_end, duration=200.0, initial_speed=30.0)
    with pytest.warns(UserWarning, match="no driving lane has"):
        env.reset(seed=0)
    truncated = False
    for _ in range(80):
        _, _, terminated, truncated, _info = env.step(1)
        if terminated or truncated:
            break
    assert truncated and not terminated
    road = env.unwrapped.highway
    assert road.road_left(env.unwrapped.lane_position) < 250.0


def test_traffic_on_a_ring_stops_short_of_the_ego(ring: Path) -> None:
    """Traffic is placed ahead of the ego along its chain of lanes; on a ring that chain
    comes back round to the ego, and no vehicle is placed on top of it from behind."""
    # the ring's lane chain is one lap (300 m), shorter than the episode's way
    with pytest.warns(UserWarning, match="no driving lane has"):
        env = _make(ring, vehicles_count=20, vehicles_density=1.0)
    for seed in range(5):
        with pytest.warns(UserWarning, match="no driving lane has"):
            env.reset(seed=seed)
        ego = env.unwrapped.vehicle
        others = env.unwrapped.road.vehicles[1:]
        assert 1 <= len(others) < 20  # the ring has room for some, not all twenty
        # each car's way ahead of the ego along the ego's (circular) lane
        length = ego.lane.length
        here = ego.lane.local_coordinates(ego.position)[0]
        gaps = [(ego.lane.local_coordinates(v.position)[0] - here) % length for v in others]
        # every car more than a car's length ahead, and as far from the ego's tail
        # counted round the ring
        assert min(gaps) > 10.0 and max(gaps) < length - 10.0, (seed, sorted(gaps))
        _, _, terminated, _, info = env.step(1)
        assert not info["crashed"] and not terminated
        assert np.all(np.isfinite(ego.position))


def test_traffic_round_a_ring_behind_a_lead_in_keeps_its_gaps(tmp_path: Path) -> None:
    """The ego on a road that runs into a ring: the traffic goes round the ring at most
    once, so no two vehicles are placed on top of each other."""
    path = tmp_path / "lead_in.xodr"
    path.write_text(_ring_xodr(lead_in=500.0))
    with pytest.warns(UserWarning, match="no driving lane has"):
        env = _make(path, vehicles_count=40, vehicles_density=1.0)
    for seed in range(3):
        with pytest.warns(UserWarning, match="no driving lane has"):
            env.reset(seed=seed)
        xy = np.array([v.position for v in env.unwrapped.road.vehicles])
        assert 2 <= len(xy) < 41
        gaps = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(gaps, np.inf)
        assert gaps.min() > 5.0, (seed, float(gaps.min()))
        env.step(1)
        assert not any(v.crashed for v in env.unwrapped.road.vehicles), seed


def test_the_ego_starts_where_its_lane_is_wide_enough(opening: Path, tmp_path: Path) -> None:
    """Not on the tip of a lane that opens from nothing (a zero lane width divided the
    lane-keeping reward), also on a map too short for the episode."""
    # the width the ALDM calls a lane
    assert MAP_START_WIDTH == ALDMParams().min_lane_width
    env = _make(opening, initial_lane_id=2, duration=10.0)
    road = env.unwrapped.highway
    for seed in range(8):
        env.reset(seed=seed)
        pos = env.unwrapped.lane_position
        assert road.siblings(pos.lane).index(pos.lane) == 2
        assert pos.width >= 2.5 - 1e-9
    # a 10 m lane that widens from 0 to 10 m: the start falls back to the first place
    # at least 2.5 m wide, and the episode steps (rewards finite)
    tiny = tmp_path / "tiny.xodr"
    tiny.write_text(
        '<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="6" name="t"/>'
        '<road id="4" length="10" junction="-1"><link/><planView>'
        '<geometry s="0" x="10" y="-10" hdg="1" length="10"><line/></geometry></planView>'
        '<lanes><laneSection s="0"><center><lane id="0" type="driving" level="false">'
        '<roadMark sOffset="0" type="solid" width="0.12"/></lane></center><right>'
        '<lane id="-1" type="driving" level="false"><width sOffset="0" a="0" b="1" c="0" d="0"/>'
        '<roadMark sOffset="0" type="solid" width="0.12"/></lane></right></laneSection>'
        "</lanes></road></OpenDRIVE>"
    )
    with pytest.warns(UserWarning, match="no driving lane has"):
        env = _make(tiny)
        env.reset(seed=0)
    pos = env.unwrapped.lane_position
    assert pos.width >= 2.5 - 1e-9
    _, reward, _, _, info = env.step(1)
    assert math.isfinite(reward) and all(math.isfinite(v) for v in info["rewards"].values())


def test_esmini_lane_that_widens_from_nothing_resets_and_steps() -> None:
    """esmini's ``lane_width_and_offset.xodr`` (a unit-test map: one 10 m lane widening
    from 0 under a ``laneOffset``): the env starts where the lane is 2.5 m wide and
    steps with finite rewards (a zero width divided the lane-keeping term at reset)."""
    path = Path(__file__).resolve().parents[1] / "roads/opendrive/data/lane_width_and_offset.xodr"
    with pytest.warns(UserWarning, match="no driving lane has"):
        env = _make(path)
        env.reset(seed=0)
    assert env.unwrapped.lane_position.width >= MAP_START_WIDTH - 1e-9
    _, reward, _, _, info = env.step(1)
    assert math.isfinite(reward) and all(math.isfinite(v) for v in info["rewards"].values())


def test_a_long_map_with_no_lane_wide_enough_still_draws_the_start(tmp_path: Path) -> None:
    """Lanes of 2.25 m everywhere: the start is drawn as on any long map, with a
    warning that says why (not that the map is short)."""
    road = xodr.create_road([xodr.Line(2000)], id=0, left_lanes=0, right_lanes=2, lane_width=2.25)
    odr = xodr.OpenDrive("narrow")
    odr.add_road(road)
    path = _write(odr, tmp_path / "narrow.xodr")
    with pytest.warns(UserWarning, match="no driving lane is 2.5 m wide where it has"):
        env = _make(path)
    starts = set()
    for seed in range(4):
        with pytest.warns(UserWarning, match="no driving lane is 2.5 m wide"):
            env.reset(seed=seed)
        pos = env.unwrapped.lane_position
        assert pos.end - pos.s >= 500.0 + 250.0 - 1.0
        starts.add(round(pos.s, 6))
    assert len(starts) == 4


def test_a_lane_change_into_the_oncoming_lane_is_a_departure(tmp_path: Path) -> None:
    """On a two-way road the lane left of the ego's is the oncoming one: the lane
    change into it (overtaking across a broken centre line; the detection cannot tell
    a lane's direction) takes the ego out of its lane, a departure at every step it
    stays there, with the road ahead still the way it drives (it was located on the
    oncoming lane, not departed, and the road ahead its lane's way back)."""
    road = xodr.create_road(
        [xodr.Line(2000)],
        id=0,
        left_lanes=1,
        right_lanes=1,
        lane_width=3.5,
        center_road_mark=xodr.std_roadmark_broken(),
    )
    odr = xodr.OpenDrive("two_way")
    odr.add_road(road)
    env = _make(_write(odr, tmp_path / "two_way.xodr"), duration=20.0)
    env.reset(seed=0)
    u = env.unwrapped
    lane, s0 = u.lane_position.lane, u.lane_position.s
    info = env.step(0)[4]  # LANE_LEFT
    assert info["lane_change"] == 1
    for _ in range(5):
        _, _, term, trunc, info = env.step(1)
        assert not (term or trunc)
    assert info["lane_changes_completed"] == 1
    assert u.lane_position.lane == lane
    assert info["lateral_offset"] == pytest.approx(3.5, abs=0.2)
    assert info["lane_departure"] and info["departures"] >= 4
    assert u.lane_position.s > s0 + 100.0
    env.close()


@pytest.mark.parametrize("cross", [False, True])
def test_a_lane_change_across_a_solid_line_is_refused(tmp_path: Path, cross: bool) -> None:
    """The lane left of the ego's lies beyond a solid centre line: LANE_LEFT is masked
    and refused (no lane change starts), unless ``action.cross_solid_lines``."""
    road = xodr.create_road([xodr.Line(2000)], id=0, left_lanes=1, right_lanes=1, lane_width=3.5)
    odr = xodr.OpenDrive("solid_centre")
    odr.add_road(road)
    env = _make(
        _write(odr, tmp_path / "solid_centre.xodr"),
        duration=20.0,
        action={"cross_solid_lines": cross},
    )
    env.reset(seed=0)
    u = env.unwrapped
    assert u.vehicle.paint["ego_left"] == 1
    assert bool(u.action_masks()[0]) is cross
    info = env.step(0)[4]  # LANE_LEFT
    assert info["lane_change_refused"] is not cross
    assert info["lane_change"] == int(cross)
    env.close()


def test_a_car_that_overtook_across_a_double_line_may_change_back() -> None:
    """``features``' centre line is broken on the car's side, solid on the oncoming
    lane's: the change into the oncoming lane is allowed, and so is the change back
    across the solid stripe, only as the return of that change."""
    from aldm_gym.roads import shipped_map

    env = _make(shipped_map("features"), duration=20.0)
    env.reset(seed=0)
    ego = env.unwrapped.vehicle
    assert ego.paint["ego_left"] == 2 and env.unwrapped.action_masks()[0]
    env.step(0)  # LANE_LEFT
    assert ego.return_permit == -1
    for _ in range(6):
        if ego.lane_changes_completed:
            break
        env.step(1)
    assert ego.lane_changes_completed == 1
    assert ego.paint["ego_right"] == 1 and ego.far_paint["ego_right"] == 2
    assert env.unwrapped.action_masks()[2]  # LANE_RIGHT: back
    ego.return_permit = 0  # no change across the line from its broken side before
    assert not env.unwrapped.action_masks()[2]
    env.close()


def test_the_ending_lane_shows_in_info(lane_end: Path) -> None:
    road = OpenDriveRoad.from_file(lane_end)
    net = road.network
    ending = [k for k in road.lanes if road.chain_end(k) < 800.0]
    assert ending and all(len(road.siblings(k)) == 3 for k in ending)
    lane = net.get_lane(net.index_of[min(ending, key=road.chain_start)])
    pos = road.lane_position(lane.position(100.0, 0.0))
    assert road.lane_ends_in(pos) == pytest.approx(pos.end - pos.s)
    assert 500.0 < road.lane_ends_in(pos) < 700.0
    # Its neighbour continues to the road's end: nothing ends ahead of it.
    beside = net.get_lane(net.index_of[road.siblings(lane.key)[0]])
    assert math.isinf(road.lane_ends_in(road.lane_position(beside.position(100.0, 0.0))))
    # In the env, the key shows on maps only.
    env = _make(lane_end, initial_lane_id=2, duration=5.0)
    with pytest.warns(UserWarning):
        _, _info = env.reset(seed=0)
    env.step(1)
    assert "lane_ends_in" in env.step(1)[4]


@pytest.mark.parametrize(("detector", "departs"), [("aldm", False), ("naive", True)])
def test_closed_loop_on_the_map(curved: Path, detector: str, departs: bool) -> None:
    """The paper's contrast on a map with per-dash objects, driving IDLE for ~30 s."""
    env = _make(curved, detector=detector, duration=30.0, initial_lane_id=1)
    env.reset(seed=1)
    departures = 0
    for _ in range(30):
        _, _, terminated, truncated, info = env.step(1)
        departures = info["departures"]
        if terminated or truncated:
            break
    assert (departures > 0) is departs


def test_config_errors_name_the_key_or_file(curved: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"\['seed'\] do not apply to maps"):
        gym.make("ALDMHighway-v0", config={"road": {"xodr": str(curved), "seed": 3}})
    with pytest.raises(ValueError, match="curved"):
        gym.make("ALDMHighway-v0", config={"road": {"xodr": str(curved), "curved": False}})
    missing = tmp_path / "nowhere.xodr"
    with pytest.raises(FileNotFoundError, match=r"nowhere\.xodr"):
        gym.make("ALDMHighway-v0", config={"road": {"xodr": str(missing)}})
    with pytest.raises(ValueError, match="apply only to maps"):
        gym.make("ALDMHighway-v0", config={"road": {"sample_step": 1.0}})
    with pytest.raises(ValueError, match="sample_step"):
        gym.make("ALDMHighway-v0", config={"road": {"xodr": str(curved), "sample_step": -1}})


def test_traffic_merges_out_of_an_ending_lane(lane_end: Path) -> None:
    """Vehicles on the lane that ends merge left before its end; none drives past it."""
    env = _make(lane_end, duration=60.0)
    with pytest.warns(UserWarning):
        env.reset(seed=0)
    u = env.unwrapped
    road, net = u.highway, u.highway.network
    u.road.vehicles.remove(u.vehicle)  # traffic alone
    ending = [k for k in road.lanes if road.successor(k) is None and road.chain_end(k) < 800]
    first = min(ending, key=road.chain_start)
    lane = net.get_lane(net.index_of[first])
    merging = []
    for s in np.arange(20.0, 500.0, 60.0):
        v = MapIDMVehicle(u.road, lane.position(s, 0.0), lane.heading_at(s), 25.0)
        u.road.vehicles.append(v)
        merging.append(v)
    # Slow traffic beside them: the merge must find gaps.
    beside = net.get_lane(net.index_of[road.siblings(first)[-2]])
    for s in np.arange(0.0, 600.0, 45.0):
        u.road.vehicles.append(
            MapIDMVehicle(u.road, beside.position(s, 0.0), beside.heading_at(s), 20.0)
        )
    worst = math.inf
    for _ in range(400):  # 40 s
        u.road.act()
        u.road.step(0.1)
        for v in u.road.vehicles:
            if road.successor(net.key_of[v.lane_index]) is None:
                worst = min(worst, net.lane_left(v.lane_index, v.position))
    assert not any(v.crashed for v in u.road.vehicles)
    assert worst > -0.5 * MapIDMVehicle.LENGTH
    assert all(road.chain_end(net.key_of[v.lane_index]) > 800.0 for v in merging)


def test_render_rgb_array_on_a_map(curved: Path) -> None:
    env = gym.make(
        "ALDMHighway-v0",
        config={"road": {"xodr": str(curved)}, "vehicles_count": 4},
        render_mode="rgb_array",
    )
    env.reset(seed=0)
    env.step(1)
    frame = env.render()
    assert frame is not None and frame.ndim == 3 and frame.std() > 0


# ---------------------------------------------------------------- speed paths
MAPS = Path(aldm_gym.__file__).parent / "roads" / "maps"
SHIPPED = ("motorway", "two_plus_one", "features", "bridges")


def _lane_table_args(lane: MapLane, points: np.ndarray) -> tuple:
    c = lane.reference
    return (
        c.lookup,
        lane._u,
        lane._w,
        lane._constant,
        1.0,
        -lane.VEHICLE_LENGTH,
        lane.length + lane.VEHICLE_LENGTH,
        points,
    )


@pytest.mark.parametrize("name", SHIPPED)
def test_lane_neighbour_table_matches_local_coordinates_and_on_lane(name: str) -> None:
    """The compiled table gives ``local_coordinates``' s and ``on_lane``'s mask."""
    road = OpenDriveRoad.from_file(MAPS / f"{name}.xodr")
    net = road.network
    rng = np.random.default_rng(0)
    varying = 0
    for index in net.key_of:
        lane = net.get_lane(index)
        varying += not lane._constant
        s = rng.uniform(-10.0, lane.length + 10.0, 40)
        r = rng.normal(0.0, 3.0, 40)
        near = np.array([lane.position(float(a), float(b)) for a, b in zip(s, r, strict=True)])
        points = np.vstack([near, rng.uniform(-3000.0, 3000.0, (10, 2)), [[np.nan, 0.0]]])
        s_ref = np.array([lane.local_coordinates(p)[0] for p in points[:-1]])
        r_ref = np.array([lane.local_coordinates(p)[1] for p in points[:-1]])
        on_ref = np.array(
            [
                lane.on_lane(p, a, b, margin=1.0)
                for p, a, b in zip(points[:-1], s_ref, r_ref, strict=True)
            ]
            + [False]
        )
        order_ref = np.flatnonzero(on_ref)[np.argsort(s_ref[on_ref[:-1]], kind="stable")]
        s_fast, on, order = lane.neighbour_table(points, 1.0)
        projected = ~np.isnan(s_fast)
        assert np.array_equal(s_fast[:-1][projected[:-1]], s_ref[projected[:-1]])
        assert not projected[-1] and projected[:40].all()
        assert np.array_equal(on, on_ref)
        assert np.array_equal(order, order_ref)
        args = _lane_table_args(lane, np.ascontiguousarray(points))
        for got, want in zip(_neighbour_table(*args), _neighbour_table_py(*args), strict=True):
            assert np.array_equal(got, want, equal_nan=True)
    assert name != "features" or varying > 0  # a width change is covered


def test_reference_line_from_points_is_the_centre_line() -> None:
    xy = np.column_stack([np.linspace(0.0, 300.0, 40), 20.0 * np.sin(np.linspace(0.0, 2.0, 40))])
    line = ReferenceLine.from_points(xy, 0.5, 15.0)
    centre = CentreLine(xy)
    assert type(line) is ReferenceLine and line.segments == ()
    for name in ("s", "xy", "heading", "kappa", "normal"):
        assert np.array_equal(getattr(line, name), getattr(centre, name))
    assert line.project(np.array([150.0, 3.0])) == centre.project(np.array([150.0, 3.0]))
    with pytest.raises(ValueError, match="positive length"):
        ReferenceLine.from_points(np.zeros((3, 2)))


def test_project_near_projects_only_within_reach() -> None:
    line = CentreLine(np.column_stack([np.linspace(0.0, 800.0, 50), np.zeros(50)]))
    points = np.array([[10.0, 2.0], [400.0, -9.0], [500.0, 300.0], [np.inf, 0.0], [790.0, 0.5]])
    s, d, near = line.project_near(points)
    assert near.tolist() == [True, True, False, False, True]
    for k in np.flatnonzero(near):
        assert (s[k], d[k]) == line.project(points[k])
    assert np.isnan(s[~near]).all() and np.isnan(d[~near]).all()
    args = (line.lookup, points)
    for got, want in zip(project_point_near(*args), project_point_near_py(*args), strict=True):
        assert np.array_equal(got, want, equal_nan=True)


@pytest.mark.parametrize("name", SHIPPED)
def test_prepared_closest_lanes_are_the_looked_up_ones(name: str) -> None:
    road = OpenDriveRoad.from_file(MAPS / f"{name}.xodr")
    net = MapNetwork(road)  # a fresh network: nothing prepared yet
    rng = np.random.default_rng(1)
    lanes = [net.get_lane(i) for i in net.key_of]
    poses = []
    for lane in lanes:
        for s in rng.uniform(0.0, lane.length, 3):
            x, y = lane.position(float(s), float(rng.normal(0.0, 2.0)))
            poses.append((x, y, float(lane.heading_at(float(s))) + float(rng.normal(0.0, 0.5))))
    poses.append((1e4, -1e4, 0.0))  # nothing within reach: every lane
    positions = np.array([p[:2] for p in poses])
    headings = np.array([p[2] for p in poses])
    fresh = [net.get_closest_lane_index(p, h) for p, h in zip(positions, headings, strict=True)]
    net.prepare_closest_lane_poses(positions, np.append(headings[:-1], np.nan))
    assert len(net._prepared) == len(poses) - 1  # the NaN heading is not remembered
    assert [
        net.get_closest_lane_index(p, h) for p, h in zip(positions, headings, strict=True)
    ] == fresh
    c = road._centres
    args = (
        c.chunk_mark,
        c.chunk_i0,
        c.chunk_i1,
        c.chunk_centre,
        c.chunk_radius,
        len(c.start) - 1,
        c.xy,
        net._seg_heading,
        positions,
        headings,
        1.0,
        15.0,
    )
    assert np.array_equal(_closest_lanes(*args), _closest_lanes_py(*args))


@pytest.mark.parametrize("connected", [False, True])
@pytest.mark.parametrize("name", ["motorway", "two_plus_one"])
def test_map_neighbours_match_highway_env(name: str, connected: bool) -> None:
    """FastRoad's neighbours on a map are highway-env's ``Road.neighbour_vehicles``."""
    env = gym.make(
        "ALDMHighway-v0",
        config={"road": {"xodr": str(MAPS / f"{name}.xodr")}, "vehicles_count": 25},
    )
    env.reset(seed=5)
    road = env.unwrapped.road
    checked = 0
    for _ in range(6):
        road.neighbour_vehicles_connected_lanes = connected
        road.invalidate()
        for v in road.vehicles:
            for index in [v.lane_index, *road.network.side_lanes(v.lane_index)]:
                fast = road.neighbour_vehicles(v, index)
                base = Road.neighbour_vehicles(road, v, index)
                assert fast[0] is base[0] and fast[1] is base[1]
                checked += 1
        env.step(1)
    assert checked > 100


def test_map_traffic_lane_updates_are_batched_and_never_reverse(curved: Path) -> None:
    """MapIDMVehicle's step is the base one (its lane look-up is batched by FastRoad)."""
    assert MapIDMVehicle.step in STEPS_ENDING_WITH_UPDATE
    env = _make(curved, vehicles_count=0)
    env.reset(seed=0)
    u = env.unwrapped
    lane = u.vehicle.lane
    v = MapIDMVehicle(u.road, lane.position(300.0, 0.0), lane.heading_at(300.0), 0.2)
    u.road.vehicles.append(v)
    v.action = {"steering": 0.0, "acceleration": -5.0}  # would reverse within the step
    u.road.step(0.1)
    assert v.speed == 0.0 and v.lane_index == u.road.network.get_closest_lane_index(
        v.position, v.heading
    )


# ------------------------------------------------------ closed loop, shipped maps
def _closed_loop(name: str, detector: str, seed: int, steps: int = 30) -> tuple[int, int]:
    """IDLE for ``steps`` policy steps (1 s each) without traffic: (departures, steps run)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # features.xodr: shorter than asked
        env = _make(
            MAPS / f"{name}.xodr",
            detector=detector,
            marking_model="per_dash",
            duration=float(steps) + 5.0,
        )
        env.reset(seed=seed)
    info: dict = {"departures": 0}
    run = 0
    while run < steps:
        _, _, terminated, truncated, info = env.step(1)
        run += 1
        if terminated or truncated:
            break
    return int(info["departures"]), run


@pytest.mark.parametrize(
    ("name", "seed"),
    [
        ("motorway", 0),
        ("motorway", 1),
        ("motorway", 4),  # passes the exit's gore in the lane next to the off-ramp
        ("two_plus_one", 0),
        ("two_plus_one", 1),
    ],
)
def test_aldm_keeps_its_lane_on_the_shipped_maps(name: str, seed: int) -> None:
    """ALDM, IDLE, per-dash objects: 30 s without a lane departure.

    Measured (seeds 0-7, no traffic, 35 s): no departure on either map in 8 of 8. Seed 4
    starts ~125 m before the exit split in the lane beside the off-ramp: the off-ramp's
    edges diverging through the start region used to tilt the common seed shape until
    the right ego line was taken for a left one (24 departures in 35 s).
    """
    assert _closed_loop(name, "aldm", seed) == (0, 30)


@pytest.mark.parametrize(("name", "seed"), [("motorway", 2), ("two_plus_one", 0)])
def test_naive_departs_on_the_shipped_maps(name: str, seed: int) -> None:
    """The naive detector on per-dash objects leaves its lane (5 of 8 seeds on both maps)."""
    departures, _ = _closed_loop(name, "naive", seed)
    assert departures >= 1


def test_features_map_aldm_keeps_its_lane_naive_departs() -> None:
    """features.xodr is 640 m long: an episode is truncated after ~16 s (the road ahead
    ends within 250 m), so the 30 s criterion cannot apply. Over those 16 s the ALDM
    keeps its lane (seeds 0-4), despite its known weak spots here (a broken edge line
    0.6 m inside a solid shoulder line, a double centre line); the naive detector
    steers across the centre line within the first second (then the oncoming lane's
    road ends ahead and the episode is truncated)."""
    departures, run = _closed_loop("features", "aldm", 0)
    assert departures == 0 and run >= 15
    departures, _ = _closed_loop("features", "naive", 0)
    assert departures >= 1


def test_a_map_searches_neighbours_across_connected_lanes(curved: Path) -> None:
    # A map's lanes end at every lane section: the leader on the next section is seen.
    env = _make(curved, neighbour_vehicles_connected_lanes=False)
    env.reset(seed=0)
    assert env.unwrapped.config["neighbour_vehicles_connected_lanes"] is True
    assert env.unwrapped.road.neighbour_vehicles_connected_lanes is True
    generated = gym.make("ALDMHighway-v0")
    generated.reset(seed=0)
    assert generated.unwrapped.road.neighbour_vehicles_connected_lanes is False
