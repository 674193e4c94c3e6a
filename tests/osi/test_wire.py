"""Bulk boundary points against the official bindings, byte for byte and value for value."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from osi3.osi_detectedlane_pb2 import DetectedLaneBoundary
from osi3.osi_lane_pb2 import LaneBoundary

from aldm_gym.errors import InputError
from aldm_gym.osi.wire import _decode_points_py, decode_points, encode_points

finite = st.floats(-1e6, 1e6, allow_nan=False)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(finite, finite, st.integers(0, 5)), max_size=40))
def test_encoded_points_are_what_the_bindings_write(points: list) -> None:
    bulk, each = LaneBoundary(), LaneBoundary()
    for msg in (bulk, each):
        msg.id.value = 9
    arr = np.array(points, dtype=float).reshape(-1, 3)
    bulk.MergeFromString(encode_points(2, arr[:, 0], arr[:, 1], arr[:, 2].astype(int)))
    for x, y, d in points:
        p = each.boundary_line.add()
        p.position.x, p.position.y, p.position.z = x, y, 0.0
        p.dash = d
    assert bulk.SerializeToString() == each.SerializeToString()
    sized, each_sized = LaneBoundary(), LaneBoundary()
    sized.MergeFromString(
        encode_points(2, arr[:, 0], arr[:, 1], arr[:, 2].astype(int), z=-1.5, width=0.2, height=0.1)
    )
    for x, y, d in points:
        p = each_sized.boundary_line.add()
        p.position.x, p.position.y, p.position.z = x, y, -1.5
        p.width, p.height, p.dash = 0.2, 0.1, d
    assert sized.SerializeToString() == each_sized.SerializeToString()
    det_bulk, det_each = DetectedLaneBoundary(), DetectedLaneBoundary()
    det_bulk.MergeFromString(encode_points(3, arr[:, 0], arr[:, 1]))
    for x, y, _ in points:
        p = det_each.boundary_line.add()
        p.position.x, p.position.y, p.position.z = x, y, 0.0
    assert det_bulk == det_each


@settings(max_examples=80, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.one_of(st.none(), finite),  # x (None: unset)
            st.one_of(st.none(), finite),  # y
            st.one_of(st.none(), finite),  # z
            st.one_of(st.none(), st.integers(0, 5)),  # dash
            st.one_of(st.none(), st.floats(0.0, 1.0)),  # width
            st.one_of(st.none(), st.floats(0.0, 3.0)),  # height
        ),
        max_size=30,
    ),
    st.booleans(),
)
def test_decoded_points_are_what_the_bindings_read(points: list, extras: bool) -> None:
    lb = LaneBoundary()
    if extras:  # fields around and between the points
        lb.id.value = 123456789
        lb.classification.type = LaneBoundary.Classification.TYPE_DASHED_LINE
        lb.source_reference.add().reference = "road 1 lane -2"
    for x, y, z, d, w, h in points:
        p = lb.boundary_line.add()
        if x is not None:
            p.position.x = x
        if y is not None:
            p.position.y = y
        if z is not None:
            p.position.z = z
        if d is not None:
            p.dash = d
        if w is not None:
            p.width = w
        if h is not None:
            p.height = h
    data = lb.SerializeToString()
    rows = decode_points(data)
    assert rows.shape == (4, len(points))
    for k, p in enumerate(lb.boundary_line):
        assert rows[0, k] == p.position.x and rows[1, k] == p.position.y
        assert rows[2, k] == p.dash
        assert (math.isnan(rows[3, k]) and not p.HasField("width")) or rows[3, k] == p.width
    # the plain twin agrees with the compiled kernel
    out = np.empty((4, max(1, len(data) // 2)))
    n = _decode_points_py(np.frombuffer(data, dtype=np.uint8), 2, out)
    np.testing.assert_array_equal(out[:, :n], rows)


@pytest.mark.parametrize("cut", [1, 3, 9, 20])
def test_malformed_bytes_are_an_error(cut: int) -> None:
    lb = LaneBoundary()
    for i in range(3):
        p = lb.boundary_line.add()
        p.position.x = float(i)
        p.width = 0.1
    data = lb.SerializeToString()
    with pytest.raises(InputError, match="here: malformed"):
        decode_points(data[:-cut], where="here")
    out = np.empty((4, 64))
    buf = np.frombuffer(data[:-cut], dtype=np.uint8)
    assert _decode_points_py(buf, 2, out) == -1


def test_a_runaway_varint_is_an_error() -> None:
    with pytest.raises(InputError, match="malformed"):
        decode_points(bytes([0x12, 0x05]) + bytes([0xFF] * 12))


def test_encode_checks_its_input() -> None:
    with pytest.raises(InputError, match="one value per point"):
        encode_points(2, np.zeros(3), np.zeros(2))
    with pytest.raises(InputError, match=r"0\.\.5"):
        encode_points(2, np.zeros(1), np.zeros(1), np.array([7]))
    with pytest.raises(InputError, match="both width and height"):
        encode_points(2, np.zeros(1), np.zeros(1), width=0.1)
