"""Rendering of ``ALDMHighway-v0``: highway-env's viewer plus a perception overlay.

On top of highway-env's road and vehicles it draws, in world coordinates:

* the line sensor's points, one colour per line object (so per-dash objects show as
  alternating colours along a dashed marking);
* the detected lines (left adjacent, ego left, ego right, right adjacent);
* the path the ego's controller follows (the trajectory, or the lane-change target).

Imported lazily by :meth:`ALDMHighwayEnv.render`, so pygame is loaded only when
rendering. ``rgb_array`` works headless (SDL's dummy video driver).
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import numpy as np

from aldm_gym.sensor.detection import LINE_NAMES
from aldm_gym.types import FloatArray

os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

if TYPE_CHECKING:
    from aldm_gym.envs.highway import ALDMHighwayEnv

import pygame
from highway_env.envs.common.graphics import EnvViewer

OBJECT_COLOURS = [
    (230, 25, 75),
    (60, 180, 75),
    (255, 225, 25),
    (0, 130, 200),
    (245, 130, 48),
    (145, 30, 180),
    (70, 240, 240),
    (240, 50, 230),
]
"""Colours cycled over line objects [RGB]."""

LINE_COLOURS = {
    "left_adjacent": (120, 120, 255),
    "ego_left": (0, 0, 200),
    "ego_right": (0, 0, 200),
    "right_adjacent": (120, 120, 255),
}
"""Colour of each detected line [RGB]."""

PATH_COLOUR = (255, 140, 0)
"""Colour of the planned path [RGB]."""


def sensor_to_world(points: FloatArray, origin: FloatArray, yaw: float) -> FloatArray:
    """Sensor-frame points ``(N, 2)`` (x forward, y left) to world ``(N, 2)`` [m].

    The driver's left in highway-env's world is ``(sin h, -cos h)`` (see
    :mod:`aldm_gym.roads.geometry`).
    """
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = points[:, 0], points[:, 1]
    return np.column_stack([origin[0] + x * c + y * s, origin[1] + x * s - y * c])


class ALDMViewer(EnvViewer):
    """highway-env's ``EnvViewer`` that draws the perception overlay after the scene."""

    def __init__(self, env: ALDMHighwayEnv) -> None:
        if env.render_mode == "rgb_array":
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        super().__init__(env)
        # highway-env disables its viewer under SDL's dummy driver; offscreen drawing
        # needs no display, so rgb_array stays enabled headless.
        if self.offscreen:
            self.enabled = True

    def display(self) -> None:
        """Draw road, vehicles (highway-env) and the overlay."""
        super().display()
        if not self.enabled:
            return
        self.draw_overlay(self.sim_surface)
        if not self.offscreen:
            self.screen.blit(self.sim_surface, (0, 0))
            pygame.display.flip()

    def draw_overlay(self, surface: pygame.Surface) -> None:
        """Sensor points per object, detected lines and the planned path."""
        env = self.env
        frame = env.frame
        if frame is None:
            return
        origin, yaw = frame.origin, frame.yaw
        radius = max(1, surface.pix(0.35))
        for n in range(frame.n_lines):
            pts = frame.line_points(n)
            if len(pts) == 0:
                continue
            colour = OBJECT_COLOURS[n % len(OBJECT_COLOURS)]
            for px, py in sensor_to_world(pts[:, :2], origin, yaw):
                pygame.draw.circle(surface, colour, surface.pos2pix(px, py), radius)
        det = env.detection
        if det is not None:
            for name in LINE_NAMES:
                line = det.line(name)
                if len(line) >= 2:
                    self._polyline(
                        surface, sensor_to_world(line, origin, yaw), LINE_COLOURS[name], 2
                    )
        path = getattr(env.vehicle, "planned_path", None)
        if path is not None and len(path) >= 2:
            self._polyline(surface, sensor_to_world(path, origin, yaw), PATH_COLOUR, 3)

    @staticmethod
    def _polyline(
        surface: pygame.Surface, world: FloatArray, colour: tuple[int, int, int], width: int
    ) -> None:
        pix = [surface.pos2pix(x, y) for x, y in world]
        pygame.draw.lines(surface, colour, False, pix, width)
