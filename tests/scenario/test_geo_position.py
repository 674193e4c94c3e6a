"""``GeoPosition``: latitude and longitude put into the map through its
``<geoReference>`` and header ``<offset>``."""

from __future__ import annotations

import math
from pathlib import Path

import pyproj
import pytest
from scenariogeneration import xosc

from aldm_gym.errors import ScenarioError
from aldm_gym.roads.map_road import load_map
from aldm_gym.scenario import read_scenario
from tests.scenario._build import at_time, play, straight_road, with_geo_reference, write

PROJ = "+proj=tmerc +lat_0=57.7 +lon_0=11.9 +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"


def _georeferenced(folder: Path, offset: tuple[float, float, float] | None) -> Path:
    """The tests' straight road with a ``<geoReference>`` and an ``<offset>``."""
    return with_geo_reference(straight_road(folder), folder / "geo.xodr", PROJ, offset)


def _lat_lon(x: float, y: float, offset: tuple[float, float, float]) -> tuple[float, float]:
    """WGS 84 latitude and longitude [deg] of the map's inertial point ``(x, y)``: the
    header's offset applied (``R(hdg) p + (x, y)``), then the projection inverted."""
    ox, oy, hdg = offset
    east = math.cos(hdg) * x - math.sin(hdg) * y + ox
    north = math.sin(hdg) * x + math.cos(hdg) * y + oy
    to_geo = pyproj.Transformer.from_crs(PROJ, "EPSG:4326", always_xy=True)
    lon, lat = to_geo.transform(east, north)
    return lat, lon


def _teleported_to(folder: Path, road: Path, position: str) -> Path:
    """The target teleported to ``position`` (a ``<Position>``'s child) at 1 s: a
    teleport to a placeholder world position, which the text then replaces."""
    ev = xosc.Event("jump", xosc.Priority.override)
    ev.add_action("jump", xosc.TeleportAction(xosc.WorldPosition(-7.0, -7.0)))
    ev.add_trigger(at_time(1.0))
    path = write(folder, [("Target", [ev])], road=road, name="geo.xosc", stop=3.0)
    text = path.read_text()
    start = text.index('<WorldPosition x="-7.0" y="-7.0"')
    end = text.index("/>", start) + 2
    path.write_text(text[:start] + position + text[end:])
    return path


def test_the_header_keeps_its_geo_reference_and_offset(tmp_path: Path) -> None:
    header = load_map(_georeferenced(tmp_path, (12.5, -3.0, 0.2))).header
    assert header.geo_reference == PROJ
    assert header.offset == (12.5, -3.0, 0.0, 0.2)


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (250.0, -40.0, 0.3)])
def test_a_geo_position_lands_on_its_inertial_point(
    tmp_path: Path, offset: tuple[float, float, float]
) -> None:
    road = _georeferenced(tmp_path, offset)
    lat, lon = _lat_lon(300.0, -5.25, offset)  # lane -2's centre, 300 m along
    position = f'<GeoPosition latitudeDeg="{lat!r}" longitudeDeg="{lon!r}"/>'
    env, rec = play(_teleported_to(tmp_path, road, position), 2.0)
    target = env.scenario.world.entities["Target"]
    lane_id, s, t_offset, _speed = rec[-1]["Target"]
    # the teleport starts at 1.1 s and puts the target there at 1.2 s (as every
    # teleport from the storyboard); it then drives 0.8 s at 20 m/s along its lane
    assert lane_id == -2
    assert s == pytest.approx(300.0 + 20.0 * 0.8, abs=1e-3)
    assert t_offset == pytest.approx(0.0, abs=1e-3)
    assert target.heading == pytest.approx(0.0, abs=1e-9)  # no orientation: heading 0


def test_a_geo_position_in_radians_and_with_a_relative_heading(tmp_path: Path) -> None:
    """1.0's ``latitude``/``longitude`` are radians; an orientation relative to the
    lane turns the entity from its lane's direction."""
    road = _georeferenced(tmp_path, None)
    lat, lon = _lat_lon(300.0, -5.25, (0.0, 0.0, 0.0))
    position = (
        f'<GeoPosition latitude="{math.radians(lat)!r}" longitude="{math.radians(lon)!r}">'
        '<Orientation type="relative" h="0.1"/></GeoPosition>'
    )
    env, _ = play(_teleported_to(tmp_path, road, position), 1.2)
    target = env.scenario.world.entities["Target"]
    assert target.reference_point()[0] == pytest.approx(300.0, abs=1e-3)  # there at 1.2 s
    # OpenDRIVE's +0.1 rad (to the left) is -0.1 in highway-env's frame (y down)
    assert target.heading == pytest.approx(-0.1, abs=1e-6)


def test_a_geo_position_needs_a_georeferenced_map(tmp_path: Path) -> None:
    position = '<GeoPosition latitudeDeg="57.7" longitudeDeg="11.9"/>'
    path = _teleported_to(tmp_path, straight_road(tmp_path), position)
    with pytest.raises(ScenarioError, match=r"needs the map's <geoReference>.*has none"):
        play(path, 2.0)


def test_a_geo_position_out_of_range_is_refused_when_read(tmp_path: Path) -> None:
    road = _georeferenced(tmp_path, None)
    position = '<GeoPosition latitudeDeg="91" longitudeDeg="11.9"/>'
    with pytest.raises(ScenarioError, match=r"GeoPosition.*must lie within"):
        read_scenario(_teleported_to(tmp_path, road, position))


def test_a_geo_reference_that_is_not_a_projection_is_a_clear_error() -> None:
    from aldm_gym.scenario.positions import _projection

    with pytest.raises(ScenarioError, match=r"x\.xosc:3: .*'garbage' is not a projection"):
        _projection("garbage", "x.xosc:3")
    for proj in ("+proj=longlat +datum=WGS84", "+proj=utm +zone=32 +ellps=GRS80 +units=us-ft"):
        with pytest.raises(ScenarioError, match=r"not a projected coordinate system in metres"):
            _projection(proj, "x.xosc:3")
