"""A tiny OpenDRIVE writer for the reader's tests: lanes, sections, roads, files."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aldm_gym.roads.opendrive import MarkingLine, OpenDriveMap
from aldm_gym.roads.opendrive.parse import (
    Geometry,
)
from aldm_gym.roads.opendrive.plan_view import PlanView

# ---------------------------------------------------------------- tiny file writer

SOLID_MARK = '<roadMark sOffset="0" type="solid" color="standard" width="0.15"/>'


def lane_xml(
    lane_id: int,
    width: str = '<width sOffset="0" a="3.5" b="0" c="0" d="0"/>',
    marks: str = SOLID_MARK,
    extra: str = "",
) -> str:
    return f'<lane id="{lane_id}" type="driving" level="false">{extra}{width}{marks}</lane>'


def section_xml(
    s: float = 0.0, left: str = "", right: str = "", centre_mark: str = SOLID_MARK
) -> str:
    parts = [f'<laneSection s="{s}">']
    if left:
        parts.append(f"<left>{left}</left>")
    parts.append(f'<center><lane id="0" type="none" level="false">{centre_mark}</lane></center>')
    if right:
        parts.append(f"<right>{right}</right>")
    parts.append("</laneSection>")
    return "".join(parts)


def road_xml(
    road_id: str,
    geometry: str,
    length: float,
    sections: str,
    link: str = "",
    offsets: str = "",
    rule: str = "RHT",
    junction: str = "-1",
    extra: str = "",
) -> str:
    return (
        f'<road id="{road_id}" length="{length}" junction="{junction}" rule="{rule}">'
        f"<link>{link}</link><planView>{geometry}</planView>{extra}"
        f"<lanes>{offsets}{sections}</lanes></road>"
    )


def geometry_xml(
    kind: str, length: float, s: float = 0.0, x: float = 0.0, y: float = 0.0, hdg: float = 0.0
) -> str:
    return f'<geometry s="{s}" x="{x}" y="{y}" hdg="{hdg}" length="{length}">{kind}</geometry>'


def write_xodr(path: Path, *roads: str, junctions: str = "") -> Path:
    path.write_text(
        '<?xml version="1.0"?>\n<OpenDRIVE>\n<header revMajor="1" revMinor="6" name="t"/>\n'
        + "\n".join(roads)
        + junctions
        + "\n</OpenDRIVE>\n"
    )
    return path


def make_plan(*geometries: Geometry) -> PlanView:
    return PlanView(geometries, "test")


def broken_mark(
    s_offset: float = 0.0, length: float = 6.0, space: float = 12.0, line_s: float = 0.0
) -> str:
    return (
        f'<roadMark sOffset="{s_offset}" type="broken" color="standard" width="0.15">'
        f'<type name="b" width="0.15"><line length="{length}" space="{space}" tOffset="0" '
        f'sOffset="{line_s}" width="0.15"/></type></roadMark>'
    )


def marking_at(odr: OpenDriveMap, x: float, y: float) -> MarkingLine:
    """The marking line passing closest to a world point."""
    dist = [np.hypot(m.xy[:, 0] - x, m.xy[:, 1] - y).min() for m in odr.markings]
    return odr.markings[int(np.argmin(dist))]
