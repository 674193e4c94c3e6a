"""Rendering of ``ALDMHighway-v0``: the road as painted, highway-env's vehicles, the perception.

The frame, bottom to top, in highway-env's world coordinates:

* the road's own paint (:func:`aldm_gym.roads.paint.painted_pieces`): every dash where
  the road paints it, continuous lines along the curve, in the road's colours and
  widths, so the sensor's points sit on the drawn paint (highway-env's own lane lines,
  a straight chord per edge and generic 3 m stripes, are not drawn);
* highway-env's road objects and vehicles;
* bridges crossing overhead: their painted markings (the road's ``overpass_lines``) in
  :data:`BRIDGE_COLOUR`, over the vehicles passing beneath;
* the line sensor's points, one colour per line object (per-dash objects show as
  alternating colours along a dashed marking);
* the detected lines (ego lines thick, adjacent lines thin) in the detector's colour;
* the path the ego's controller follows (the trajectory, or the lane-change target);
* a legend and a scale bar.

How much road shows is set by the env's ``scaling`` [px/m], ``centering_position`` and
``screen_width``/``screen_height`` [px] (``docs/env.md``, "Rendering").

Imported lazily by :meth:`ALDMHighwayEnv.render`, so pygame is loaded only when
rendering. ``rgb_array`` works headless (SDL's dummy video driver).
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import numpy as np

from aldm_gym.envs.observation import sensor_to_world
from aldm_gym.roads.paint import PaintedPiece, painted_pieces
from aldm_gym.sensor.lane_detection import LINE_NAMES
from aldm_gym.types import FloatArray

os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

if TYPE_CHECKING:
    from aldm_gym.envs.highway import ALDMHighwayEnv

import pygame
from highway_env.envs.common.graphics import EnvViewer, ObservationGraphics
from highway_env.road.graphics import RoadGraphics, WorldSurface
from highway_env.vehicle.graphics import VehicleGraphics

Colour = tuple[int, int, int]

ASPHALT: Colour = (90, 90, 90)
"""Background of the frame [RGB]."""

WHITE: Colour = (255, 255, 255)

PAINT_COLOURS: dict[int, Colour] = {
    0: (255, 255, 255),  # white
    1: (240, 200, 0),  # yellow
    2: (170, 170, 180),  # barrier (guard rail of the generated road)
    3: (40, 90, 230),  # blue
    4: (40, 170, 60),  # green
    5: (220, 40, 40),  # red
    6: (240, 140, 0),  # orange
    7: (140, 60, 200),  # violet
    8: (20, 20, 20),  # black
}
"""Colour of the paint by the road's colour index [RGB] (``docs/roads.md``)."""

MIN_PAINT_PX = 2
"""Thinnest drawn paint [px]: real paint (0.15 m) is under a pixel at a wide view."""

OBJECT_COLOURS: list[Colour] = [
    (255, 225, 25),
    (70, 240, 240),
    (240, 50, 230),
    (245, 130, 48),
]
"""Colours cycled over the sensor's line objects [RGB]: none of them is a paint, line or
path colour."""

DETECTOR_COLOURS: dict[str, Colour] = {
    "naive": (230, 30, 30),
    "aldm": (30, 70, 255),
    "ground_truth": (0, 0, 0),
}
"""Colour of the detected lines by detector [RGB] (as in the comparison figures)."""

DETECTOR_NAMES = {"naive": "naive", "aldm": "ALDM", "ground_truth": "ground truth"}
"""The detectors' names in the legend."""

PATH_COLOUR: Colour = (0, 200, 0)
"""Colour of the planned path [RGB]."""

BRIDGE_COLOUR: Colour = (150, 160, 200)
"""Colour of the markings of a bridge overhead [RGB] (none of the paint colours)."""

SCALE_BAR = (200.0, 100.0, 50.0, 20.0, 10.0)
"""Lengths a scale bar may have [m]: the longest that fits a quarter of the width."""


def world_to_pixels(surface: WorldSurface, world: FloatArray) -> np.ndarray:
    """World points ``(N, 2)`` [m] to surface pixels ``(N, 2)`` [px], as ``pos2pix``
    (truncation towards zero) for every point at once."""
    return ((np.asarray(world) - surface.origin) * surface.scaling).astype(np.int64)


def view_radius(surface: WorldSurface) -> float:
    """Half the diagonal of the surface's window in the world [m]."""
    return 0.5 * math.hypot(surface.get_width(), surface.get_height()) / surface.scaling


def view_centre(surface: WorldSurface) -> FloatArray:
    """World position of the surface's centre [m]."""
    size = np.array([surface.get_width(), surface.get_height()], dtype=np.float64)
    return np.asarray(surface.origin, dtype=np.float64) + 0.5 * size / surface.scaling


def draw_bridges(surface: WorldSurface, lines: FloatArray) -> bool:
    """Draw the segments ``(x0, y0, x1, y1, z)`` [m] of bridge markings that reach into
    the window, :data:`BRIDGE_COLOUR`, 0.15 m wide (at least :data:`MIN_PAINT_PX`).

    :return: whether any was drawn.
    """
    if len(lines) == 0:
        return False
    centre, radius = view_centre(surface), view_radius(surface)
    a, b = lines[:, 0:2], lines[:, 2:4]
    # Distance from the window's centre to each segment.
    d = b - a
    t = np.clip(
        np.einsum("ij,ij->i", centre - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-12),
        0.0,
        1.0,
    )
    near = np.hypot(*(a + t[:, None] * d - centre).T) <= radius
    if not near.any():
        return False
    width = max(MIN_PAINT_PX, round(0.15 * surface.scaling))
    pa, pb = world_to_pixels(surface, a[near]), world_to_pixels(surface, b[near])
    for p, q in zip(pa.tolist(), pb.tolist(), strict=True):
        pygame.draw.line(surface, BRIDGE_COLOUR, p, q, width)
    return True


def draw_paint(surface: WorldSurface, pieces: list[PaintedPiece]) -> None:
    """Draw painted pieces as polylines of their own colour and width (at least
    :data:`MIN_PAINT_PX`)."""
    for p in pieces:
        colour = PAINT_COLOURS.get(p.colour, PAINT_COLOURS[0])
        width = max(MIN_PAINT_PX, round(p.width * surface.scaling))
        pix = world_to_pixels(surface, p.xy)
        pygame.draw.lines(surface, colour, False, pix.tolist(), width)


class ALDMViewer(EnvViewer):
    """highway-env's ``EnvViewer`` drawing the road as painted and the perception overlay."""

    def __init__(self, env: ALDMHighwayEnv) -> None:
        if env.render_mode == "rgb_array":
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        super().__init__(env)
        # highway-env disables its viewer under SDL's dummy driver; offscreen drawing
        # needs no display, so rgb_array stays enabled headless.
        if self.offscreen:
            self.enabled = True
        # Text is rendered once (pygame fonts die with the viewer's pygame.quit()).
        self._legend: tuple[tuple[str, bool], pygame.Surface] | None = None
        self._bridges_shown = False
        self._scale_labels: dict[float, pygame.Surface] = {}

    def display(self) -> None:
        """Draw paint, road objects and vehicles (highway-env's), the overlay, the legend."""
        if not self.enabled:
            return
        surface = self.sim_surface
        surface.move_display_window_to(self.window_position())
        self.draw_road(surface)
        if self.vehicle_trajectory:
            VehicleGraphics.display_trajectory(
                self.vehicle_trajectory, surface, offscreen=self.offscreen
            )
        RoadGraphics.display_road_objects(self.env.road, surface, offscreen=self.offscreen)
        RoadGraphics.display_traffic(
            self.env.road,
            surface,
            simulation_frequency=self.env.settings.simulation_frequency,
            offscreen=self.offscreen,
        )
        ObservationGraphics.display(self.env.observation_type, surface)
        road = self.env.highway
        bridges = getattr(road, "overpass_lines", None)
        self._bridges_shown = bridges is not None and draw_bridges(surface, bridges)
        self.draw_overlay(surface)
        self.draw_legend(surface)
        if not self.offscreen:
            self.screen.blit(surface, (0, 0))
            if self.env.settings.real_time_rendering:
                self.clock.tick(self.env.settings.simulation_frequency)
            pygame.display.flip()

    def draw_road(self, surface: WorldSurface) -> None:
        """Asphalt and the road's paint within the window."""
        surface.fill(ASPHALT)
        road = self.env.highway
        if road is not None:
            draw_paint(surface, painted_pieces(road, view_centre(surface), view_radius(surface)))

    def draw_overlay(self, surface: WorldSurface) -> None:
        """Sensor points per object, detected lines and the planned path."""
        env = self.env
        frame = env.frame
        if frame is None:
            return
        origin, yaw = frame.origin, frame.yaw
        colour = DETECTOR_COLOURS.get(env.settings.detector, DETECTOR_COLOURS["aldm"])
        det = env.detection
        if det is not None:
            for name in LINE_NAMES:
                line = det.line(name)
                if len(line) >= 2:
                    width = 3 if name.startswith("ego") else 1
                    world = sensor_to_world(line, origin, yaw)
                    pygame.draw.lines(
                        surface, colour, False, world_to_pixels(surface, world).tolist(), width
                    )
        # Dots smaller than the spacing of the points (1 m), so the paint shows between.
        radius = max(1, surface.pix(0.2))
        # Every point to pixels at once, then one colour per object.
        pix = world_to_pixels(surface, sensor_to_world(frame.all_points[:, :2], origin, yaw))
        starts = frame.line_start.tolist()
        for n in range(frame.n_lines):
            dot = OBJECT_COLOURS[n % len(OBJECT_COLOURS)]
            for p in pix[starts[n] : starts[n + 1]].tolist():
                pygame.draw.circle(surface, dot, p, radius)
        path = getattr(env.vehicle, "planned_path", None)
        if path is not None and len(path) >= 2:
            world = sensor_to_world(path, origin, yaw)
            pygame.draw.lines(
                surface, PATH_COLOUR, False, world_to_pixels(surface, world).tolist(), 2
            )

    def draw_legend(self, surface: WorldSurface) -> None:
        """The legend (top left) and a scale bar (bottom left)."""
        key = (str(self.env.settings.detector), self._bridges_shown)
        if self._legend is None or self._legend[0] != key:
            self._legend = (key, _legend_surface(*key))
        surface.blit(self._legend[1], (6, 6))
        length = next(
            (m for m in SCALE_BAR if m * surface.scaling <= 0.25 * surface.get_width()),
            SCALE_BAR[-1],
        )
        if length not in self._scale_labels:
            self._scale_labels[length] = _font(18).render(f"{length:.0f} m", True, WHITE)
        _draw_scale_bar(surface, length, self._scale_labels[length])


def _font(size: int) -> pygame.font.Font:
    if not pygame.font.get_init():
        pygame.font.init()
    return pygame.font.Font(None, size)


def _legend_surface(detector: str, bridges: bool = False) -> pygame.Surface:
    """The legend box: sensor points, the detector's lines, planned path, paint, and
    with ``bridges`` the markings of a bridge overhead."""
    font = _font(16)
    colour = DETECTOR_COLOURS.get(detector, DETECTOR_COLOURS["aldm"])
    name = DETECTOR_NAMES.get(detector, detector)
    rows = [
        ("points", "sensor points (colour per line object)"),
        ("line", f"{name} lines (ego thick, adjacent thin)"),
        ("path", "planned path"),
        ("paint", "road paint"),
    ]
    if bridges:
        rows.append(("bridge", "bridge overhead (its markings)"))
    height = 14 * len(rows) + 8
    width = 8 + 34 + max(font.size(text)[0] for _, text in rows) + 8
    box = pygame.Surface((width, height), pygame.SRCALPHA)
    box.fill((255, 255, 255, 210))
    for k, (kind, text) in enumerate(rows):
        y = 4 + 14 * k + 7
        if kind == "points":
            for i, c in enumerate(OBJECT_COLOURS[:3]):
                pygame.draw.circle(box, c, (12 + 10 * i, y), 3)
        elif kind == "line":
            pygame.draw.line(box, colour, (8, y), (36, y), 3)
        elif kind == "path":
            pygame.draw.line(box, PATH_COLOUR, (8, y), (36, y), 2)
        elif kind == "bridge":
            pygame.draw.line(box, BRIDGE_COLOUR, (8, y), (36, y), 2)
        else:
            pygame.draw.rect(box, ASPHALT, (6, y - 5, 32, 10))
            pygame.draw.line(box, PAINT_COLOURS[0], (10, y), (18, y), 2)
            pygame.draw.line(box, PAINT_COLOURS[0], (26, y), (34, y), 2)
        label = font.render(text, True, (0, 0, 0))
        box.blit(label, (44, y - label.get_height() // 2))
    return box


def _draw_scale_bar(surface: WorldSurface, length: float, label: pygame.Surface) -> None:
    """A bar of ``length`` [m] at the bottom left, with its label."""
    px = int(length * surface.scaling)
    x0, y0 = 10, surface.get_height() - 12
    pygame.draw.line(surface, WHITE, (x0, y0), (x0 + px, y0), 2)
    for x in (x0, x0 + px):
        pygame.draw.line(surface, WHITE, (x, y0 - 4), (x, y0 + 4), 2)
    surface.blit(label, (x0 + px + 6, y0 - label.get_height() // 2))
