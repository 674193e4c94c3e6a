"""Boundary points in and out of the protobuf wire format, in bulk.

A lane boundary in view has hundreds of ``BoundaryPoint``s. Built or read one field at
a time through the bindings they cost about 0.7 µs per point and field access, which
made the points most of a trace's cost (``benchmarks/bench_osi.py``). The points have
one fixed, tiny layout, so:

* :func:`encode_points` writes the repeated field's bytes with numpy, and the caller
  appends them to a message with the bindings' own ``MergeFromString`` (protobuf
  appends repeated fields on merge), so the message is still parsed and checked by
  the official code;
* :func:`decode_points` reads ``position.x``, ``position.y`` and ``dash`` of every
  point from a serialized ``LaneBoundary`` (``SerializeToString()``) in one compiled
  pass that follows the wire format (any field order, absent fields at their
  defaults, unknown fields skipped), the same values the bindings give.

Both are tested against the bindings (``tests/osi/test_wire.py``).
"""

from __future__ import annotations

import numba
import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.types import FloatArray


def _layout(dash: bool, size: bool) -> np.dtype:
    """A BoundaryPoint as a repeated entry: position (x, y, z), then optionally width
    and height (fixed64) and the dash state (varint 0–5), packed."""
    fields = [
        ("tag", "u1"),  # the repeated field's key, wire type 2 (length-delimited)
        ("size", "u1"),  # the BoundaryPoint's length
        ("pos_tag", "u1"),  # position = 1, wire type 2
        ("pos_size", "u1"),  # 27 bytes of Vector3d
        ("x_tag", "u1"),
        ("x", "<f8"),
        ("y_tag", "u1"),
        ("y", "<f8"),
        ("z_tag", "u1"),
        ("z", "<f8"),
    ]
    if size:
        fields += [("w_tag", "u1"), ("w", "<f8"), ("h_tag", "u1"), ("h", "<f8")]
    if dash:
        fields += [("dash_tag", "u1"), ("dash", "u1")]  # dash = 4, varint
    return np.dtype(fields)


_LAYOUTS = {(d, w): _layout(d, w) for d in (False, True) for w in (False, True)}


def encode_points(
    field: int,
    x: FloatArray,
    y: FloatArray,
    dash: np.ndarray | None = None,
    *,
    z: float = 0.0,
    width: float | None = None,
    height: float | None = None,
) -> bytes:
    """The bytes of ``len(x)`` ``BoundaryPoint``s as entries of repeated field ``field``
    (``LaneBoundary.boundary_line`` is 2, ``DetectedLaneBoundary.boundary_line`` 3):
    ``position = (x, y, z)``, ``width`` and ``height`` on every point when given
    (both or neither), and ``dash`` (0–5) when given.

    :raises InputError: ``x``, ``y`` and ``dash`` of different lengths, a dash state
        outside 0–5, or only one of width and height.
    """
    n = len(x)
    if len(y) != n or (dash is not None and len(dash) != n):
        raise InputError("x, y and dash must have one value per point")
    if (width is None) != (height is None):
        raise InputError("give both width and height, or neither")
    sized = width is not None
    out = np.zeros(n, dtype=_LAYOUTS[(dash is not None, sized)])
    out["tag"] = (field << 3) | 2
    out["size"] = out.itemsize - 2
    out["pos_tag"], out["pos_size"] = (1 << 3) | 2, 27
    out["x_tag"], out["y_tag"], out["z_tag"] = (1 << 3) | 1, (2 << 3) | 1, (3 << 3) | 1
    out["x"], out["y"], out["z"] = x, y, z
    if sized:
        out["w_tag"], out["h_tag"] = (2 << 3) | 1, (3 << 3) | 1
        out["w"], out["h"] = width, height
    if dash is not None:
        d = np.asarray(dash)
        if len(d) and (d.min() < 0 or d.max() > 5):
            raise InputError("dash states are 0..5")
        out["dash_tag"] = (4 << 3) | 0
        out["dash"] = d
    return out.tobytes()


@numba.njit(cache=True)
def _varint(buf: np.ndarray, i: int) -> tuple[int, int]:
    """The varint at ``i`` and the index after it; ``(0, -1)`` past the end or longer
    than 10 bytes."""
    value = 0
    shift = 0
    while i < len(buf) and shift < 70:
        b = int(buf[i])
        i += 1
        value |= (b & 0x7F) << shift
        if b < 0x80:
            return value, i
        shift += 7
    return 0, -1


@numba.njit(cache=True)
def _f64(buf: np.ndarray, i: int) -> float:
    """The little-endian double at ``i`` (the caller checked ``i + 8 <= len(buf)``)."""
    return buf[i : i + 8].view(np.float64)[0]


@numba.njit(cache=True)
def _skip(buf: np.ndarray, i: int, wire: int) -> int:
    """The index after a field of wire type ``wire`` at ``i``; -1 when malformed."""
    if wire == 0:
        _, i = _varint(buf, i)
    elif wire == 1:
        i += 8
    elif wire == 2:
        n, i = _varint(buf, i)
        if i < 0:
            return -1
        i += n
    elif wire == 5:
        i += 4
    else:
        return -1  # groups: not in OSI
    return i if i <= len(buf) else -1


def _decode_points_py(buf: np.ndarray, field: int, out: np.ndarray) -> int:
    """Fill ``out`` (rows x, y, dash, width) with the points of repeated field ``field``
    of a serialized message; the number of points, or -1 for malformed bytes.

    Plain-Python reference of ``_decode_points`` (same code, compiled once)."""
    i = 0
    n = 0
    end = len(buf)
    while i < end:
        key, i = _varint(buf, i)
        if i < 0:
            return -1
        num = key >> 3
        wire = key & 7
        if num != field or wire != 2:
            i = _skip(buf, i, wire)
            if i < 0:
                return -1
            continue
        size, i = _varint(buf, i)
        if i < 0 or i + size > end:
            return -1
        stop = i + size
        x = 0.0
        y = 0.0
        dash = 0.0
        width = np.nan
        while i < stop:
            k2, i = _varint(buf, i)
            if i < 0:
                return -1
            f2 = k2 >> 3
            w2 = k2 & 7
            if f2 == 1 and w2 == 2:  # position
                psize, i = _varint(buf, i)
                if i < 0 or i + psize > stop:
                    return -1
                pend = i + psize
                while i < pend:
                    k3, i = _varint(buf, i)
                    if i < 0:
                        return -1
                    if (k3 & 7) == 1 and 1 <= (k3 >> 3) <= 2:
                        if i + 8 > pend:
                            return -1
                        if (k3 >> 3) == 1:
                            x = _f64(buf, i)
                        else:
                            y = _f64(buf, i)
                        i += 8
                    else:
                        i = _skip(buf, i, k3 & 7)
                        if i < 0 or i > pend:
                            return -1
            elif f2 == 2 and w2 == 1:  # width
                if i + 8 > stop:
                    return -1
                width = _f64(buf, i)
                i += 8
            elif f2 == 4 and w2 == 0:  # dash
                v, i = _varint(buf, i)
                if i < 0:
                    return -1
                dash = float(v)
            else:
                i = _skip(buf, i, w2)
                if i < 0 or i > stop:
                    return -1
        if i != stop or n >= out.shape[1]:
            return -1
        out[0, n] = x
        out[1, n] = y
        out[2, n] = dash
        out[3, n] = width
        n += 1
    return n


_decode_points = numba.njit(cache=True)(_decode_points_py)


def decode_points(data: bytes, field: int = 2, where: str = "") -> FloatArray:
    """``(4, N)`` rows ``x``, ``y``, ``dash``, ``width`` (NaN where unset) of the points
    of repeated field ``field`` of a serialized message (``LaneBoundary``: 2).

    :raises InputError: bytes that are not a well-formed message (naming ``where``).
    """
    buf = np.frombuffer(data, dtype=np.uint8)
    # a point takes at least 2 bytes on the wire
    out = np.empty((4, max(1, len(buf) // 2)))
    n = _decode_points(buf, field, out)
    if n < 0:
        raise InputError(f"{where}: malformed protobuf bytes of a lane boundary")
    return out[:, :n]
