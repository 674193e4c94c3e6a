"""The render draws the road as painted: the sensor's points sit on the drawn paint."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aldm_gym  # registers the env
from aldm_gym.roads import HighwayRoad, OpenDriveRoad
from aldm_gym.roads.paint import painted_pieces

MOTORWAY = Path(aldm_gym.__file__).parent / "roads" / "maps" / "motorway.xodr"
CURVE = {"road": {"segments": ((3000.0, -1.0 / 500.0, -1.0 / 500.0),)}}
"""A generated road that is one right curve of R 500 m."""


def _length(xy: np.ndarray) -> float:
    return float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))


def test_generated_pieces_are_the_dash_pattern() -> None:
    road = HighwayRoad({"segments": ((1000.0, 1.0 / 400.0, 1.0 / 400.0),)})
    around = road.reference.position(500.0)
    pieces = painted_pieces(road, around, 60.0)
    lane_line = [p for p in pieces if p.marking == 1]
    edge = [p for p in pieces if p.marking == 0]
    # Dashes of 6 m along the marking's own arc length, 18 m apart; inner ones whole.
    inner = [p for p in lane_line if abs(_length(p.xy) - 6.0) < 0.05]
    assert len(inner) >= len(lane_line) - 2 >= 5
    starts = np.array(
        [road.marking_arc_length(1, road.reference.project(p.xy[0])[0]) for p in inner]
    )
    assert np.allclose(np.diff(np.sort(starts)), 18.0, atol=0.05)
    # The edge line is one continuous run that follows the curve (not a chord).
    assert len(edge) == 1 and _length(edge[0].xy) > 120.0
    s = np.array([road.reference.project(p)[0] for p in edge[0].xy[::25]])
    d = np.hypot(*(road.marking_position(0, s) - edge[0].xy[::25]).T)
    assert d.max() < 0.01
    assert edge[0].width == pytest.approx(0.30) and lane_line[0].width == pytest.approx(0.15)


def test_map_pieces_are_the_painted_intervals() -> None:
    road = OpenDriveRoad.from_file(MOTORWAY)
    x, y, _ = road.lane_pose("3", -2, 120.0)
    pieces = painted_pieces(road, np.array([x, y]), 80.0)
    dashes = [p for p in pieces if p.type == 2]
    solid = [p for p in pieces if p.type == 1]
    assert dashes and solid
    whole = [_length(p.xy) for p in dashes if abs(_length(p.xy) - 6.0) < 0.05]
    assert len(whole) >= len(dashes) - 4


@pytest.mark.parametrize("bad", [math.nan, 0.0, -1.0])
def test_painted_pieces_rejects_a_bad_radius(bad: float) -> None:
    with pytest.raises(ValueError, match="radius"):
        painted_pieces(HighwayRoad({"length": 500.0}), np.zeros(2), bad)


def _curved_env(config: dict, seeds: range) -> gym.Env:
    """An env reset on the seed whose ego is in the sharpest curve."""
    env = gym.make("ALDMHighway-v0", config=config, render_mode="rgb_array")
    best = (-1.0, 0)
    for seed in seeds:
        env.reset(seed=seed)
        u = env.unwrapped
        s = u.lane_position.s
        hw = u.highway
        if isinstance(hw, HighwayRoad):
            kappa = abs(float(hw.curvature_at(s)))
        else:
            lane = u.vehicle.lane
            kappa = abs(
                float(lane.reference.curvature_at(lane.local_coordinates(u.vehicle.position)[0]))
            )
        best = max(best, (kappa, seed))
    env.reset(seed=best[1])
    assert best[0] > 1.0 / 1500.0, "no pose in a curve"
    return env


def _on_paint(env: gym.Env, shift: float = 0.0) -> float:
    """Share of the frame's sensor points (within the window) on drawn paint, after the
    points are shifted ``shift`` [m] to the sensor's left."""
    import pygame

    from aldm_gym.envs.rendering import PAINT_COLOURS, sensor_to_world, world_to_pixels

    env.step(1)
    env.render()
    u = env.unwrapped
    viewer = u.viewer
    surface = viewer.sim_surface
    viewer.draw_road(surface)  # the paint alone, same window as the frame
    img = pygame.surfarray.array3d(surface)  # (W, H, 3)
    frame = u.frame
    pts = frame.all_points[:, :2] + np.array([0.0, shift])
    pix = world_to_pixels(surface, sensor_to_world(pts, frame.origin, frame.yaw))
    w, h = surface.get_width(), surface.get_height()
    inside = (pix[:, 0] >= 1) & (pix[:, 0] < w - 1) & (pix[:, 1] >= 1) & (pix[:, 1] < h - 1)
    pix = pix[inside]
    assert len(pix) > 50
    white = np.array(PAINT_COLOURS[0])
    hits = 0
    for px, py in pix:
        # A point is on the paint if a pixel of its 3x3 neighbourhood is (rounding).
        patch = img[px - 1 : px + 2, py - 1 : py + 2].reshape(-1, 3)
        hits += bool(np.any(np.all(patch == white, axis=1)))
    return hits / len(pix)


@pytest.mark.parametrize(
    ("config", "seeds"),
    [
        (CURVE, range(1)),
        ({"road": {"xodr": str(MOTORWAY)}}, range(6)),
    ],
    ids=["generated", "motorway.xodr"],
)
def test_sensor_points_sit_on_the_drawn_paint_in_a_curve(config: dict, seeds: range) -> None:
    env = _curved_env({**config, "scaling": 6.0, "vehicles_count": 3}, seeds)
    try:
        assert _on_paint(env) > 0.95
        # Sensitivity: the same points 1 m to the side are off the paint.
        assert _on_paint(env, shift=1.0) < 0.2
    finally:
        env.close()


def test_frame_has_a_legend_and_is_drawn_at_a_range_view() -> None:
    env = gym.make(
        "ALDMHighway-v0",
        config={"scaling": 3.0, "centering_position": [0.12, 0.5], "vehicles_count": 3},
        render_mode="rgb_array",
    )
    try:
        env.reset(seed=0)
        img = env.render()
        assert img.shape == (300, 800, 3)
        # The legend box (light, top left) and the paint 200 m ahead of the ego.
        assert np.median(img[10:20, 10:200]) > 200
        u = env.unwrapped
        surface = u.viewer.sim_surface
        ahead = u.vehicle.position + 200.0 * np.array(
            [math.cos(u.vehicle.heading), math.sin(u.vehicle.heading)]
        )
        assert surface.is_visible(ahead, margin=0)
    finally:
        env.close()


# ----------------------------------------------------------------- figures


def test_bar_labels_are_percentages_and_zero_reads_zero() -> None:
    from aldm_gym.sensor.frame_plot import percent

    assert [percent(v) for v in (0.0, 0.004, 0.145, 1.0)] == ["0", "<1", "14", "100"]


def test_demo_frame_is_where_naive_errs_most() -> None:
    from aldm_gym.cli.compare import worst_naive_frame
    from aldm_gym.sensor import LineSensor, score_detection
    from aldm_gym.sensor.detectors import make_detector

    road = HighwayRoad({"seed": 0})
    frame, lane, error = worst_naive_frame(road, LineSensor(), 40, seed=0)
    assert error > 3.0  # at least a lane width: naive follows another marking
    per_dash = road.with_marking_model("per_dash")
    sc = score_detection(make_detector("naive")(frame, per_dash, lane), per_dash, frame, lane)
    assert not (sc["ego_left"].correct and sc["ego_right"].correct)


def test_offset_figure_marks_a_collision(tmp_path: Path) -> None:
    from argparse import Namespace

    from aldm_gym.agents.figures import plot_offsets
    from aldm_gym.cli.compare import _crashed

    full = [(25.0 * k, 0.01 * k) for k in range(40)]
    traces = {
        ("per_dash", "naive"): full[:12],
        ("per_dash", "aldm"): full,
        ("editor", "naive"): full,
        ("editor", "aldm"): full,
    }
    crashed = _crashed(traces, Namespace(xodr=None))
    assert crashed == {
        ("per_dash", "naive"): True,
        ("per_dash", "aldm"): False,
        ("editor", "naive"): False,
        ("editor", "aldm"): False,
    }
    assert _crashed(traces, Namespace(xodr="map.xodr")) == {}
    plot_offsets(traces, tmp_path / "offset.png", crashed=crashed)
    assert (tmp_path / "offset.png").stat().st_size > 10_000


def test_offset_figure_survives_an_episode_that_leaves_the_map(tmp_path: Path) -> None:
    """An episode that leaves a map ends in an infinite offset: the figure is still
    written, with one symmetric range from the finite offsets that keeps the lane
    edges (±1.875 m) inside."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from aldm_gym.agents.figures import plot_offsets

    traces = {
        ("editor", "naive"): [(0.0, -math.inf)],
        ("editor", "aldm"): [(0.0, 0.0), (25.0, 2.9)],
        ("per_dash", "aldm"): [(0.0, 0.1), (25.0, -0.2)],
    }
    seen: list[tuple[float, float]] = []
    real_savefig = plt.Figure.savefig

    def savefig(fig: plt.Figure, *args: object, **kwargs: object) -> None:
        seen.extend(ax.get_ylim() for ax in fig.axes)
        real_savefig(fig, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plt.Figure, "savefig", savefig)
        plot_offsets(traces, tmp_path / "offset.png")
    assert (tmp_path / "offset.png").stat().st_size > 10_000
    assert seen == [(-2.9 * 1.1, 2.9 * 1.1)] * 2


def test_frame_panels_are_as_wide_as_their_lines(tmp_path: Path) -> None:
    """The frame figure's lateral range follows the drawn lines (2 m beyond them, at
    least ±15 m, at most ±30 m), the same for every panel; points alone (a bridge's, a
    far road's) do not widen it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from aldm_gym.sensor import LineSensor, detect_lanes
    from aldm_gym.sensor.frame_plot import plot_frames
    from aldm_gym.sensor.lane_detection import LaneDetection

    road = HighwayRoad({"seed": 0, "min_radius": 500.0})
    x, y = road.reference.position(1000.0, road.lane_offset(1))
    heading = float(road.reference.heading_at(1000.0))
    frame = LineSensor().measure(road, (float(x), float(y), heading))
    wide = LaneDetection(ego_left=np.array([[0.0, 1.8], [150.0, 24.3]]))
    for panels, half in (
        ({"none": (frame, None)}, 15.0),
        ({"wide": (frame, wide), "none": (frame, None)}, 27.0),
    ):
        fig = plot_frames(panels, None)
        assert [ax.get_xlim() for ax in fig.axes] == [(half, -half)] * len(panels)
        plt.close(fig)
    det = detect_lanes(frame)
    widest = max(float(np.max(np.abs(det.line(n)[:, 1]))) for n in ("ego_left", "ego_right"))
    fig = plot_frames({"ALDM": (frame, det)}, None)
    assert fig.axes[0].get_xlim()[0] >= min(max(15.0, widest + 2.0), 30.0)
    plt.close(fig)
