"""Layout of the kernels' parameters and of the four line slots.

The wrapper (:func:`aldm_gym.sensor.aldm.detect_lanes`) packs
:class:`~aldm_gym.sensor.aldm.ALDMParams` into these vectors once per parameter set.
"""

from __future__ import annotations

# Float parameters are passed as one float64 vector, integer ones as one int64 vector
# (module-level ints are compile-time constants inside numba).
P_START_X_MAX = 0  # start points only at x <= this [m] (paper: 18 + 5.52)
P_START_SPACING = 1  # paper mode: start points at least this far apart in x [m]
P_SEARCH = 2  # next-point search window ahead of the last point [m] (paper: 18)
P_ADJ_OFFSET = 3  # adjacent line starts this far outside the ego line [m] (paper: 2)
P_NOISE = 4  # robust: design lateral noise sigma [m]
P_GATE_SIGMAS = 5  # robust: residual gate in predicted standard deviations
P_GATE_MIN = 6  # robust: smallest residual gate [m]
P_GATE_MAX = 7  # robust: largest residual gate [m]
P_FIT_LENGTH = 8  # robust: fit uses accepted points within this x distance [m]
P_A_MAX = 9  # robust: |a| bound of y = a x^2 + ..., 1 / (2 R_min) [1/m]
P_A_STD = 10  # robust: prior std of a [1/m]
P_B_STD = 11  # robust: prior std of the slope dy/dx [-]
P_LINK_DX = 12  # robust seeds: link points at most this far apart in x [m]
P_LINK_DY = 13  # robust seeds: ... and this far apart in y [m]
P_MERGE_DY = 14  # robust seeds: chains whose offsets differ less are one line [m]
P_MAX_EGO = 15  # robust: an ego line passes within this |y| of the sensor [m]
P_MAX_LANE = 16  # robust: adjacent line at most this far outside the ego line [m]
P_SMOOTH_H = 17  # smoothed output: half width of the local quadratic fit [m]
P_TIE_DX = 18  # robust: gated points within this x of the first one compete [m]
P_LANE_WIDTH = 19  # default lane width for a one-line trajectory [m]
P_MIN_LANE = 20  # smallest plausible lane width [m] (lane-width estimate)
P_Z_BAND = 21  # points with |z| above this are not road paint (overpass, barrier) [m]
P_MAX_RANGE = 22  # points farther ahead or sideways are ignored [m]
P_VIEW_RANGE = 23  # paper mode: the sensor's range of view [m] (trace end)
P_GAP_SEARCH = 24  # robust: next-point window, bridging a missing dash [m]
P_MAX_SLOPE = 25  # robust: a trace stops where its slope |dy/dx| exceeds this [-]
P_GUIDE_A_STD = 26  # robust: prior std of a about the guide line's [1/m]
P_GUIDE_B_STD = 27  # robust: prior std of the slope about the guide line's [-]
N_FLOAT_PARAMS = 28

I_PAPER = 0  # 1: the paper's literal algorithm, 0: the robust variant
I_START_POINTS = 1  # paper mode: number of start points per line (3)
I_MIN_SEED = 2  # robust: fewest start-region points of a line
I_N_OUT = 3  # points per output line (0: all traced points)
I_SMOOTH = 4  # 1: output the smoothed line, 0: the measured points
N_INT_PARAMS = 5

N_LINES = 4
"""Line slots, in the order of ``LINE_NAMES``: left_adjacent, ego_left, ego_right,
right_adjacent. A point's mask bit ``1 << slot`` says that line owns it."""
L_LEFT_ADJ = 0
L_EGO_LEFT = 1
L_EGO_RIGHT = 2
L_RIGHT_ADJ = 3
