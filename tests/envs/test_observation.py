"""The observation's parts (aldm_gym.envs.observation)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aldm_gym.envs.observation import LANE_ROWS, lane_gaps


def _reference_lane_gaps(codes, x, vx, pd, lengths):  # type: ignore[no-untyped-def]
    """The definition, vectorised: per lane the smallest x >= 0 and the largest x < 0
    (the first index on ties), bumper to bumper, clipped to [0, pd]."""
    reach = 0.5 * (lengths + 5.0)
    out = np.tile(np.array([pd, 0.0, pd, 0.0]), (3, 1))
    for row, code in enumerate(LANE_ROWS):
        mine = codes == code
        ahead = np.flatnonzero(mine & (x >= 0.0))
        if len(ahead):
            i = ahead[np.argmin(x[ahead])]
            out[row, 0] = min(max(x[i] - reach[i], 0.0), pd)
            out[row, 1] = vx[i]
        behind = np.flatnonzero(mine & (x < 0.0))
        if len(behind):
            i = behind[np.argmax(x[behind])]
            out[row, 2] = min(max(-x[i] - reach[i], 0.0), pd)
            out[row, 3] = vx[i]
    return out


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 12), st.integers(0, 2**31 - 1))
def test_lane_gaps_is_the_nearest_vehicle_per_lane(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    codes = rng.integers(0, 4, n).astype(np.float64)
    x = rng.choice([-30.0, -10.0, 0.0, 4.0, 10.0, 60.0, 150.0], n)  # ties on purpose
    vx = rng.normal(0.0, 3.0, n)
    lengths = rng.choice([5.0, 12.0, 18.0], n)
    got = lane_gaps(codes, x, vx, 100.0, lengths)
    np.testing.assert_array_equal(got, _reference_lane_gaps(codes, x, vx, 100.0, lengths))
