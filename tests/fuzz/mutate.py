"""Mutations of the files users give aldm-gym: OpenSCENARIO, OpenDRIVE, OSI traces.

Each mutation is drawn by Hypothesis (:func:`xml_mutation`, :func:`bytes_mutation`,
:func:`osi_mutation`) as a small plain description, so a finding can be written down
and replayed: :func:`apply_xml` / :func:`apply_bytes` / :func:`apply_osi` turn a seed
file and a description into the mutant's bytes. The operators are those of the
project's reliability review (docs/reliability.md, "Fuzzing the inputs"):

* attribute values replaced by garbage, NaN, inf, 1e308, huge integers, negative
  numbers, empty strings, deep or long ``${...}`` expressions;
* elements deleted, duplicated, renamed, given an unknown child, attributes removed;
* bytes truncated, bits flipped, invalid UTF-8 inserted, an empty file;
* in an OSI trace: a field of a message set to NaN, inf or 1e300, a timestamp going
  back, a moving object's id repeated, the host's id removed, a frame dropped or
  repeated.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st
from lxml import etree

BAD_VALUES: tuple[str, ...] = (
    "nan",
    "NaN",
    "INF",
    "-inf",
    "1e308",
    "-1e308",
    "1e30",
    "-1e30",
    "123456789012345678901234567890123",
    "-1",
    "0",
    "-0.5",
    "",
    "garbage",
    "true",
    "1e-320",
    "9" * 4000,
    "${1/0}",
    "${" + "(" * 150 + "1" + ")" * 150 + "}",
    "${" + "+".join(["1"] * 1600) + "}",
    "${2**99999}",
    "${$undefined + 1}",
    "$undefined",
)
"""What an attribute value is replaced with."""

XML_OPERATORS = (
    "value",
    "value",
    "value",
    "delete",
    "duplicate",
    "unknown_child",
    "rename",
    "drop_attr",
)
"""Tree mutations (a value change drawn three times as often: most findings live there)."""

BYTE_OPERATORS = ("truncate", "flip", "bad_utf8", "empty")
"""Byte mutations of any file."""

OSI_FIELDS = (
    "host.position.x",
    "host.position.y",
    "host.orientation.yaw",
    "host.dimension.length",
    "host.dimension.width",
    "host.bbcenter_to_rear.x",
    "host.velocity.x",
    "object.position.x",
    "object.dimension.width",
    "boundary.position.x",
    "boundary.position.y",
    "boundary.width",
    "timestamp.seconds",
)
"""Message fields an OSI mutation sets to a bad number."""

OSI_NUMBERS = (float("nan"), float("inf"), -float("inf"), 1e300, -1e300, 1e30, -5.0, 0.0)
"""The numbers they are set to."""

OSI_STRUCTURE = ("time_back", "duplicate_id", "no_host_id", "drop_frame", "repeat_frame")
"""Structural mutations of an OSI trace."""


def elements(root: Any) -> list[Any]:
    """The elements of a tree, in document order (comments and processing instructions
    left out)."""
    return [e for e in root.iter() if isinstance(e.tag, str)]


@st.composite
def xml_mutation(draw: Any, size: int) -> dict[str, Any]:
    """A tree mutation of a file with ``size`` elements: ``{"op", "index", ...}``."""
    op = draw(st.sampled_from(XML_OPERATORS))
    index = draw(st.integers(0, size - 1))
    out: dict[str, Any] = {"op": op, "index": index, "pick": draw(st.integers(0, 1 << 16))}
    if op == "value":
        out["value"] = draw(st.sampled_from(BAD_VALUES))
    return out


@st.composite
def bytes_mutation(draw: Any) -> dict[str, Any]:
    """A byte mutation: ``{"op", "at" (a fraction of the file), "bits"}``."""
    return {
        "op": draw(st.sampled_from(BYTE_OPERATORS)),
        "at": draw(st.floats(0.0, 1.0)),
        "bits": draw(st.integers(1, 8)),
        "pick": draw(st.integers(0, 1 << 16)),
    }


@st.composite
def osi_mutation(draw: Any, frames: int) -> dict[str, Any]:
    """A message mutation of a trace of ``frames`` messages."""
    frame = draw(st.integers(0, frames - 1))
    if draw(st.booleans()):
        return {
            "op": "field",
            "frame": frame,
            "field": draw(st.sampled_from(OSI_FIELDS)),
            "number": draw(st.sampled_from(OSI_NUMBERS)),
        }
    return {"op": draw(st.sampled_from(OSI_STRUCTURE)), "frame": frame}


def describe(mutation: dict[str, Any]) -> str:
    """A short label of a mutation (for test output)."""
    parts = [str(mutation["op"])]
    for key in ("index", "frame", "field", "at"):
        if key in mutation:
            value = mutation[key]
            parts.append(f"{key}={value:.3f}" if isinstance(value, float) else f"{key}={value}")
    for key in ("value", "number"):
        if key in mutation:
            parts.append(f"{key}={str(mutation[key])[:24]!r}")
    return " ".join(parts)


# --------------------------------------------------------------------------- XML
def apply_xml(source: bytes, mutation: dict[str, Any]) -> tuple[bytes, str]:
    """The mutant of the XML ``source``; and where it was changed (tag and line)."""
    parser = etree.XMLParser(remove_blank_text=False, resolve_entities=False)
    root = etree.fromstring(source, parser)
    nodes = elements(root)
    node = nodes[mutation["index"] % len(nodes)]
    where = f"<{node.tag}> line {node.sourceline}"
    pick = mutation["pick"]
    op = mutation["op"]
    if op in ("value", "drop_attr"):
        names = list(node.attrib)
        if not names:  # an element without attributes: give it text instead
            node.text = mutation.get("value", "garbage")
        else:
            name = names[pick % len(names)]
            where += f" @{name}"
            if op == "value":
                node.set(name, mutation["value"])
            else:
                del node.attrib[name]
    elif op == "delete" and node is not root:
        node.getparent().remove(node)
    elif op == "duplicate" and node is not root:
        node.addnext(copy.deepcopy(node))
    elif op == "unknown_child":
        etree.SubElement(node, "UnknownElement", attrib={"value": "1"})
    elif op == "rename":
        node.tag = f"{node.tag}Typo"
    return etree.tostring(root, xml_declaration=True, encoding="utf-8"), where


# --------------------------------------------------------------------------- bytes
def apply_bytes(source: bytes, mutation: dict[str, Any]) -> bytes:
    """The mutant of any file's bytes."""
    op = mutation["op"]
    at = min(int(mutation["at"] * len(source)), max(len(source) - 1, 0))
    if op == "empty" or not source:
        return b""
    if op == "truncate":
        return source[:at]
    if op == "bad_utf8":
        return source[:at] + b"\xff\xfe\xc3\x28" + source[at:]
    data = bytearray(source)
    pick = mutation["pick"]
    for k in range(mutation["bits"]):
        i = (at + k * 7919 + pick) % len(data)
        data[i] ^= 1 << ((pick + k) % 8)
    return bytes(data)


# --------------------------------------------------------------------------- OSI
def _set_path(message: Any, path: Sequence[str], number: float) -> None:
    for name in path[:-1]:
        message = getattr(message, name)
    setattr(message, path[-1], number)


def _host(gt: Any, sv: Any) -> Any:
    host_id = sv.host_vehicle_id.value if sv is not None else gt.host_vehicle_id.value
    for obj in gt.moving_object:
        if obj.id.value == host_id:
            return obj
    return gt.moving_object[0] if len(gt.moving_object) else None


def apply_osi(messages: list[Any], mutation: dict[str, Any]) -> list[Any]:
    """The mutant of a trace's messages (``SensorView``); the input is left unchanged."""
    out = [copy.deepcopy(m) for m in messages]
    frame = mutation["frame"] % len(out)
    msg = out[frame]
    gt = msg.global_ground_truth
    op = mutation["op"]
    if op == "time_back" and frame > 0:
        msg.timestamp.seconds = 0
        msg.timestamp.nanos = 0
        gt.timestamp.seconds = 0
        gt.timestamp.nanos = 0
    elif op == "duplicate_id" and len(gt.moving_object) > 1:
        gt.moving_object[1].id.value = gt.moving_object[0].id.value
    elif op == "no_host_id":
        msg.ClearField("host_vehicle_id")
        gt.ClearField("host_vehicle_id")
    elif op == "drop_frame" and len(out) > 1:
        del out[frame]
    elif op == "repeat_frame":
        out.insert(frame, copy.deepcopy(msg))
    elif op == "field":
        head, *rest = mutation["field"].split(".")
        number = mutation["number"]
        if head == "host":
            host = _host(gt, msg)
            if host is not None and rest[0] == "bbcenter_to_rear":
                _set_path(host.vehicle_attributes, rest, number)
            elif host is not None:
                _set_path(host.base, rest, number)
        elif head == "object":
            others = [o for o in gt.moving_object if o.id.value != msg.host_vehicle_id.value]
            if others:
                _set_path(others[0].base, rest, number)
        elif head == "boundary":
            if len(gt.lane_boundary) and len(gt.lane_boundary[0].boundary_line):
                line = gt.lane_boundary[0].boundary_line
                point = line[len(line) // 2]
                if rest[0] == "width":
                    point.width = number
                else:
                    setattr(point.position, rest[1], number)
        elif head == "timestamp":
            msg.timestamp.seconds = (
                int(max(min(number, 2**62), -(2**62))) if number == number else 7
            )
    return out
