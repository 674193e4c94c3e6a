"""The jerk-limited speed profile of ``SpeedProfileAction followingMode="follow"``
(:class:`aldm_gym.scenario.actions.JerkProfile`): continuous speeds, jerks and
accelerations within their limits, the final speed reached. Its agreement with esmini
is the corpus file ``jerk_limited_speed_profiles`` (tests/scenario/test_esmini.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aldm_gym.scenario.actions import JerkProfile

speeds = st.floats(0.0, 40.0)
times = st.floats(0.5, 12.0)
jerk = st.floats(0.5, 6.0)
limit = st.floats(1.0, 8.0)


def _sampled(plan: JerkProfile, until: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, until, 4001)
    return t, np.array([plan.speed(x) for x in t])


@settings(max_examples=200, deadline=None)
@given(speeds, speeds, times, jerk, jerk, limit, limit)
def test_two_speeds_are_joined_within_the_limits(
    v0: float, v1: float, span: float, rise: float, fall: float, acc: float, dec: float
) -> None:
    plan = JerkProfile.plan([(0.0, v0), (span, v1)], 0.0, (rise, fall), (acc, dec))
    if plan is None:
        return  # no plan: the linear profile plays (esmini finds no solution either)
    assert plan.final == pytest.approx(v1)
    assert plan.end >= span - 1e-6  # on time, or later where the limits do not allow it
    t, v = _sampled(plan, plan.end + 1.0)
    dt = t[1] - t[0]
    a = np.diff(v) / dt
    assert np.all(np.abs(np.diff(v)) <= (max(acc, dec) + 1e-3) * dt + 1e-6)  # continuous
    assert a.max() <= acc + 1e-2 and a.min() >= -dec - 1e-2
    jerks = np.diff(a) / dt
    assert jerks.max() <= rise + 0.5 and jerks.min() >= -fall - 0.5
    assert v[-1] == pytest.approx(v1, abs=1e-6)


def test_a_held_acceleration_arrives_on_time() -> None:
    """0 to 20 m/s in 10 s at 2 m/s³: the peak (J/2)·(T − √(T² − 4Δv/J)) held between
    two jerks of a_p/J each, arriving at 10 s."""
    plan = JerkProfile.plan([(0.0, 0.0), (10.0, 20.0)], 0.0, (2.0, 2.0), (5.0, 5.0))
    assert plan is not None
    peak = 1.0 * (10.0 - math.sqrt(100.0 - 40.0))
    assert [s[0] for s in plan.segments] == pytest.approx([0.0, peak / 2, 10 - peak / 2, 10.0])
    assert plan.segments[1][2] == pytest.approx(peak)
    assert plan.speed(5.0) == pytest.approx(10.0)


def test_corners_are_cut_by_the_jerks() -> None:
    """Through 0 -> 10 -> 10 -> 0 at 5 s each with 2 m/s³: a jerk centred on every
    corner, missing the vertex by Δk²/(8 j), ending half a jerk after the last."""
    vertices = [(0.0, 0.0), (5.0, 10.0), (10.0, 10.0), (15.0, 0.0)]
    plan = JerkProfile.plan(vertices, 0.0, (2.0, 2.0), (10.0, 10.0))
    assert plan is not None
    assert plan.end == pytest.approx(15.5)
    assert plan.final == 0.0
    # the first line is reached after a jerk of 1 s: it lags the nominal by k²/(2j)
    lag = 2.0**2 / (2 * 2.0)
    assert plan.speed(3.0) == pytest.approx(2.0 * 3.0 - lag)
