"""The lane-model filter: one clothoid-spline model of all lines, carried by a Kalman filter.

:class:`LaneModelFilter` (``detector_params={"tracking": "model"}``) estimates one
road shape shared by every line and an offset per line, in the ISO 8855 sensor frame
(x forward, y left) [m]. The shape is a *reference curve* through the sensor: heading
``psi`` [rad] at the sensor, and a curvature [1/m] linear in arc length between
:data:`~aldm_gym.sensor.aldm_kernels.model.N_NODES` nodes
:data:`~aldm_gym.sensor.aldm_kernels.model.NODE_STEP` (18 m) apart, constant beyond
the last one: a clothoid spline, the road model of Dickmanns and Mysliwetz (1992) with
its curvature rate free per node step, so that a transition into a bend that begins
in view is followed. Every line is the parallel curve at its offset ``y0_i`` along
the normal: a point belongs to line ``i`` when its signed distance ``l`` to the left
of the reference curve is ``y0_i``. Measured in the curve's own frame (the foot point
on a table of the curve and the circle of its curvature there), this holds in any
bend the generator or a map makes (R 100 m turns 0.9 rad within the model's 90 m),
where a cubic in x loses the lines below R 250 m. The measurement ``h = y0_i - l`` is
linearised about the prediction (an extended Kalman filter).

Each frame:

1. **Predict** the state by the ego's odometry (:class:`~aldm_gym.sensor.tracking.
   EgoMotion`): the new origin's foot point on the reference curve starts the new
   curve (its heading less the yaw change, the curvature nodes moved along the curve,
   the last node's curvature held beyond it), the offsets less the origin's distance
   to the curve; the process noise grows with the travel (see :class:`FilterParams`).
2. **Associate** every raw sensor point up to ``model_range`` with the nearest
   predicted line (by ``l``) whose gate it falls in: ``association_sigmas`` times the
   predicted standard deviation of the line there (the state's covariance and the
   point's noise), clipped to ``[association_min, association_max]``. Each line
   keeps one stripe of a double line, the one it lies on near the sensor
   (:meth:`LaneModelFilter._one_stripe`): the other stripe's points are not used.
3. **Update** with all associated points at once (information form), robustly:
   iteratively re-weighted least squares with Tukey's biweight (``tukey`` standard
   deviations: a redescending M-estimator, so points beyond it, a tar seam beside a
   dashed line, an old marking, get no weight at all) against clutter inside the
   gate. A second hypothesis, *the curvature jumped somewhere in view* (a straight
   meeting an arc with no transition curve, as OpenDRIVE allows), is updated beside
   it from the same prediction with the shape's covariance grown by a random walk of
   ``jump_curvature`` per node step; it replaces the nominal update when it explains
   more of the frame's points on at least two lines, or on the one line seen as far
   as the bend when vehicles hide the others (:data:`JUMP_MARGIN`,
   :data:`JUMP_LINE_GAIN`): a multiple-model filter with a hard decision.
4. **Existence.** A line whose points' robust weights sum to at least
   :data:`MIN_SUPPORT` in the frame is *hit*: its confidence ``p`` rises,
   ``p += hit_gain (1 - p)``; otherwise it falls, ``p -= miss_loss p`` (times the
   share of the line the vehicles leave in view, below). A line without a hit for
   ``drop_length`` metres of travel (counted by that share too) is dropped; of two lines
   closer than ``min_spacing`` the less confident one is dropped, and of two closer
   than ``lane_spacing`` (a narrow strip: a shoulder's edge line beside the lane
   line) once it is confirmed and has faded below ``min_confidence``. A line a vehicle
   hides (the frame's ``occluders``, through the line sensor's own sight model:
   :data:`HIDDEN_LENGTH`) is not missed: its confidence and miss length hold, and it
   is drawn through the shadow as far as the model is sure of it
   (:data:`CARRY_STD`). A line they partly hide is missed in proportion to the share
   of its length in view they leave visible (the detection probability of an
   existence filter, lowered by occlusion).
5. **Birth.** Points no line took (outside every gate, or given no weight), up to
   ``birth_range``, are put in the reference curve's frame (their ``l``); a cluster
   of at least ``birth_points`` of them within ``birth_width`` laterally, spanning
   ``birth_span`` in x and at least ``lane_spacing`` from every line, is a new line
   (a lane opening, the lane a lane change brings into view); closer, but at least
   ``min_spacing`` from every line, where it makes the lane widths more regular or
   lies outside the outermost line of its side (a narrow strip). Where the lines'
   spacing puts a line the model lacks, one dash is enough
   (:data:`SHORT_BIRTH_POINTS`, :data:`SHORT_BIRTH_SPAN`). A cluster closer to a
   line that has had no hit for ``reseat_length`` of travel *re-seats* that line
   when that makes the lane widths more regular: its offset is set there (id and
   role kept), its uncertainty reset (a line started on clutter, or lost; not a
   hidden line onto a seam inside its lane).
6. **Roles.** Confirmed lines (whose confidence has reached ``min_confidence``
   once; a confirmed line stays until it is dropped, so a hidden ego line keeps its
   role and is drawn from the model) get the roles by the sign of their offset at
   the sensor: the nearest on the left is the ego-left line, the next at least the
   ALDM's ``min_lane_width`` beyond it the left adjacent, if it is at most
   ``max_lane_width`` beyond it (a median between two edge lines is no lane); the
   same on the right.
   When the nearest lines on the two sides are more than the ALDM's
   ``max_lane_width`` apart, an ego line is missing: the one
   farther from the sensor is the adjacent line of its side. A lane change moves
   the offsets through 0 and so re-labels the lines; the ids stay.

Without a model (the first frame, ``motion=None``, or every line dropped) the
model starts from the single-frame ALDM (:func:`~aldm_gym.sensor.aldm.detect_lanes`)
on the frame: its lines fitted whole, or only up to :data:`START_RANGE`, or a straight
road at their offsets, whichever lays most of the frame's raw points on lines
parallel to its shape (the simplest of equal scores; a trace that wandered far out
under noise, or jumped onto the next line, does not bend the model). Lines of the
frame the start lacks (a shoulder's edge line beside a lane line) are born on its
shape before the frame's points update it. When a confirmed line hit in a frame has its
farthest point ``recede_length`` short of that of its last hit (a shape bent off the
road far out, whose gates miss the points that would bend it back; not where a vehicle
hides the line from there on), or short of where the model puts it in view while
another line is seen that far (the same, over several frames), the model competes with
such a start on the frame and is replaced if the start scores higher (a line of the
start that the model has keeps its id).
The decisions are listed in
``docs/aldm.md``, section "Lane-model filter".
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aldm_gym.config import build_config, check_keys, setting, validate
from aldm_gym.errors import ConfigError, InputError
from aldm_gym.sensor.aldm import ALDMParams, as_points, detect_lanes_checked, make_params
from aldm_gym.sensor.aldm_kernels.model import (
    _C,
    _S,
    _X,
    N_GEOMETRY,
    N_NODES,
    NODE_STEP,
    SCALE,
    TABLE_STEP,
    any_closer,
    associate_update,
    curve_table,
    draw_on,
    existence,
    fit,
    lateral_std,
    measurements,
    one_stripe,
    predict,
    project_on,
    receded,
    spans,
)
from aldm_gym.sensor.conditions import _occlude, occluder_array
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection
from aldm_gym.sensor.tracking import TRACKER_KEYS, EgoMotion, TrackerParams, split_params
from aldm_gym.sensor.trajectory import DEFAULT_LANE_WIDTH, PATH_STEP, driving_trajectory, fit_reach
from aldm_gym.types import FloatArray

MIN_SUPPORT = 2.5
"""A line is hit in a frame when the robust weights of its points sum to at least
this: one 6 m dash sampled every 2 m gives three points, whose weights sum to a little
under 3 (one or two points could be specks of clutter within the gate)."""

START_X_MAX = 20.0
"""Lines are drawn from the nearest point of the frame, but from no farther than this
[m] (the score's start region is 25 m)."""

EMPTY_START = 5.52
"""Lines of a frame without points are drawn from here [m] (the line sensor's
``fov_start``)."""

START_INFLATION = 4.0
"""The covariance from the single-frame ALDM's lines is multiplied by this before the
frame's points update it (the lines' points are correlated)."""

SCORE_REACH = 7.5
"""A start's score (:meth:`LaneModelFilter._parallel_support`) counts the points up to
this far from its reference curve [m]: two lane widths, the ego's lines and the
adjacent ones."""

STATE_LAYOUT = (N_NODES, NODE_STEP)
"""The shape's layout, ``(curvature nodes, node step [m])``, that a pickled filter
carries and must match to be restored (:meth:`LaneModelFilter.__setstate__`)."""

RESTART_MARGIN = 0.03
"""A restart (a receded model competing with a fresh start on the frame) replaces the
model only when the start's score is more than this share above the model's: a model
that left the road scores far below a start, while one point more or less is the
frame's noise (on ``motorway`` under the camera preset, seed 4, a start turned
0.055 rad out scored 66 against the right model's 65, and the car left its lane).
On a model's score below 34 points the margin is under one point: any point more
replaces it."""

SIGHT_MARGIN = 0.2
"""A restart for a line seen short of its sight (:meth:`LaneModelFilter._short_of_sight`)
replaces the model only when the start scores this share above it (a drop,
:meth:`LaneModelFilter._receded`: :data:`RESTART_MARGIN`). Under the camera preset far
dashes drop out, so a line stops short of where it is in view far more often than the
model leaves the road, and each restart is a chance for a start turned a little off
to win. On ``motorway`` under the camera preset: at 0.03, 33 restarts in 20 episodes
instead of 7 and 0.970 both-correct instead of 0.976 (seed 4 wrong in 17 steps
instead of 10); at 0.1 seed 4 left its lane twice; at 0.2 neither. A model that left
the road scores far below a start."""

RECEDE_SHADOW = 4.0
"""A line's drop (:meth:`LaneModelFilter._receded`) is no evidence when a vehicle
hides the line from within this [m] beyond its farthest point in the frame (two
occlusion steps: the car starts where the line stops being seen). Farther, the car
hides what may not be there: at 13 m (a dash gap) the curvature-step map with
vehicles fell 0.954 -> 0.909, where the restart follows a step that a car half
hides."""

START_RANGE = 50.0
"""The start fits the single-frame ALDM's lines up to this x [m]: farther out a trace
that wandered (noise, dropout) would bend the whole model; the frame's raw points
then extend the model to ``model_range`` through the gates."""

START_ITERATIONS = 4
"""Gauss-Newton iterations of the start's update (from a straight prior to an R 100 m
bend the foot points settle in three)."""

JUMP_MARGIN = 3.0
"""The curvature-jump hypothesis replaces the nominal update when its points' robust
weights sum to more than this above the nominal update's ..."""

JUMP_LINE_GAIN = 2.0
"""... and at least :data:`JUMP_LINES` lines gain this much support each: the road
bends every marking, clutter one."""

JUMP_LINES = 2
"""See :data:`JUMP_LINE_GAIN`."""

HIDDEN_LENGTH = 20.0
"""A line is *hidden* in a frame when a vehicle (the frame's ``occluders``) blocks
the sight of part of it and less than this much of it [m], from ``fov_start`` to
``model_range``, is left in view: a dashed line (6 m dashes, 12 m gaps) shows a whole
dash, enough points for a hit, in any 18 m. A hidden line's miss is no evidence that
it is gone."""

SHORT_BIRTH_POINTS = 3
"""Where the lines' spacing puts a line the model lacks, a cluster of this many free
points ..."""

SHORT_BIRTH_SPAN = 4.0
"""... spanning this much in x [m] (one 6 m dash sampled every 2 m) is a new line:
a line lost while a car hid all but its near dashes comes back from them."""

CARRY_STD = 0.1
"""A line a vehicle hides beyond where it was seen is drawn on past where any line is
seen only while its drawn points' lateral standard deviation (the model's
covariance) stays at most this [m]: a third of the score's 0.3 m."""

OCCLUSION_STEP = 2.0
"""The x step [m] at which the lines are checked for occlusion (the line sensor's
sampling)."""

MIN_EXTENT = 10.0
"""A line shorter than this in x [m] is not drawn."""

STRIPE_GAP = 0.45
"""Two points of a frame at one station less than this apart laterally [m] are the two
stripes of a double line (a stripe, a gap and a stripe: 0.24-0.3 m), not two borders
(a lane width, or a narrow strip's 0.75 m)."""

STRIPE_STATION = 1.0
"""Points within this arc length of each other [m] are at one station: half the line
sensor's 2 m sampling step."""

STRIPE_NEAR = 40.0
"""A line's stripe is decided by the double line's pairs within this arc length of
the sensor [m], where the shape is sure to a few centimetres (the stripes are 0.24 m
apart) and the line has followed its stripe from frame to frame."""


def _end_row(
    tab: FloatArray, max_slope: float, s_max: float = math.inf
) -> tuple[int, float] | None:
    """Where a line of the reference curve tabulated in ``tab`` ends: the first row
    ``k`` beyond the end and the fraction ``t`` of the step from row ``k - 1`` at which
    it is reached (the same for every line: parallel curves share their tangent and
    their foot points); ``None``: nowhere in the table. The end is the nearer of two
    places:

    * where the curve first gets steeper than ``max_slope`` in the sensor frame. A
      line is a function y(x): beyond that, a small error along the normal is a large
      one in y, and the single-frame ALDM stops its traces there (its ``max_slope``);
    * ``s_max`` [m] of arc from the sensor: the model's range along the road (its
      ``model_range``). Points beyond it are not its measurements (see
      :func:`~aldm_gym.sensor.aldm_kernels.model.associate_update`), so a line drawn
      there would be the last node's curvature carried on, not the road."""
    c, sn = tab[:, _C], tab[:, _S]
    steep = np.flatnonzero((c <= 0.0) | (np.abs(sn) > max_slope * c))
    # both ends as a position in rows: row k - 1 plus the fraction t of the next step
    ends = [s_max / TABLE_STEP] if s_max / TABLE_STEP < len(tab) - 1 else []
    if len(steep):
        k = int(steep[0])
        if k == 0:
            return 0, 0.0
        slope = np.abs(sn[k - 1 : k + 1]) / np.maximum(c[k - 1 : k + 1], 1e-9)
        t = (max_slope - slope[0]) / max(slope[1] - slope[0], 1e-12)
        ends.append(k - 1 + min(max(float(t), 0.0), 1.0))
    if not ends:
        return None
    end = max(min(ends), 0.0)
    k = min(math.floor(end) + 1, len(tab) - 1)
    return k, end - (k - 1)


def _end_x(tab: FloatArray, row: tuple[int, float] | None, offset: float) -> float:
    """The x [m] where the line at ``offset`` [m] from the reference curve tabulated
    in ``tab`` ends (:func:`_end_row`'s ``row``; inf: nowhere)."""
    if row is None:
        return math.inf
    k, t = row
    if k == 0:
        return 0.0
    x0 = float(tab[k - 1, _X] - offset * tab[k - 1, _S])
    x1 = float(tab[k, _X] - offset * tab[k, _S])
    return x0 + t * (x1 - x0)


def shape_covariance(heading: float, curvature: float, curvature_rate: float) -> FloatArray:
    """``(N_GEOMETRY, N_GEOMETRY)`` covariance of the shape entries as the state holds
    them, from standard deviations of the heading [rad], of the curvature common to
    all nodes [1/m] and of its change per metre [1/m^2]: the node curvatures are a
    random walk along the road (node ``k`` is node 0 plus ``k`` independent steps of
    ``curvature_rate * NODE_STEP``), so a node without measurements follows its
    neighbours rather than drifting on its own."""
    cov = np.zeros((N_GEOMETRY, N_GEOMETRY))
    cov[0, 0] = (heading * SCALE) ** 2
    step = (curvature_rate * NODE_STEP) ** 2
    for i in range(N_NODES):
        for j in range(N_NODES):
            cov[1 + i, 1 + j] = (curvature**2 + min(i, j) * step) * SCALE**4
    return cov


@dataclass(frozen=True)
class FilterParams:
    """Parameters of :class:`LaneModelFilter` (lengths [m]).

    Measurement and association:

    :ivar model_range: points up to this x are measurements, and lines are drawn at
        most this far (90 m: beyond it the camera's noise and the cars ahead leave
        the shape a guess).
    :ivar point_std: standard deviation of a point's lateral position at x = 0 (the
        sensor's noise and what the spline misses) ...
    :ivar point_std_slope: ... plus this much per metre ahead [m/m].
    :ivar association_sigmas: a point is associated with a line within this many predicted
        standard deviations ...
    :ivar association_min: ... but at least this ...
    :ivar association_max: ... and at most this (well below half a lane width).
    :ivar tukey: the robust update's Tukey biweight threshold, in standard
        deviations (a point farther from the updated line has no weight).

    Process noise (standard deviations per square root of the travel [1/sqrt(m)]):

    :ivar q_offset: of the lines' common offset [m] (the odometry's lateral error:
        all lines move together) ...
    :ivar q_width: ... and of each line's own offset [m] (lane widths change
        slowly: a line seen for a while holds its distance to its neighbours).
    :ivar q_heading: of the heading [rad] (the odometry's yaw error).
    :ivar q_curvature: of the curvature, common to all nodes [1/m].
    :ivar q_curvature_rate: of the curvature's change per metre [1/m^2], per node step
        (:func:`shape_covariance`: node ``k`` is node 0 plus ``k`` independent steps;
        the road's clothoids begin and end, and the last node sees new road every
        frame: 2e-6 lets the model follow an R 100 m transition, 5e-7 did not).
    :ivar q_far_curvature_rate: the road's curvature rate where the model extrapolates
        [1/m^2]: each frame the last node moves onto road it had not seen and holds
        the curvature of the old last node; it gets ``(q_far_curvature_rate * d)^2``
        more variance for the ``d`` metres it moved, so that a clothoid coming into
        view bends it at once rather than a node step late. Only while points reach
        the last node step (else nothing would measure it). 0: none (the default:
        with six nodes it gains nothing on the drive benchmark's curvature-step map,
        and it costs the camera preset; ``docs/aldm.md``).
    :ivar far_curvature_trend: how much of the last node step's curvature change the
        last node carries on as it moves onto new road (0: the curvature held, 1: the
        clothoid continued), while points reach the last node step (else the
        curvature is held: an unmeasured trend would bend on without bound). On a
        spiral whose curvature changes across the whole view, a held last node lags
        the road by a node step; 0.5 (the drive benchmark, "The far end's lag" in
        docs/aldm.md) follows it and does not overshoot where a clothoid ends.

    Existence:

    :ivar hit_gain: confidence gained on a hit (a fraction of what is missing to 1).
    :ivar miss_loss: confidence lost on a miss (a fraction of it).
    :ivar min_confidence: a line is confirmed, and from then on reported until it
        is dropped, once its confidence reaches this.
    :ivar birth_confidence: confidence of a line born from points.
    :ivar drop_length: a line without a hit for this much travel is dropped (a miss
        counts the share of the line in view that no vehicle hides).
    :ivar min_spacing: after a frame's update no two lines are closer than this at
        the sensor (of two, the less confident is dropped): the stripes of a double
        line, at most 0.45 m apart, are one line.
    :ivar lane_spacing: two lines closer than this (and at least ``min_spacing``: a
        narrow strip, a shoulder's edge line 0.75 m outside a lane line) both stay
        only while the less confident is unconfirmed or at least ``min_confidence``;
        a line is born this close to another only where it makes the lane widths more
        regular (lane openings, clutter and seams are not).
    :ivar extend_length: a line is drawn beyond its own farthest point at most this far,
        up to where the other lines are seen (the car ahead hides the ego lane's lines,
        not the lane beside).

    Birth:

    :ivar birth_range: points up to this x can give birth to a line.
    :ivar birth_points: a new line needs at least this many points ...
    :ivar birth_width: ... within this width of their distance to the reference
        curve ...
    :ivar birth_span: ... spanning at least this much in x.
    :ivar max_offset: lines farther than this laterally are dropped, and none is
        born there.
    :ivar reseat_length: a line without a hit for this much travel is re-seated
        onto a cluster of free points within ``lane_spacing`` of it (0: never).
    :ivar recede_length: when a confirmed line hit in a frame has its farthest point
        this much short of that of its last hit (carried by the odometry), or of
        where the model puts it in view and another line is seen (once while it
        stays short), the model competes with a fresh start on the frame (0: never).
    :ivar jump_curvature: the curvature-jump hypothesis: the standard deviation of
        the change of curvature per node step [1/m] added to the prediction's shape
        covariance (0: no such hypothesis; 0.005 follows a step to R 100 m).
    """

    model_range: float = setting(90.0, lo=20.0, hi=1000.0)
    point_std: float = setting(0.03, lo=0.0, lo_open=True, hi=10.0)
    point_std_slope: float = setting(0.0005, lo=0.0, hi=1.0)
    association_sigmas: float = setting(4.0, lo=0.0, lo_open=True, hi=100.0)
    association_min: float = setting(0.4, lo=0.0, lo_open=True, hi=10.0)
    association_max: float = setting(1.2, lo="association_min", hi=10.0)
    tukey: float = setting(3.0, lo=0.0, lo_open=True, hi=100.0)
    q_offset: float = setting(0.01, lo=0.0, hi=10.0)
    q_width: float = setting(0.005, lo=0.0, hi=10.0)
    q_heading: float = setting(0.002, lo=0.0, hi=1.0)
    q_curvature: float = setting(2.0e-5, lo=0.0, hi=1.0)
    q_curvature_rate: float = setting(2.0e-6, lo=0.0, hi=1.0)
    q_far_curvature_rate: float = setting(0.0, lo=0.0, hi=1.0)
    far_curvature_trend: float = setting(0.5, lo=0.0, hi=1.0)
    hit_gain: float = setting(0.3, lo=0.0, lo_open=True, hi=1.0)
    miss_loss: float = setting(0.1, lo=0.0, hi=1.0)
    min_confidence: float = setting(0.5, lo=0.0, hi=1.0)
    birth_confidence: float = setting(0.4, lo=0.0, hi=1.0)
    drop_length: float = setting(60.0, lo=0.0, hi=1.0e4)
    min_spacing: float = setting(0.6, lo=0.0, lo_open=True, hi=10.0)
    lane_spacing: float = setting(2.5, lo="min_spacing", hi=10.0)
    extend_length: float = setting(60.0, lo=0.0, hi=1000.0)
    birth_range: float = setting(60.0, lo=10.0, hi=1000.0)
    birth_points: int = setting(6, lo=3, hi=1000, integer=True)
    birth_width: float = setting(0.4, lo=0.0, lo_open=True, hi=10.0)
    birth_span: float = setting(12.0, lo=0.0, hi=1000.0)
    max_offset: float = setting(12.0, lo=1.0, hi=100.0)
    reseat_length: float = setting(10.0, lo=0.0, hi=1.0e4)
    recede_length: float = setting(20.0, lo=0.0, hi=1000.0)
    jump_curvature: float = setting(0.005, lo=0.0, hi=1.0)

    def __post_init__(self) -> None:
        validate(self, "filter")
        if self.birth_range > self.model_range:
            raise ConfigError(
                f"filter.birth_range ({self.birth_range}) must not exceed model_range "
                f"({self.model_range}): births are measured in the model's range"
            )
        if self.birth_span > self.birth_range:
            raise ConfigError(
                f"filter.birth_span ({self.birth_span}) must not exceed birth_range "
                f"({self.birth_range}): no cluster could span it, no line would be born"
            )
        if self.reseat_length > self.drop_length:
            raise ConfigError(
                f"filter.reseat_length ({self.reseat_length}) must not exceed drop_length "
                f"({self.drop_length}): a line is dropped before it could be re-seated "
                "(0 turns re-seating off)"
            )


FILTER_KEYS: tuple[str, ...] = tuple(FilterParams.__dataclass_fields__)
"""The ``detector_params`` keys of the lane-model filter (besides ``tracking``); none
is a key of :class:`ALDMParams` or of the tracker."""


def split_aldm_params(
    params: dict[str, Any],
) -> tuple[bool | str, TrackerParams | None, FilterParams | None, ALDMParams]:
    """``detector_params`` of ``"aldm"`` -> ``(tracking, tracker params, filter params,
    ALDM params)``: ``tracking`` is one of :data:`~aldm_gym.sensor.tracking.
    TRACKING_CHOICES`; the tracker's parameters are ``None`` unless it is ``True``, the
    filter's unless it is ``"model"``.

    :raises ConfigError: an unknown key (naming the allowed ones), a bad value, a
        ``tracking`` not among the choices (naming them), or settings of the tracker
        or the filter without the ``tracking`` that reads them.
    """
    check_keys(
        "aldm config", params, {*ALDMParams.__dataclass_fields__, *TRACKER_KEYS, *FILTER_KEYS}
    )
    tracking = params.get("tracking", False)
    if isinstance(tracking, str) and tracking == "model":
        filt, aldm = split_filter_params(params)
        return "model", None, filt, aldm
    extra = sorted(k for k in params if k in FILTER_KEYS)
    if extra and isinstance(tracking, (bool, np.bool_)):
        raise ConfigError(
            f"aldm settings {extra} are the lane-model filter's: they need tracking='model'"
        )
    on, tracker, aldm = split_params(params)
    return on, tracker if on else None, None, aldm


def split_filter_params(params: dict[str, Any]) -> tuple[FilterParams, ALDMParams]:
    """``detector_params`` of ``"aldm"`` with ``tracking="model"`` -> ``(filter params,
    ALDM params)`` (the ALDM starts the model).

    :raises ConfigError: an unknown key (naming the allowed ones), a bad value, a
        ``tracking`` other than ``"model"``, or settings of the point-level tracker
        (they need ``tracking=True``).
    """
    check_keys(
        "aldm config", params, {*ALDMParams.__dataclass_fields__, *TRACKER_KEYS, *FILTER_KEYS}
    )
    if params.get("tracking") != "model":
        raise ConfigError(f"aldm.tracking must be 'model' here, got {params.get('tracking')!r}")
    tracker = sorted(k for k in params if k in TRACKER_KEYS and k != "tracking")
    if tracker:
        raise ConfigError(
            f"aldm settings {tracker} are the point-level tracker's: they need tracking=True, "
            "not tracking='model'"
        )
    filt = {k: v for k, v in params.items() if k in FILTER_KEYS}
    aldm = {k: v for k, v in params.items() if k in ALDMParams.__dataclass_fields__}
    return build_config(FilterParams, filt, where="aldm"), make_params(None, **aldm)


@dataclass(frozen=True)
class ModelLaneDetection(LaneDetection):
    """A :class:`~aldm_gym.sensor.lane_detection.LaneDetection` of the lane-model filter:
    the lines drawn from the model, and per line its confidence and id.

    :ivar confidence: ``(4,)`` existence confidence of each line in :data:`LINE_NAMES`
        order, in [0, 1] (0: no line in that role).
    :ivar ids: the filter's id of each line (-1: none); a marking keeps its id while
        its role changes in a lane change.
    :ivar measured: ``(4, 2)`` per line, the x range ``[from, to]`` [m] of this
        frame's points that updated it (NaN, NaN: the line was not measured in this
        frame, e.g. hidden or worn, and is drawn from the model alone). Inside the
        range the line is measured (across the gaps of a dashed line); outside it, at
        either end, it is carried by the model: :meth:`measured_mask`.
    :ivar lateral_std: ``(4, n)`` per line, the standard deviation of each drawn
        point's lateral position [m] from the filter's covariance (the shape's and the
        line's offset; NaN where a role has no line). It grows where the line is
        carried far beyond its measurements.
    """

    confidence: FloatArray = field(default_factory=lambda: np.zeros(len(LINE_NAMES)))
    ids: tuple[int, ...] = (-1,) * len(LINE_NAMES)
    measured: FloatArray = field(default_factory=lambda: np.full((len(LINE_NAMES), 2), np.nan))
    lateral_std: FloatArray = field(default_factory=lambda: np.zeros((len(LINE_NAMES), 0)))

    def measured_mask(self, name: str) -> np.ndarray:
        """Per point of line ``name``, whether it lies in the x range measured in this
        frame (:attr:`measured`); False everywhere for a line drawn from the model
        alone, and for no line (an empty mask).

        :raises InputError: an unknown line name (naming the allowed ones).
        """
        line = self.line(name)
        lo, hi = self.measured[LINE_NAMES.index(name)]
        if not (math.isfinite(lo) and math.isfinite(hi)):
            return np.zeros(len(line), dtype=bool)
        return (line[:, 0] >= lo) & (line[:, 0] <= hi)


class LaneModelFilter:
    """One clothoid-spline model of all lines, carried from frame to frame by a Kalman
    filter.

    Call :meth:`update` once per frame with the points and the motion since the
    previous frame; :meth:`reset` forgets the model (a new episode). Deterministic
    (no randomness) and picklable; :func:`copy.copy` copies it whole (its arrays are
    updated in place). The state, in SI units, is :attr:`heading`,
    :attr:`node_curvatures` (:attr:`curvature`, :attr:`curvature_rate` near the
    sensor) and :attr:`offsets`.

    :param params: the ALDM's parameters, for the frame that starts the model and
        its ``z_band`` (:class:`ALDMParams`; default robust).
    :param filt: the filter's (:class:`FilterParams`).
    :param path_range: the trajectory's fit range [m], as for
        :func:`~aldm_gym.sensor.aldm.detect_lanes`.
    """

    def __init__(
        self,
        params: ALDMParams | None = None,
        filt: FilterParams | None = None,
        *,
        path_range: float | None = None,
    ) -> None:
        self.params = make_params(params)
        self.filter = filt if filt is not None else FilterParams()
        if not isinstance(self.filter, FilterParams):
            raise TypeError(f"filt must be FilterParams, got {type(self.filter).__name__}")
        fit_reach(path_range)  # raises on a bad path_range now, not at the first frame
        self.path_range = path_range
        fp = self.filter
        self._q_shape = shape_covariance(fp.q_heading, fp.q_curvature, fp.q_curvature_rate)
        self._q_jump = (
            shape_covariance(0.0, 0.0, fp.jump_curvature / NODE_STEP)
            if fp.jump_curvature > 0.0
            else None
        )
        self.reset()

    def __copy__(self) -> LaneModelFilter:
        """A whole copy (the bookkeeping arrays are updated in place each frame, so a
        shallow copy would share them)."""
        return copy.deepcopy(self)

    def __getstate__(self) -> dict[str, Any]:
        """The filter's state, with the layout of its shape (:data:`STATE_LAYOUT`)."""
        return {**self.__dict__, "_layout": STATE_LAYOUT}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a pickled filter; one pickled with another shape layout (an older
        aldm-gym, another number of curvature nodes) cannot be carried on. Settings
        added to :class:`FilterParams` since the pickle was made take their defaults.

        :raises InputError: the pickle's layout is not :data:`STATE_LAYOUT`.
        """
        layout = state.pop("_layout", None)
        if layout != STATE_LAYOUT:
            raise InputError(
                "this LaneModelFilter was pickled with another state layout "
                f"({layout if layout is not None else 'an aldm-gym before 2026-11-30'}; "
                f"this one: {STATE_LAYOUT}, (curvature nodes, node step [m])): its model "
                "cannot be carried on; start the filter (or the episode) anew"
            )
        fp = state.get("filter")
        if isinstance(fp, FilterParams):
            defaults = FilterParams()
            for f in dataclasses.fields(FilterParams):
                if f.name not in fp.__dict__:
                    object.__setattr__(fp, f.name, getattr(defaults, f.name))
        self.__dict__.update(state)
        if "_examined" not in state:
            self._examined = set()

    def reset(self) -> None:
        """Forget the model and the lines' ids (the next frame starts a new model)."""
        self._x = np.zeros(N_GEOMETRY)
        self._p = np.zeros((N_GEOMETRY, N_GEOMETRY))
        self._ids = np.zeros(0, dtype=np.int64)
        self._conf = np.zeros(0)
        self._miss = np.zeros(0)
        self._far = np.zeros(0)
        self._confirmed = np.zeros(0, dtype=bool)
        self._span = np.zeros((0, 2))
        self._examined: set[int] = set()
        self._next_id = 0
        self._last_ids: tuple[int, ...] = (-1,) * len(LINE_NAMES)
        self.n_used = 0
        """Points associated with a line, and not rejected by the robust step, in the
        last frame."""
        self.n_born = 0
        """Lines born from points since the reset."""
        self.n_reseated = 0
        """Lines re-seated onto a cluster of free points since the reset."""
        self.n_starts = 0
        """Times the model was started from the single-frame ALDM since the reset."""
        self.n_restarts = 0
        """Of those, fresh starts that replaced a model whose lines receded (its shape
        laid fewer of the frame's points on parallel lines)."""
        self.n_jumps = 0
        """Frames whose update came from the curvature-jump hypothesis since the reset."""
        self.n_reborn = 0
        """Of the lines born, those born from short evidence (one dash) where the lines'
        spacing puts one, since the reset."""

    # -- the state in SI units ---------------------------------------------------------

    @property
    def heading(self) -> float:
        """The reference curve's heading at the sensor, ``psi`` [rad], left positive."""
        return float(self._x[0] / SCALE)

    @property
    def curvature(self) -> float:
        """The reference curve's curvature at the sensor [1/m], left positive."""
        return float(self._x[1] / SCALE**2)

    @property
    def curvature_rate(self) -> float:
        """Its rate of change over the first node step [1/m^2]."""
        return float((self._x[2] - self._x[1]) / SCALE**2 / NODE_STEP)

    @property
    def node_curvatures(self) -> FloatArray:
        """The curvature at each node, ``NODE_STEP`` apart from the sensor [1/m]."""
        return self._x[1:N_GEOMETRY] / SCALE**2

    @property
    def offsets(self) -> FloatArray:
        """Each line's offset from the reference curve (the curve through the sensor)
        along its normal at the sensor [m], left positive, in the order of
        :attr:`line_ids`."""
        return self._x[N_GEOMETRY:].copy()

    @property
    def line_ids(self) -> tuple[int, ...]:
        """The id of every line of the model (reported or not)."""
        return tuple(int(i) for i in self._ids)

    @property
    def confidences(self) -> FloatArray:
        """The confidence of every line of the model, in the order of :attr:`line_ids`."""
        return self._conf.copy()

    # -- one frame ---------------------------------------------------------------------

    def update(self, points: Any, motion: EgoMotion | None) -> ModelLaneDetection:
        """Carry the model to this frame and update it with the frame's points.

        Rows with NaN or inf, behind the sensor (x < 0) or off the road plane
        (``|z| > z_band``) are dropped, as :func:`~aldm_gym.sensor.aldm.detect_lanes`
        drops them; an empty frame is a frame in which every line is missed.

        :param points: ``(N, 2|3)`` points in the sensor frame [m], or a sensor frame.
        :param motion: the sensor's motion since the previous frame; ``None`` starts
            the model again from this frame (without odometry the old lines cannot be
            placed).
        :raises TypeError: ``points`` is not an array or frame, or ``motion`` is not
            an :class:`EgoMotion`.
        :raises ValueError: ``points`` of a bad shape.
        """
        pts = as_points(points)
        if motion is not None and not isinstance(motion, EgoMotion):
            raise TypeError(f"motion must be EgoMotion or None, got {type(motion).__name__}")
        fp = self.filter
        x, y = measurements(pts, fp.model_range, self.params.z_band)
        near = float(min(x.min(), START_X_MAX)) if len(x) else EMPTY_START
        started = motion is None or len(self._ids) == 0
        if started:
            self._start(pts, x, y)
            self._start_births(x, y)
            travel = 0.0
        else:
            travel = motion.travel
            self._predict(*motion.displacement(), travel)
        line = None
        if len(self._ids):
            line, support, far = self._correct(x, y)
            drop = short = False
            if not started and fp.recede_length > 0.0:
                drop = self._receded(points, far)
                short = self._short_of_sight(points, far)
            margin = RESTART_MARGIN if drop else SIGHT_MARGIN
            if (drop or short) and self._start(pts, x, y, incumbent=True, margin=margin):
                # the model had left the road: started anew from this frame
                self.n_restarts += 1
                travel = 0.0
                line, support, far = self._correct(x, y)
            # where each line was measured (NaN without MIN_SUPPORT)
            self._span = spans(x, line, support, len(self._ids), MIN_SUPPORT)
            seen, _ = self._occlusion(points)
            self._existence(support, far, travel, seen)
        # the reference curve after the update (births and drawing move no shape)
        tab = curve_table(self._x, fp.model_range)
        if line is not None and len(self._ids):
            self._birth(x, y, line, tab)
        # where a vehicle hides each line of the final model, beyond where it was seen
        _, shadow = self._occlusion(points, beyond=self._far - OCCLUSION_STEP)
        return self._detection(near, shadow, tab)

    def _start(
        self,
        pts: FloatArray,
        x: FloatArray,
        y: FloatArray,
        incumbent: bool = False,
        margin: float = RESTART_MARGIN,
    ) -> bool:
        """A new model from the single-frame ALDM's lines, checked against the frame's
        points ``(x, y)`` [m]: a flat prior updated (robustly) with the lines' points up
        to ``model_range``, or only up to :data:`START_RANGE`, or a straight road at the
        lines' offsets, whichever lays most of the frame's points on lines parallel to
        its shape (:meth:`_parallel_support`; of equal scores the simplest: straight,
        then fitted near, then whole). A trace that wandered far out under noise, or
        jumped onto the next line, then does not bend the model, and the ALDM's lines
        still start it in a bend; a fit's noise where its lines end is not carried on
        to 90 m when a straight start lays as many points on parallel lines.

        :param incumbent: the current model competes too (its shape, as updated with
            this frame, scored on the same points); it is kept, and nothing changes,
            unless a new start scores more than ``margin`` (a share) higher.
        :param margin: see ``incumbent`` (:data:`RESTART_MARGIN`, :data:`SIGHT_MARGIN`).
            A new start replacing the model keeps the ids (and confidences, where higher)
            of the lines it shares with it (:meth:`_same_lines`) and the lines it lacks
            (:meth:`_inherited`).
        :return: whether the model was started anew.
        """
        fp = self.filter
        _, _, lines, ls = detect_lanes_checked(pts, self.params, None)
        kept = [lines[ls[i] : ls[i + 1]] for i in range(len(LINE_NAMES))]
        kept = [v[v[:, 0] <= fp.model_range] for v in kept]
        kept = [v for v in kept if len(v) >= 2]
        n = len(kept)
        if incumbent and n == 0:
            return False
        x0 = np.concatenate((np.zeros(N_GEOMETRY), [float(v[0, 1]) for v in kept]))
        # a flat prior: headings of +-0.3, radii down to ~100 m, curvature changing by
        # 0.005 1/m per node step (R 100 m reached over two steps, 36 m; chosen with
        # 30 m steps), offsets +-2 m
        p0 = np.zeros((N_GEOMETRY + n, N_GEOMETRY + n))
        p0[:N_GEOMETRY, :N_GEOMETRY] = shape_covariance(0.3, 0.01, 0.005 / NODE_STEP)
        p0[N_GEOMETRY:, N_GEOMETRY:] = np.diag(np.full(n, 2.0**2))
        best: tuple[FloatArray, FloatArray] = (x0, p0)
        if n:
            lx = np.concatenate([v[:, 0] for v in kept])
            ly = np.concatenate([v[:, 1] for v in kept])
            which = np.concatenate([np.full(len(v), i) for i, v in enumerate(kept)])
            candidates = []
            for top in (fp.model_range, START_RANGE):
                sel = lx <= top
                # robust too: a traced line bent onto clutter near the car keeps the
                # offset of the most of its points; the 13 points per line are a fit,
                # not independent measurements: the covariance is inflated, and the
                # frame's own points follow in the same update
                state, cov = self._fit(lx[sel], ly[sel], which[sel], x0, p0)
                candidates.append((state, cov * START_INFLATION))
            state, cov = candidates[-1]
            straight = state.copy()
            straight[:N_GEOMETRY] = 0.0
            candidates.append((straight, cov))
            # each start's support: how many of the frame's points its shape lays on
            # parallel lines (the lines the ALDM found and any other)
            # scored on the same points: those near any of the shapes (and the
            # incumbent's), so that a shape bent to take in one more line gains
            # nothing the right shape would not count too
            states = [st for st, _ in candidates] + ([self._x] if incumbent else [])
            scores = self._parallel_supports(states, x, y)
            # the best score; of equal ones the later, simpler shape (whole fit, near
            # fit, straight)
            k = max(range(len(candidates)), key=lambda i: (scores[i], i))
            if incumbent and scores[k] <= scores[-1] * (1.0 + margin):
                return False
            best = candidates[k]
        old = self._inherited(best[0]) if incumbent else None
        same = self._same_lines(best[0]) if incumbent else np.full(n, -1)
        conf = np.full(n, 0.5 + 0.5 * fp.min_confidence)
        ids = np.empty(n, dtype=np.int64)
        for i, j in enumerate(same.tolist()):
            if j >= 0:
                ids[i] = self._ids[j]
                conf[i] = max(conf[i], float(self._conf[j]))
            else:
                ids[i] = self._next_id
                self._next_id += 1
        self._x, self._p = best
        self._ids = ids
        self._conf = conf
        self._miss = np.zeros(n)
        self._far = np.array([float(v[-1, 0]) for v in kept])
        self._confirmed = np.ones(n, dtype=bool)
        self._span = np.full((n, 2), np.nan)
        if old is not None:
            self._inherit(old)
        self.n_starts += 1
        return True

    def _start_births(self, x: FloatArray, y: FloatArray) -> None:
        """Lines of the frame's points ``(x, y)`` [m] that a start lacks (the
        single-frame ALDM reports four at most, and none inside a lane's width: a
        shoulder's edge line 0.75 m outside the lane line), born on the start's shape
        (:meth:`_birth`, every point free) before the frame's points update it: else
        the nearest line's gate, as wide as a fresh start's uncertainty, takes their
        points, and the shared shape bends to lay that line on them (on ``features``,
        with wear, noise and cars, the ego's right line onto the shoulder's line beyond
        45 m, where the lane line was worn: the shape zigzagged for 1.4 s). A restart
        has no such step: it keeps the lines of the model it replaces that it lacks at
        least ``lane_spacing`` from its own (:meth:`_inherited`); a narrow strip's
        line closer than that is lost and born again by the rules after the update
        (born before it, such lines cost ``features`` worn 0.994 -> 0.989 on the drive
        benchmark)."""
        if not len(self._ids) or not len(x):
            return
        tab = curve_table(self._x, self.filter.model_range)
        free = np.full(len(x), -1, dtype=np.int64)
        for _ in range(len(LINE_NAMES)):
            n = len(self._ids)
            self._birth(x, y, free, tab)
            if len(self._ids) == n:
                break

    def _same_lines(self, state: FloatArray) -> np.ndarray:
        """For each line of a new start ``state``, the current model's confirmed line
        within ``min_spacing`` [m] of it at the sensor (the same marking: the nearest,
        each taken once), -1: none. A restart replaces the shape; such a line keeps its
        id and, if higher than a start's, its confidence (a lane line seen for a while
        with its worn dashes is not a fresh line beside a narrow strip's other one)."""
        new = state[N_GEOMETRY:]
        off = self._x[N_GEOMETRY:]
        out = np.full(len(new), -1, dtype=np.int64)
        if len(new) == 0 or len(off) == 0:
            return out
        gap = np.abs(new[:, None] - off[None, :])
        gap[:, ~self._confirmed] = np.inf
        for flat in np.argsort(gap, axis=None, kind="stable"):
            i, j = divmod(int(flat), len(off))
            if gap[i, j] >= self.filter.min_spacing:
                break
            if out[i] < 0 and j not in out:
                out[i] = j
        return out

    def _inherited(self, state: FloatArray) -> dict[str, np.ndarray] | None:
        """The current model's confirmed lines that a new start ``state`` lacks: at
        least ``lane_spacing`` [m] from each of its lines at the sensor (where the two
        reference curves meet, so offsets compare), with their offsets, offset
        variances and bookkeeping (:meth:`_inherit`); None: none."""
        new = state[N_GEOMETRY:]
        off = self._x[N_GEOMETRY:]
        if len(off) == 0:
            return None
        gap = np.abs(off[:, None] - new[None, :]).min(axis=1) if len(new) else np.inf
        j = np.flatnonzero(self._confirmed & (gap >= self.filter.lane_spacing))
        if len(j) == 0:
            return None
        return {
            "offsets": off[j].copy(),
            "var": np.diag(self._p)[N_GEOMETRY + j].copy(),
            "ids": self._ids[j].copy(),
            "conf": self._conf[j].copy(),
            "miss": self._miss[j].copy(),
            "far": self._far[j].copy(),
            "span": self._span[j].copy(),
        }

    def _inherit(self, old: dict[str, np.ndarray]) -> None:
        """Carry lines of the replaced model (:meth:`_inherited`) into the new one: a
        restart replaces a shape that left the road far out, while the lines' offsets
        at the sensor were measured near the car. A line the single-frame ALDM did not
        report (hidden, worn, sparsely sampled) would otherwise be lost until a birth
        finds it again. Each keeps its id, confidence and history; its offset is
        uncorrelated with the new shape, with the variance it had."""
        self._append_lines(
            old["offsets"], old["var"], old["ids"], old["conf"], old["miss"], old["far"],
            np.ones(len(old["offsets"]), dtype=bool), old["span"],
        )  # fmt: skip

    def _append_lines(
        self,
        offsets: FloatArray,
        var: FloatArray,
        ids: np.ndarray,
        conf: FloatArray,
        miss: FloatArray,
        far: FloatArray,
        confirmed: np.ndarray,
        span: FloatArray,
    ) -> None:
        """Lines at ``offsets`` [m] added to the state, each uncorrelated with the
        shape and the other lines, of variance ``var`` [m^2], with their bookkeeping."""
        n, m = len(self._x), len(offsets)
        p = np.zeros((n + m, n + m))
        p[:n, :n] = self._p
        p[n:, n:] = np.diag(var)
        self._x = np.concatenate((self._x, offsets))
        self._p = p
        self._ids = np.concatenate((self._ids, ids))
        self._conf = np.concatenate((self._conf, conf))
        self._miss = np.concatenate((self._miss, miss))
        self._far = np.concatenate((self._far, far))
        self._confirmed = np.concatenate((self._confirmed, confirmed))
        self._span = np.vstack((self._span, span))

    def _receded(self, points: Any, far: FloatArray) -> bool:
        """Whether a confirmed line hit in this frame has its farthest point (``far``
        [m], -inf: no hit) more than ``recede_length`` short of where its farthest
        point of its last hit was carried (a *drop*): the sign of a shape that bent off
        the road far out, whose gates then miss the points that would bend it back. A
        line without a hit (hidden, or worn) is not evidence of that, nor is one a
        vehicle hides from within :data:`RECEDE_SHADOW` beyond where it is seen (the
        frame's ``points``, :meth:`_occlusion`)."""
        length = self.filter.recede_length
        if not receded(self._far, far, self._confirmed, length):
            return False
        drop = self._confirmed & (far > -math.inf) & (self._far - far > length)
        _, shadow = self._occlusion(points, beyond=far - OCCLUSION_STEP)
        return bool((drop & (shadow > far + RECEDE_SHADOW)).any())

    def _short_of_sight(self, points: Any, far: FloatArray) -> bool:
        """Whether a confirmed line hit in this frame has its farthest point (``far``
        [m], -inf: no hit) newly more than ``recede_length`` short of where the model
        puts it in view (:meth:`_sight`) and of where another line is seen: a shape
        that bent off the road over several frames, each hit's far end a little
        nearer, so that no one frame drops by ``recede_length`` (on ``motorway`` under
        the camera preset, seed 19: the far ends of three lines came nearer with the
        car's travel for a second, 76 -> 54 m, while the fourth was seen to 90 m, and
        the car left its lane). A line is examined once while it stays short: the
        restart decides whether the model holds.

        Only a frame given as a :class:`~aldm_gym.sensor.frame.SensorFrame` has a
        field of view; bare points give no sight and no such check."""
        length = self.filter.recede_length
        # plain lists: a handful of lines, checked every frame
        pairs = zip(far.tolist(), self._confirmed.tolist(), strict=True)
        ends = [f if c else -math.inf for f, c in pairs]
        reach = max(ends, default=-math.inf)
        short = [i for i, f in enumerate(ends) if -math.inf < f < reach - length]
        if short and isinstance(points, SensorFrame):
            sight = self._sight(points).tolist()
            short = [i for i in short if sight[i] - ends[i] > length]
        else:
            short = []
        ids = {int(self._ids[i]) for i in short}
        new = bool(ids - self._examined)
        self._examined = ids
        return new

    def _parallel_support(self, state: FloatArray, x: FloatArray, y: FloatArray) -> int:
        """How many of the points ``(x, y)`` [m] lie on lines parallel to the reference
        curve of ``state``: in a cluster of at least ``birth_points`` whose distances to
        the curve lie within ``birth_width`` (a line as a birth finds one).

        Markings are parallel, so the right shape gathers every line's points, those of
        lines the single-frame ALDM did not report (beyond its four, or dropped by a
        camera's gaps) included, while a shape bent onto clutter or onto a trace that
        jumped between lines spreads them. Only points within :data:`SCORE_REACH` of
        the curve count: the lines of the ego's lane and its neighbours, not those of
        an exit lane or another carriageway, which a shape bent onto them would
        gather."""
        return self._parallel_supports([state], x, y)[0]

    def _parallel_supports(
        self, states: list[FloatArray], x: FloatArray, y: FloatArray
    ) -> list[int]:
        """:meth:`_parallel_support` of each of ``states``, all counted on the same
        points: those within :data:`SCORE_REACH` of any of the curves. A shape bent
        far out can reach a line beyond the others' reach; counted on its own points
        it would gain that line, while the right shape lays it on a parallel line too
        once it counts it."""
        fp = self.filter
        if len(x) == 0:
            return [0] * len(states)
        offs = [project_on(curve_table(st, fp.model_range), x, y)[1] for st in states]
        near = np.zeros(len(x), dtype=bool)
        for off in offs:
            near |= np.abs(off) <= SCORE_REACH
        scores = []
        for off in offs:
            off = np.sort(off[near])
            end = np.searchsorted(off, off + fp.birth_width, side="right")
            # mark every point inside a window of enough points (a difference array)
            full = np.flatnonzero(end - np.arange(len(off)) >= fp.birth_points)
            cover = np.zeros(len(off) + 1, dtype=np.int64)
            np.add.at(cover, full, 1)
            np.add.at(cover, end[full], -1)
            scores.append(int(np.count_nonzero(np.cumsum(cover)[:-1])))
        return scores

    def _associate_update(
        self, x: FloatArray, y: FloatArray, state: FloatArray, cov: FloatArray
    ) -> tuple[FloatArray, FloatArray, np.ndarray, FloatArray, FloatArray, bool]:
        """:func:`~aldm_gym.sensor.aldm_kernels.model.associate_update` of ``(state,
        cov)`` with the points ``(x, y)`` and the filter's settings."""
        fp = self.filter
        return associate_update(
            x,
            y,
            state,
            cov,
            fp.point_std,
            fp.point_std_slope,
            fp.association_sigmas,
            fp.association_min,
            fp.association_max,
            fp.tukey,
            3,
            fp.model_range,
        )

    def _predict(self, dx: float, dy: float, dpsi: float, travel: float) -> None:
        """Move the model into the new sensor frame: the origin advances ``dx`` along
        the old x and ``dy`` along the old y [m], the axes turn by ``dpsi`` [rad]
        (:func:`~aldm_gym.sensor.aldm_kernels.model.predict`)."""
        fp = self.filter
        # new road enters the view at the far end: its curvature is unknown only where
        # points reach the last node step (else nothing measures it, and the hidden
        # lines carried on would only lose their certainty)
        q_far, trend = fp.q_far_curvature_rate, fp.far_curvature_trend
        if (q_far > 0.0 or trend > 0.0) and self._reach() < (N_NODES - 2) * NODE_STEP:
            q_far = trend = 0.0
        self._x, self._p = predict(
            self._x,
            self._p,
            dx,
            dy,
            dpsi,
            travel,
            self._q_shape,
            fp.q_offset,
            fp.q_width,
            q_far,
            trend,
        )
        self._far = self._far - dx

    def _reach(self) -> float:
        """The farthest x [m] a confirmed line hit in the last update was seen at
        (-inf: none)."""
        seen = self._far[self._confirmed & (self._miss == 0.0)]
        return float(np.max(seen)) if len(seen) else -math.inf

    def _sigma(self, x: FloatArray) -> FloatArray:
        """A point's lateral standard deviation at ``x`` [m]."""
        return self.filter.point_std + self.filter.point_std_slope * x

    def _correct(self, x: FloatArray, y: FloatArray) -> tuple[np.ndarray, FloatArray, FloatArray]:
        """Association and robust update with the frame's points
        (:func:`~aldm_gym.sensor.aldm_kernels.model.associate_update`): each point's
        line (-1: free, also for associated points given no weight), each line's
        support (the sum of its points' robust weights) and farthest point's x
        (-inf: none). The curvature-jump hypothesis (the prediction's shape covariance
        grown by ``jump_curvature``) is updated too and wins when its support is more
        than :data:`JUMP_MARGIN` higher, gained on at least :data:`JUMP_LINES` lines
        (fewer when fewer are seen as far out: :meth:`_jump_lines`) by
        :data:`JUMP_LINE_GAIN` each."""
        keep = self._one_stripe(x, y)
        if keep.all():
            return self._correct_points(x, y)
        kept, support, far = self._correct_points(x[keep], y[keep])
        line = np.full(len(x), -1, dtype=kept.dtype)
        line[keep] = kept
        return line, support, far

    def _correct_points(
        self, x: FloatArray, y: FloatArray
    ) -> tuple[np.ndarray, FloatArray, FloatArray]:
        """:meth:`_correct` with the points ``(x, y)`` [m] the stripe check kept."""
        state, cov, line, support, far, _ok = self._associate_update(x, y, self._x, self._p)
        if self._q_jump is not None and np.count_nonzero(line < 0) >= JUMP_LINES * JUMP_LINE_GAIN:
            # the nominal update left points unexplained (outside every gate, or given
            # no weight): try the jump
            jump = self._p.copy()
            jump[:N_GEOMETRY, :N_GEOMETRY] += self._q_jump
            alt = self._associate_update(x, y, self._x, jump)
            gain = alt[3] - support
            if float(gain.sum()) > JUMP_MARGIN and np.count_nonzero(
                gain >= JUMP_LINE_GAIN
            ) >= self._jump_lines(x, line, alt[2]):
                state, cov, line, support, far, _ok = alt
                self.n_jumps += 1
        self._x, self._p = state, cov
        self.n_used = int(np.count_nonzero(line >= 0))
        return line, support, far

    def _one_stripe(self, x: FloatArray, y: FloatArray) -> np.ndarray:
        """Which of the points ``(x, y)`` [m] the update may use: each line keeps the
        stripe of a double line it lies on near the sensor
        (:func:`~aldm_gym.sensor.aldm_kernels.model.one_stripe`, pairs within the
        gate's ``association_max`` of a line, :data:`STRIPE_GAP` apart at one
        station, decided within :data:`STRIPE_NEAR`)."""
        n = len(self._ids)
        if n == 0 or len(x) < 2 or not any_closer(x, y, math.hypot(STRIPE_GAP, STRIPE_STATION)):
            return np.ones(len(x), dtype=bool)
        s, off, _g = project_on(curve_table(self._x, self.filter.model_range), x, y)
        return one_stripe(
            s,
            off,
            self._x[N_GEOMETRY:],
            self.filter.association_max,
            STRIPE_GAP,
            STRIPE_STATION,
            STRIPE_NEAR,
        )

    def _jump_lines(self, x: FloatArray, line: np.ndarray, alt: np.ndarray) -> int:
        """How many lines must gain for the jump to win: :data:`JUMP_LINES`, or as many
        lines as have points (taken by either update) from the nearest x at which the
        jump takes a point the nominal update left free, if fewer. A line that is not
        seen that far (a vehicle hides it, or it is worn there) cannot confirm a bend
        there, nor contradict it."""
        gained = (alt >= 0) & (line < 0)
        if not gained.any():
            return JUMP_LINES
        far = x >= float(np.min(x[gained]))
        seen = np.union1d(line[far & (line >= 0)], alt[far & (alt >= 0)])
        return max(1, min(JUMP_LINES, len(seen)))

    def _fit(
        self, x: FloatArray, y: FloatArray, line: np.ndarray, x0: FloatArray, p0: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The start's update of the prior ``(x0, p0)`` with points ``(x, y)`` on lines
        ``line`` (:func:`~aldm_gym.sensor.aldm_kernels.model.fit`, Gauss-Newton,
        :data:`START_ITERATIONS` times)."""
        return fit(x, y, line, x0, p0, self._sigma(x), self.filter.tukey, START_ITERATIONS)

    def _occlusion(
        self, points: Any, beyond: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """How much of each line the vehicles leave in view in this frame, and where
        each line's first point hidden by one lies [m] (inf: none; with ``beyond``,
        the first at or beyond that x [m] per line), from the frame's ``occluders``
        and the sensor's own sight model (the line sensor's occlusion, on the model's
        lines every :data:`OCCLUSION_STEP` within the field of view).

        The first is the share of the line's length in the field of view that no
        vehicle blocks, 0 for a *hidden* line (less than :data:`HIDDEN_LENGTH` left in
        view) and 1 where no vehicle blocks any of it (or none of it is in the field
        of view): how far a miss in this frame is evidence that the line is gone
        (:meth:`_existence`). A frame given as bare points, or without occluders,
        hides nothing (all 1)."""
        n = len(self._ids)
        seen = np.ones(n)
        shadow = np.full(n, math.inf)
        if not isinstance(points, SensorFrame) or n == 0:
            return seen, shadow
        world = occluder_array(np.asarray(points.occluders, dtype=np.float64))
        if len(world) == 0:
            return seen, shadow
        grid = self._view(points, world)
        if grid is None:
            return seen, shadow
        xs, in_view, blocked = grid
        visible = in_view & ~blocked
        left, span = visible.sum(axis=1), in_view.sum(axis=1)
        hidden = blocked.any(axis=1) & (left * OCCLUSION_STEP < HIDDEN_LENGTH)
        # a line with nothing in the field of view is missed whole, as without vehicles
        seen = np.where(hidden, 0.0, np.where(span > 0, left / np.maximum(span, 1), 1.0))
        if beyond is not None:
            blocked &= xs[None, :] >= np.asarray(beyond)[:, None]
        first = np.where(blocked.any(axis=1), np.argmax(blocked, axis=1), -1)
        shadow = np.where(first >= 0, xs[np.maximum(first, 0)], math.inf)
        return seen, shadow

    def _sight(self, points: Any) -> FloatArray:
        """How far [m] each line is in view: the farthest x, every
        :data:`OCCLUSION_STEP` from the frame's ``fov_start`` to ``model_range``,
        where the model puts it within the field of view and no vehicle hides it
        (-inf: nowhere, or ``points`` are bare points, without a field of view)."""
        n = len(self._ids)
        if not isinstance(points, SensorFrame) or n == 0:
            return np.full(n, -math.inf)
        world = occluder_array(np.asarray(points.occluders, dtype=np.float64))
        grid = self._view(points, world)
        if grid is None:
            return np.full(n, -math.inf)
        xs, in_view, blocked = grid
        visible = in_view & ~blocked
        last = len(xs) - 1 - np.argmax(visible[:, ::-1], axis=1)
        return np.where(visible.any(axis=1), xs[last], -math.inf)

    def _view(
        self, points: SensorFrame, world: FloatArray
    ) -> tuple[FloatArray, np.ndarray, np.ndarray] | None:
        """The model's lines every :data:`OCCLUSION_STEP` from the frame's
        ``fov_start`` to ``model_range`` (or its ``range``): the x [m], and per line
        and x whether the line is within the field of view and whether a vehicle of
        ``world`` (:func:`~aldm_gym.sensor.conditions.occluder_array`) blocks the
        sight of it there (the line sensor's own occlusion); None: no such x.

        :raises InputError: a frame with occluders and a non-finite pose or range.
        """
        n = len(self._ids)
        ranged = (
            math.isfinite(points.fov_start)
            and math.isfinite(points.range)
            and points.range > points.fov_start >= 0.0
        )
        if len(world):
            pose = (*np.ravel(points.origin)[:2], points.yaw, points.mount_position[2])
            if not (len(np.ravel(points.origin)) == 2 and np.isfinite(pose).all() and ranged):
                raise InputError(
                    "a frame with occluders needs a finite origin (2,), yaw, mount height "
                    f"and 0 <= fov_start < range, got origin {points.origin}, yaw "
                    f"{points.yaw}, fov_start {points.fov_start}, range {points.range}"
                )
        elif not ranged:
            return None
        x0 = float(points.fov_start)
        x1 = min(self.filter.model_range, float(points.range))
        k = int((x1 - x0) / OCCLUSION_STEP) + 1
        if k < 2:
            return None
        x1 = x0 + (k - 1) * OCCLUSION_STEP
        tab = curve_table(self._x, self.filter.model_range)
        pts = draw_on(tab, self._x, np.arange(n, dtype=np.int64), x0, np.full(n, x1), k)
        xs = np.ascontiguousarray(pts[0, :, 0])
        ys = np.ascontiguousarray(pts[:, :, 1])
        lateral = np.abs(ys)
        in_view = (
            np.isfinite(ys)
            & (lateral <= xs * math.tan(points.fov_half_angle))
            & (lateral <= points.max_lateral)
        )
        if len(world) == 0:
            return xs, in_view, np.zeros_like(in_view)
        seen = ys.copy()
        _occlude(
            xs,
            seen,
            np.zeros(n),
            np.ascontiguousarray(world),
            float(points.origin[0]),
            float(points.origin[1]),
            float(points.yaw),
            x1 + 10.0,
            float(points.mount_position[2]),
        )
        return xs, in_view, in_view & np.isnan(seen)

    def _existence(
        self, support: FloatArray, far: FloatArray, travel: float, seen: FloatArray
    ) -> None:
        """Hits and misses (a missed line loses confidence and counts travel towards
        ``drop_length`` in proportion to ``seen``, the share of it the vehicles left in
        view, :meth:`_occlusion`: a hidden line neither loses nor counts), the lines'
        far ends (``far``: the farthest point of each line in the frame [m]), and the
        lines dropped (:func:`~aldm_gym.sensor.aldm_kernels.model.existence`)."""
        fp = self.filter
        keep = existence(
            support,
            far,
            self._conf,
            self._miss,
            self._far,
            self._confirmed,
            self._ids,
            self._x[N_GEOMETRY:],
            seen,
            travel,
            fp.hit_gain,
            fp.miss_loss,
            fp.min_confidence,
            fp.drop_length,
            fp.max_offset,
            fp.min_spacing,
            fp.lane_spacing,
            MIN_SUPPORT,
        )
        if not keep.all():
            self._keep(keep)

    def _keep(self, keep: np.ndarray) -> None:
        """Drop the lines not in ``keep`` from the state and the bookkeeping."""
        idx = np.concatenate((np.arange(N_GEOMETRY), N_GEOMETRY + np.flatnonzero(keep)))
        self._x = self._x[idx]
        self._p = self._p[np.ix_(idx, idx)]
        self._ids, self._conf = self._ids[keep], self._conf[keep]
        self._miss, self._far = self._miss[keep], self._far[keep]
        self._confirmed = self._confirmed[keep]
        self._span = self._span[keep]

    def _birth(self, x: FloatArray, y: FloatArray, line: np.ndarray, tab: FloatArray) -> None:
        """New lines from clusters of the points no line took, by their distance to
        the reference curve tabulated in ``tab``: at most one per call (once a frame
        after the update; up to four times before it on a fresh start,
        :meth:`_start_births`). A cluster of
        ``birth_points`` spanning ``birth_span``, or, where the lines' spacing puts a
        line the model lacks (:meth:`_expected_lines`), of :data:`SHORT_BIRTH_POINTS`
        spanning :data:`SHORT_BIRTH_SPAN` (one dash), confirmed at once (the lane's
        structure corroborates it)."""
        fp = self.filter
        free = (line < 0) & (x <= fp.birth_range)
        if np.count_nonzero(free) < min(fp.birth_points, SHORT_BIRTH_POINTS):
            return
        fx = x[free]
        _s, off, _g = project_on(tab, fx, y[free])
        order = np.argsort(off, kind="stable")
        off, fx = off[order], fx[order]
        # clusters: windows of birth_width starting at each point, largest first
        end = np.searchsorted(off, off + fp.birth_width, side="right")
        count = end - np.arange(len(off))
        lines = self._x[N_GEOMETRY:]
        expected: FloatArray | None = None
        near_expected = np.zeros(0, dtype=bool)
        for i in np.argsort(-count, kind="stable"):
            if count[i] < min(fp.birth_points, SHORT_BIRTH_POINTS):
                return
            members = slice(i, end[i])
            full = count[i] >= fp.birth_points
            if not full:
                # a short cluster counts only near where a line is expected
                if expected is None:
                    expected, near_expected = self._near_expected(off, end)
                if not len(expected):
                    return  # the rest are short too
                if not near_expected[i]:
                    continue
            centre = float(np.median(off[members]))
            span = float(np.ptp(fx[members]))
            extent = (float(np.min(fx[members])), float(np.max(fx[members])))
            if abs(centre) > fp.max_offset:
                continue
            # the nearest line, and whether the cluster is closer to it than lane_spacing
            j = int(np.argmin(np.abs(lines - centre))) if len(lines) else -1
            gap = abs(lines[j] - centre) if j >= 0 else math.inf
            crowded = gap < fp.lane_spacing
            if full and span >= fp.birth_span:
                if crowded:
                    regular = self._regular(j, centre)
                    if regular and 0.0 < fp.reseat_length <= self._miss[j]:
                        self._reseat(j, centre, extent[1])
                        self._span[j] = extent
                        return
                    # a narrow strip: a lane line inside the one the model holds there
                    # (its widths more regular), or the road's edge line outside it
                    side = 1.0 if centre >= 0.0 else -1.0
                    edge = not np.any(side * lines > abs(centre))
                    if gap < fp.min_spacing or not (regular or edge):
                        continue
            else:
                # short evidence where the lines' spacing puts a line the model lacks
                if count[i] < SHORT_BIRTH_POINTS or span < SHORT_BIRTH_SPAN or crowded:
                    continue
                if expected is None:
                    expected, near_expected = self._near_expected(off, end)
                if not len(expected) or float(np.min(np.abs(expected - centre))) > fp.birth_width:
                    continue
                # the lane's structure corroborates it: confirmed at once
                self._add_line(centre, extent[1])
                self._span[-1] = extent
                self._conf[-1] = max(fp.birth_confidence, fp.min_confidence)
                self._confirmed[-1] = True
                self.n_reborn += 1
                return
            self._add_line(centre, extent[1])
            self._span[-1] = extent
            return

    def _near_expected(self, off: FloatArray, end: np.ndarray) -> tuple[FloatArray, np.ndarray]:
        """:meth:`_expected_lines`, and for each cluster window ``off[i:end[i]]`` of
        the sorted free offsets ``off`` [m] whether its middle lies within twice
        ``birth_width`` of one (a cheap first test before its median)."""
        expected = self._expected_lines()
        if not len(expected) or not len(off):
            return expected, np.zeros(len(off), dtype=bool)
        mids = 0.5 * (off + off[end - 1])
        gap = np.min(np.abs(mids[:, None] - expected[None, :]), axis=1)
        return expected, gap <= 2.0 * self.filter.birth_width

    def _expected_lines(self) -> FloatArray:
        """Offsets [m] where the confirmed lines' spacing puts a line the model lacks:
        one spacing beside each confirmed line, at least ``lane_spacing`` from every
        line and within ``max_offset``. The spacing is the median of the gaps between
        neighbouring confirmed lines that are no narrow strip (at least
        ``lane_spacing``), each divided by the number of lanes it spans: its ratio,
        rounded, to the median of the gaps one lane can be (at most the ALDM's
        ``max_lane_width``; :data:`~aldm_gym.sensor.trajectory.DEFAULT_LANE_WIDTH`
        without one). A gap of two lanes (a line missing between them) is two
        spacings; without any gap the spacing is ``DEFAULT_LANE_WIDTH``."""
        fp = self.filter
        lines = self._x[N_GEOMETRY:]
        shown = np.sort(lines[self._confirmed])
        if len(shown) == 0:
            return np.zeros(0)
        # the spacing: each gap between neighbouring confirmed lines that is no narrow
        # strip, over the number of lanes it spans (a missing line between two lanes of
        # 3.75 m: 7.5 m, two spacings), counted in the median of the gaps one lane can
        # be (up to max_lane_width: a hard shoulder's 2.5 m beside 3.75 m lanes moves
        # that median, but does not set it alone, as the narrowest gap would)
        gaps = np.diff(shown)
        gaps = gaps[gaps >= fp.lane_spacing]
        single = gaps[gaps <= self.params.max_lane_width]
        unit = float(np.median(single)) if len(single) else DEFAULT_LANE_WIDTH
        if len(gaps):
            lanes = np.maximum(np.round(gaps / unit), 1.0)
            ref = float(np.median(gaps / lanes))
        else:
            ref = DEFAULT_LANE_WIDTH
        cand = np.concatenate((shown - ref, shown + ref))
        far_from_all = np.min(np.abs(cand[:, None] - lines[None, :]), axis=1) >= fp.lane_spacing
        return cand[far_from_all & (np.abs(cand) <= fp.max_offset)]

    def _regular(self, j: int, offset: float) -> bool:
        """Whether line ``j`` at ``offset`` [m] makes the lane widths more regular than
        where it is: the squared differences of its spacings to its neighbours from
        the median spacing of the other neighbouring lines (the default lane width
        without such) fall. A hidden line carried at the right width is not moved
        onto a seam or an old marking inside the lane; a line born on clutter is.
        Lines closer than ``lane_spacing`` to line ``j`` (a narrow strip's other
        line, a seam held beside it) are no lane's border here."""
        lines = self._x[N_GEOMETRY:]
        strip = np.abs(lines - lines[j]) < self.filter.lane_spacing
        strip[j] = False
        if strip.any():
            lines = lines[~strip]
            j -= int(np.count_nonzero(strip[:j]))
        order = np.argsort(lines, kind="stable")
        gaps = [
            float(lines[b] - lines[a]) for a, b in itertools.pairwise(order) if a != j and b != j
        ]
        ref = float(np.median(gaps)) if gaps else DEFAULT_LANE_WIDTH
        others = np.sort(np.delete(lines, j))

        def cost(y0: float) -> float:
            left = others[others > y0]
            right = others[others < y0]
            c = 0.0
            if len(left):
                c += (float(left[0]) - y0 - ref) ** 2
            if len(right):
                c += (y0 - float(right[-1]) - ref) ** 2
            return c

        return cost(offset) < cost(float(lines[j]))

    def _reseat(self, j: int, offset: float, far: float) -> None:
        """Line ``j`` set onto ``offset`` [m]: uncorrelated with the rest, 0.3 m
        uncertain; id, role and confidence kept."""
        k = N_GEOMETRY + j
        self._x[k] = offset
        self._p[k, :] = 0.0
        self._p[:, k] = 0.0
        self._p[k, k] = 0.3**2
        self._far[j] = far
        self.n_reseated += 1

    def _add_line(self, offset: float, far: float) -> None:
        """A new line at ``offset`` [m]: uncorrelated with the shape, 0.3 m uncertain."""
        self._append_lines(
            np.array([offset]), np.array([0.3**2]),
            np.array([self._next_id], dtype=np.int64),
            np.array([self.filter.birth_confidence]), np.zeros(1), np.array([far]),
            np.zeros(1, dtype=bool), np.full((1, 2), np.nan),
        )  # fmt: skip
        self._next_id += 1
        self.n_born += 1

    # -- output ------------------------------------------------------------------------

    def _roles(self) -> list[int]:
        """The model's line index of each role in :data:`LINE_NAMES` order (-1: none)."""
        offsets = self._x[N_GEOMETRY:].tolist()
        shown = [i for i, c in enumerate(self._confirmed.tolist()) if c]
        left = sorted((i for i in shown if offsets[i] > 0.0), key=offsets.__getitem__)
        right = sorted((i for i in shown if offsets[i] <= 0.0), key=lambda i: -offsets[i])
        if left and right:
            # the nearest lines on both sides wider apart than a lane: an ego line is
            # missing (dropped, not yet born); the farther one is the adjacent line
            # of its side, not an ego line of a lane twice as wide
            if offsets[left[0]] - offsets[right[0]] > self.params.max_lane_width:
                if offsets[left[0]] > -offsets[right[0]]:
                    left.insert(0, -1)
                else:
                    right.insert(0, -1)
        pick = [-1, -1, -1, -1]
        if left:
            pick[1] = left[0]
            pick[0] = self._adjacent(left, offsets)
        if right:
            pick[2] = right[0]
            pick[3] = self._adjacent(right, offsets)
        return pick

    def _adjacent(self, side: list[int], offsets: list[float]) -> int:
        """The adjacent line of one side, whose lines ``side`` run outwards from the
        ego line (-1: an ego line missing): the first at least the ALDM's
        ``min_lane_width`` beyond it, if it is at most ``max_lane_width`` beyond it (the
        single frame's rule). A narrower strip (a shoulder's edge line beside the lane
        line) is no lane, nor is a wider one (a median between two edge lines; -1:
        none)."""
        if len(side) < 2:
            return -1
        if side[0] < 0:
            return side[1]
        for i in side[1:]:
            gap = abs(offsets[i] - offsets[side[0]])
            if gap >= self.params.min_lane_width:
                return i if gap <= self.params.max_lane_width else -1
        return -1

    def _detection(
        self, near: float, shadow: FloatArray | None = None, tab: FloatArray | None = None
    ) -> ModelLaneDetection:
        """The model drawn as a detection: 13 points per line (``n_points`` of the
        ALDM's parameters) from ``near`` to the line's far end (and no farther than
        where it gets steeper than the ALDM's ``max_slope``; a line a vehicle hides
        from ``shadow`` [m] on, beyond where it was seen, farther: see
        :data:`CARRY_STD`; None: no vehicle hides any), on the reference curve
        tabulated in ``tab`` (None: tabulated here)."""
        fp = self.filter
        if shadow is None:
            shadow = np.full(len(self._ids), math.inf)
        if tab is None:
            tab = curve_table(self._x, fp.model_range)
        n_points = self.params.n_points if self.params.n_points >= 2 else 13
        roles = self._roles()
        end = _end_row(tab, self.params.max_slope, fp.model_range)
        shared = self._reach()
        # where any confirmed line was last seen, carried by the odometry
        carried = self._far[self._confirmed]
        last_seen = float(np.max(carried)) if len(carried) else -math.inf
        fields: dict[str, FloatArray] = {}
        conf = np.zeros(len(LINE_NAMES))
        ids = [-1] * len(LINE_NAMES)
        measured = np.full((len(LINE_NAMES), 2), np.nan)
        lateral_std = np.full((len(LINE_NAMES), n_points), np.nan)
        drawn: list[tuple[int, int, float]] = []
        carried_from: dict[int, float] = {}
        for r in range(len(LINE_NAMES)):
            i = roles[r]
            if i < 0:
                continue
            own = float(self._far[i])
            if shadow[i] <= max(own, near) + HIDDEN_LENGTH:
                # a vehicle hides the line beyond where it was last seen: it goes on
                # as far as any line is seen, or was last seen
                far = fp.model_range
                carried_from[i] = max(own, shared, last_seen)
            else:
                far = min(fp.model_range, max(own, min(shared, own + fp.extend_length)))
            far = min(far, _end_x(tab, end, float(self._x[N_GEOMETRY + i])))
            if far - near >= MIN_EXTENT:
                drawn.append((r, i, far))
        if drawn:
            # every drawn line at once: (n_points, lines) x and y
            idx = np.array([i for _, i, _ in drawn], dtype=np.int64)
            fars = np.array([far for *_, far in drawn])
            pts = draw_on(tab, self._x, idx, near, fars, n_points)
            std = self._lateral_std(tab, pts, idx)
            cut = False
            for c, (_r, i, _f) in enumerate(drawn):
                if i not in carried_from:
                    continue
                # a hidden line is carried past where any line was seen only as far as
                # the model is sure of it
                unsure = (pts[c, :, 0] > carried_from[i]) & (std[c] > CARRY_STD)
                if unsure.any():
                    k = int(np.argmax(unsure))
                    fars[c] = max(float(pts[c, max(k - 1, 0), 0]), carried_from[i])
                    cut = True
            if cut:
                # a line cut shorter than MIN_EXTENT is not drawn
                long = fars - near >= MIN_EXTENT
                drawn = [d for d, ok in zip(drawn, long.tolist(), strict=True) if ok]
                idx, fars = idx[long], fars[long]
                pts = draw_on(tab, self._x, idx, near, fars, n_points)
                std = self._lateral_std(tab, pts, idx)
            for c, (r, i, _) in enumerate(drawn):
                fields[LINE_NAMES[r]] = pts[c]
                conf[r] = self._conf[i]
                ids[r] = int(self._ids[i])
                measured[r] = self._span[i]
                lateral_std[r] = std[c]
        left, right = fields.get("ego_left"), fields.get("ego_right")
        width = DEFAULT_LANE_WIDTH
        if left is not None and right is not None:
            width = float(left[0, 1] - right[0, 1])
        empty = np.zeros((0, 2))
        traj = driving_trajectory(
            left if left is not None else empty,
            right if right is not None else empty,
            width,
            PATH_STEP,
            self.path_range,
        )
        base = LaneDetection.trusted(**fields, trajectory=traj, source="aldm")
        det = object.__new__(ModelLaneDetection)
        for name in (*LINE_NAMES, "trajectory", "source"):
            object.__setattr__(det, name, getattr(base, name))
        object.__setattr__(det, "confidence", conf)
        object.__setattr__(det, "ids", tuple(ids))
        object.__setattr__(det, "measured", measured)
        object.__setattr__(det, "lateral_std", lateral_std)
        self._last_ids = tuple(ids)
        return det

    def _lateral_std(self, tab: FloatArray, pts: FloatArray, idx: np.ndarray) -> FloatArray:
        """``(lines, n)`` the standard deviation [m] of the lateral position of the
        drawn points ``pts`` (``(lines, n, 2)``) of the model lines ``idx``: a point of
        line ``i`` is where ``l = y0_i``, so its variance is that of ``y0_i - l`` by the
        state's covariance (the measurement row of a point on the line)."""
        x = np.ascontiguousarray(pts[:, :, 0])
        y = np.ascontiguousarray(pts[:, :, 1])
        return lateral_std(tab, x, y, np.asarray(idx, dtype=np.int64), self._p)

    @property
    def ids(self) -> tuple[int, ...]:
        """The id of each role's line in the last detection, in :data:`LINE_NAMES`
        order (-1: none), as :attr:`LaneTracker.ids <aldm_gym.sensor.tracking.
        LaneTracker.ids>`."""
        return self._last_ids


__all__ = [
    "CARRY_STD",
    "FILTER_KEYS",
    "HIDDEN_LENGTH",
    "JUMP_LINES",
    "JUMP_LINE_GAIN",
    "JUMP_MARGIN",
    "MIN_SUPPORT",
    "OCCLUSION_STEP",
    "RESTART_MARGIN",
    "SHORT_BIRTH_POINTS",
    "SHORT_BIRTH_SPAN",
    "STATE_LAYOUT",
    "FilterParams",
    "LaneModelFilter",
    "ModelLaneDetection",
    "split_aldm_params",
    "split_filter_params",
]
