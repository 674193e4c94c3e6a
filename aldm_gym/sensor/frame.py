"""What a CarMaker-like line sensor reports in one frame.

Mirrors the output listed in the paper (§"Line Sensor Model") and CarMaker's
``tLineSensor``: per side (left ``LLines``, right ``RLines``) up to 100 line
objects, each with type, colour index, height and points ``ds[p] = (x, y, z)``;
the number of lines per side; a 30-point list of the relevant line per side; the
time stamp; and the sensor's mount and its additional external rotation and
travel. Coordinates: ISO 8855 sensor frame, x forward, y left, z up [m]; ``z`` is
the height above the road surface (paint ~0, barriers > 0).

Fields marked *ground truth* are known only in simulation (which painted marking
and which dash an object comes from). Detectors must not use them; metrics and
plots may. One exception: the lane-model filter reads ``occluders`` (with ``origin``
and ``yaw``) as the object list of a car's object fusion, to tell a line a vehicle
hides from one that is gone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.roads.markings import MarkingType
from aldm_gym.types import FloatArray

_EMPTY3 = np.zeros((0, 3))


@dataclass(frozen=True)
class LineObject:
    """One detected line object (``LineSensor[m].LLines.L[n]`` in CarMaker).

    :ivar ds: ``(K, 3)`` points (x, y, z) in the sensor frame [m], sorted by x,
        about one every 2 m of x (``ds[p]``).
    :ivar type: line type (1 continuous, 2 dashed, 3 dotted).
    :ivar colour: user-defined colour index.
    :ivar height: object height [m] (> 0 for barriers).
    :ivar width: painted width [m].
    :ivar marking: *ground truth*: index of the road marking it belongs to.
    :ivar piece: *ground truth*: index of the dash along that marking, or -1 when
        the object is a whole marking.
    """

    ds: FloatArray
    type: MarkingType
    colour: int
    height: float
    width: float
    marking: int
    piece: int = -1

    @property
    def n_points(self) -> int:
        """Number of points."""
        return int(self.ds.shape[0])


@dataclass(frozen=True)
class SideLines:
    """The line objects CarMaker assigns to one side (``LLines`` or ``RLines``).

    An object belongs to the right side when its first visible point lies right of
    the car's middle axis (``y < axis_y``, see :attr:`SensorFrame.axis_y`), otherwise
    to the left, a point on the axis included (paper §"Line Sensor Model": "Is the
    beginning of the line on the right side of the middle axis it is assigned to
    the right side, otherwise to the left").

    :ivar lines: the objects, ordered by the x of their first point, then by its
        distance to the middle axis.
    :ivar relevant: index in ``lines`` of the relevant line, the one whose first
        point is nearest to the vehicle's middle axis (smallest ``|y - axis_y|``);
        -1 if none.
    :ivar relevant_points: ``(<= 30, 3)`` first points of the relevant line [m].
    """

    lines: tuple[LineObject, ...] = ()
    relevant: int = -1
    relevant_points: FloatArray = field(default_factory=lambda: _EMPTY3.copy())

    @property
    def n_lines(self) -> int:
        """Number of line objects on this side (``nLine``)."""
        return len(self.lines)

    @property
    def relevant_line(self) -> LineObject | None:
        """The relevant line object, or ``None``."""
        return self.lines[self.relevant] if self.relevant >= 0 else None


@dataclass(frozen=True)
class SensorFrame:
    """One measurement of a line sensor, stored as flat arrays (CarMaker's C layout).

    Line objects ``0 .. n_left - 1`` are the left side (``LLines``), the rest the
    right side (``RLines``); object ``n`` owns points
    ``all_points[line_start[n]:line_start[n + 1]]``. :attr:`left`, :attr:`right` and
    :attr:`lines` give the same content as :class:`LineObject` records.

    :ivar timestamp: simulation time of the measurement [s].
    :ivar sensor_index: ``m``: 0 for the forward sensor, 1 for a backward one, ...
    :ivar all_points: ``(N, 3)`` every point (x, y, z) [m], grouped by object.
    :ivar line_start: ``(L + 1,)`` offsets of each object's points in ``all_points``.
    :ivar line_type: ``(L,)`` line types (1 continuous, 2 dashed, 3 dotted).
    :ivar line_colour: ``(L,)`` colour indices.
    :ivar line_height: ``(L,)`` heights [m].
    :ivar line_width: ``(L,)`` painted widths [m].
    :ivar line_marking: ``(L,)`` *ground truth* marking index of each object.
    :ivar line_piece: ``(L,)`` *ground truth* dash index (-1 for a whole marking).
    :ivar n_left: number of objects on the left side.
    :ivar relevant_left: index (within the left side) of its relevant line, or -1.
    :ivar relevant_right: index (within the right side) of its relevant line, or -1.
    :ivar relevant_points: length of the relevant-line point lists (30).
    :ivar mount_position: sensor position in the vehicle frame (x, y, z) [m].
    :ivar mount_rotation: sensor orientation in the vehicle frame (roll, pitch, yaw) [rad].
    :ivar ext_rotation: additional external rotation in the mount frame (roll, pitch, yaw) [rad].
    :ivar ext_travel: additional external travel in the mount frame (x, y, z) [m].
    :ivar origin: *ground truth*: world position of the sensor (2,) [m].
    :ivar yaw: *ground truth*: world heading of the sensor's x axis [rad].
    :ivar range: range of view [m].
    :ivar fov_start: x of the nearest detectable point [m].
    :ivar fov_half_angle: half the horizontal angle of view [rad]: points were seen
        where ``|y| <= x tan(fov_half_angle)``.
    :ivar max_lateral: the sensor's extra lateral limit [m] (``inf``: none).
    :ivar axis_y: y of the car's middle axis in the sensor frame [m] (``-mount_y`` for
        a forward sensor); sides and relevant lines are judged against it.
    :ivar occluders: *ground truth*: ``(V, 6)`` world footprints ``(x, y, heading,
        length, width, height)`` [m, rad] of the vehicles the sensor's occlusion model
        hid points behind, in highway-env's world frame as ``origin`` and ``yaw``
        (``(0, 6)``: occlusion off, or no vehicle). The stand-in for the object list
        of the car's object fusion: the lane-model filter reads it to tell a line
        hidden by a vehicle from one that is no longer there.
    """

    timestamp: float
    sensor_index: int
    all_points: FloatArray
    line_start: np.ndarray
    line_type: np.ndarray
    line_colour: np.ndarray
    line_height: FloatArray
    line_width: FloatArray
    line_marking: np.ndarray
    line_piece: np.ndarray
    n_left: int
    relevant_left: int
    relevant_right: int
    relevant_points: int
    mount_position: FloatArray
    mount_rotation: FloatArray
    ext_rotation: FloatArray
    ext_travel: FloatArray
    origin: FloatArray
    yaw: float
    range: float
    fov_start: float
    fov_half_angle: float = 0.5 * np.pi
    max_lateral: float = np.inf
    axis_y: float = 0.0
    occluders: FloatArray = field(default_factory=lambda: np.zeros((0, 6)))

    @property
    def n_lines(self) -> int:
        """Total number of line objects."""
        return len(self.line_type)

    def line(self, n: int) -> LineObject:
        """Object ``n`` (global index: left side first) as a :class:`LineObject`."""
        if not 0 <= n < self.n_lines:
            raise IndexError(f"line index {n} out of range [0, {self.n_lines})")
        a, b = self.line_start[n], self.line_start[n + 1]
        return LineObject(
            ds=self.all_points[a:b],
            type=MarkingType(int(self.line_type[n])),
            colour=int(self.line_colour[n]),
            height=float(self.line_height[n]),
            width=float(self.line_width[n]),
            marking=int(self.line_marking[n]),
            piece=int(self.line_piece[n]),
        )

    def line_points(self, n: int) -> FloatArray:
        """``(K, 3)`` points of object ``n`` (global index) [m]."""
        return self.all_points[self.line_start[n] : self.line_start[n + 1]]

    @cached_property
    def lines(self) -> tuple[LineObject, ...]:
        """All objects, left side first."""
        return tuple(self.line(n) for n in range(self.n_lines))

    def _side_lines(self, left: bool) -> SideLines:
        lo, hi = (0, self.n_left) if left else (self.n_left, self.n_lines)
        rel = self.relevant_left if left else self.relevant_right
        lines = self.lines[lo:hi]
        pts = lines[rel].ds[: self.relevant_points] if rel >= 0 else _EMPTY3.copy()
        return SideLines(lines, rel, pts)

    @cached_property
    def left(self) -> SideLines:
        """Objects assigned to the left side (``LLines``)."""
        return self._side_lines(True)

    @cached_property
    def right(self) -> SideLines:
        """Objects assigned to the right side (``RLines``)."""
        return self._side_lines(False)

    def side(self, name: str) -> SideLines:
        """``"left"`` or ``"right"`` side."""
        if name not in ("left", "right"):
            raise InputError(f"side must be 'left' or 'right', got {name!r}")
        return self.left if name == "left" else self.right

    def side_offsets(self) -> FloatArray:
        """``(L,)`` signed distance of each object's first point from the middle axis [m].

        Positive (or zero) on the left side, negative on the right: ``y - axis_y``.
        """
        return self.all_points[self.line_start[:-1], 1] - self.axis_y

    def relevant_line_points(self, name: str) -> FloatArray:
        """All points of the relevant line of side ``name`` (``(K, 3)``, empty if none)."""
        if name not in ("left", "right"):
            raise InputError(f"side must be 'left' or 'right', got {name!r}")
        rel = self.relevant_left if name == "left" else self.relevant_right
        if rel < 0:
            return _EMPTY3.copy()
        return self.line_points(rel if name == "left" else self.n_left + rel)

    def points(self) -> FloatArray:
        """Every point of every object pooled, ``(N, 3)`` (x, y, z) [m], side grouping dropped."""
        return self.all_points
