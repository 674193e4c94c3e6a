"""A function under test written against ``aldm_gym.function``'s interface.

Two controllers, each taking one domain (the env's built-in function keeps the other):

* :class:`PurePursuitLKA` (lateral): pure pursuit on the centre of the perceived ego
  lane. It sees the perceived lines only, never the road: where the detector loses a
  line, it follows the other one at half a lane width; where it loses both, it holds
  its last curvature for a second, then steers straight.
* :class:`TimeGapACC` (longitudinal): a constant time-gap law on the nearest object
  ahead in the perceived ego lane, with a comfortable set speed.

:class:`LaneCenteringChauffeur` takes both. Try them on the OSC-ALKS cut-in::

    aldm-gym scenario run cut_in.xosc --function examples/lane_centering.py:PurePursuitLKA
    aldm-gym scenario run cut_in.xosc \\
        --function examples/lane_centering.py:LaneCenteringChauffeur --env sensor.preset=camera
"""

from __future__ import annotations

import math

import numpy as np

from aldm_gym.function import FunctionInput, FunctionOutput

LANE_WIDTH = 3.5
"""The lane width the LKA assumes where it sees only one line [m]."""


def _centre(inputs: FunctionInput) -> np.ndarray | None:
    """``(c0, c1, c2, c3)`` of the ego lane's centre line ``y(x)`` in the sensor frame,
    from both ego lines, or one of them shifted by half a lane; None without either."""
    left, right = inputs.line("ego_left"), inputs.line("ego_right")
    if left.found and right.found:
        return 0.5 * (left.cubic() + right.cubic())
    if left.found:
        c = left.cubic()
        c[0] -= 0.5 * LANE_WIDTH
        return c
    if right.found:
        c = right.cubic()
        c[0] += 0.5 * LANE_WIDTH
        return c
    return None


class PurePursuitLKA:
    """Pure pursuit on the perceived lane centre (lateral domain).

    :param lookahead_time: look-ahead distance per unit speed [s].
    :param min_lookahead: shortest look-ahead [m].
    :param hold_time: how long the last curvature is held without any line [s].
    """

    domains = frozenset({"lateral"})

    def __init__(
        self, lookahead_time: float = 1.0, min_lookahead: float = 12.0, hold_time: float = 1.0
    ) -> None:
        self.lookahead_time = lookahead_time
        self.min_lookahead = min_lookahead
        self.hold_time = hold_time
        self._curvature = 0.0
        self._blind = 0.0

    def reset(self) -> None:
        """Steer straight at the start of an episode."""
        self._curvature = 0.0
        self._blind = 0.0

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        """The curvature of the arc through the look-ahead point on the lane centre."""
        centre = _centre(inputs)
        if centre is None:
            self._blind += inputs.step
            if self._blind > self.hold_time:
                self._curvature = 0.0
            return FunctionOutput(curvature=self._curvature)
        self._blind = 0.0
        x = max(self.min_lookahead, self.lookahead_time * inputs.ego.speed)
        y = float(np.polynomial.polynomial.polyval(x, centre))
        self._curvature = 2.0 * y / (x * x + y * y)
        return FunctionOutput(curvature=self._curvature)


class TimeGapACC:
    """A constant time-gap ACC on the nearest object in the perceived ego lane
    (longitudinal domain).

    :param set_speed: the speed held with nothing ahead [m/s].
    :param time_gap: the time gap kept behind the object ahead [s].
    :param standstill: the gap kept at standstill [m].
    """

    domains = frozenset({"longitudinal"})

    def __init__(
        self, set_speed: float = 16.7, time_gap: float = 1.8, standstill: float = 4.0
    ) -> None:
        self.set_speed = set_speed
        self.time_gap = time_gap
        self.standstill = standstill

    def reset(self) -> None:
        """Nothing to forget."""

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        """Speed control, or gap control behind the object ahead, whichever is lower."""
        v = inputs.ego.speed
        accel = 0.5 * (self.set_speed - v)
        centre = _centre(inputs)
        for obj in inputs.objects:
            if obj.x <= 0.0:
                continue
            poly = np.polynomial.polynomial
            lane_y = 0.0 if centre is None else float(poly.polyval(obj.x, centre))
            if abs(obj.y - lane_y) > 0.5 * (LANE_WIDTH + obj.width):
                continue  # not in the ego lane
            gap = obj.x - 0.5 * obj.length - 2.0  # the sensor sits about 2 m behind the front
            wanted = self.standstill + self.time_gap * v
            accel = min(accel, 0.25 * (gap - wanted) + 0.6 * obj.vx)
        return FunctionOutput(acceleration=float(np.clip(accel, -9.0, 2.0)))


class LaneCenteringChauffeur:
    """:class:`PurePursuitLKA` and :class:`TimeGapACC` together (both domains)."""

    domains = frozenset({"lateral", "longitudinal"})

    def __init__(self) -> None:
        self.lka = PurePursuitLKA()
        self.acc = TimeGapACC()

    def reset(self) -> None:
        """Reset both."""
        self.lka.reset()
        self.acc.reset()

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        """The LKA's curvature and the ACC's acceleration."""
        lateral, longitudinal = self.lka.step(inputs), self.acc.step(inputs)
        return FunctionOutput(curvature=lateral.curvature, acceleration=longitudinal.acceleration)


if __name__ == "__main__":
    import gymnasium as gym

    import aldm_gym  # noqa: F401  (registers ALDMHighway-v0)
    from aldm_gym.function import FunctionDriver

    # a function that steers is stepped as often as the simulation (10 Hz)
    env = gym.make("ALDMHighway-v0", config={"policy_frequency": 10})
    driver = FunctionDriver(env, LaneCenteringChauffeur())
    driver.reset(seed=0)
    steps = departures = 0
    while True:
        _, _, terminated, truncated, info = driver.step()
        steps += 1
        departures += int(info["lane_departure"])
        if terminated or truncated:
            break
    print(f"{steps} steps, {departures} departures, crashed: {info['crashed']}")
    assert math.isfinite(info["speed"])
