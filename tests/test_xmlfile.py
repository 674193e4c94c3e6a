"""The one XML reader (aldm_gym.xmlfile): hardened, one error format for every file."""

from __future__ import annotations

from pathlib import Path

import pytest

from aldm_gym.errors import MapError, ScenarioError
from aldm_gym.roads import OpenDriveRoad
from aldm_gym.scenario import read_scenario
from aldm_gym.xmlfile import parse_xml

SECRET = "top-secret-local-file-content"


def _with_external_entity(tmp_path: Path, root: str) -> Path:
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET)
    path = tmp_path / f"evil.{'xodr' if root == 'OpenDRIVE' else 'xosc'}"
    path.write_text(
        f'<?xml version="1.0"?>\n<!DOCTYPE {root} [<!ENTITY leak SYSTEM "file://{secret}">]>\n'
        f'<{root}><FileHeader revMajor="1" revMinor="1" description="&leak;"/></{root}>\n'
    )
    return path


def test_an_external_entity_reads_no_local_file(tmp_path: Path) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET)
    path = tmp_path / "evil.xosc"
    path.write_text(
        f'<!DOCTYPE OpenSCENARIO [<!ENTITY leak SYSTEM "file://{secret}">]>\n'
        "<OpenSCENARIO><FileHeader>&leak;</FileHeader></OpenSCENARIO>\n"
    )
    root = parse_xml(path).getroot()
    assert SECRET not in "".join(root.itertext())
    # in an attribute the reference is refused, without the file's content
    with pytest.raises(ScenarioError, match="external entity") as info:
        parse_xml(_with_external_entity(tmp_path, "OpenSCENARIO"))
    assert SECRET not in str(info.value)


@pytest.mark.parametrize("root", ["OpenSCENARIO", "OpenDRIVE"])
def test_scenario_and_map_readers_do_not_leak_an_external_entity(tmp_path: Path, root: str) -> None:
    path = _with_external_entity(tmp_path, root)
    with pytest.raises((ScenarioError, MapError)) as info:
        if root == "OpenSCENARIO":
            read_scenario(path)
        else:
            OpenDriveRoad.from_file(str(path))
    assert SECRET not in str(info.value)


@pytest.mark.parametrize(
    ("content", "error", "message"),
    [
        (
            b"<OpenSCENARIO>\n<FileHeader>\n</OpenSCENARIO>",
            ScenarioError,
            r"x\.xml:3: malformed XML",
        ),
        (
            b'<?xml version="1.0" encoding="UTF-8"?>\n<a>\xff\xfe</a>',
            MapError,
            r"x\.xml: cannot be read as XML: .*encoding",
        ),
        (b"", ScenarioError, r"x\.xml:\S*: malformed XML"),
        (b"<OpenDRIVE/>", ScenarioError, r"x\.xml:1: the root is <OpenDRIVE>, not <OpenSCENARIO>"),
    ],
)
def test_every_failure_is_one_error_naming_file_and_line(
    tmp_path: Path, content: bytes, error: type[Exception], message: str
) -> None:
    path = tmp_path / "x.xml"
    path.write_bytes(content)
    with pytest.raises(error, match=message):
        parse_xml(path, "OpenSCENARIO", error=error)  # type: ignore[arg-type]


def test_a_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match=r"nope\.xosc: no such file"):
        parse_xml(tmp_path / "nope.xosc")


def test_one_element_reader_format_for_every_file_kind(tmp_path: Path) -> None:
    """Scenarios, variation files and maps name a place the same way:
    ``file:line <Tag>: message``, with the reader's error type."""
    from aldm_gym.xmlfile import ElementReader, children

    path = tmp_path / "f.xml"
    path.write_text("<A>\n<!-- c -->\n<B x='1'/>\n<C/>\n</A>")
    root = parse_xml(path).getroot()
    assert [c.tag for c in children(root)] == ["B", "C"]
    reader = ElementReader(path)
    b, c = list(children(root))
    assert str(reader.error(b, "bad", "x")) == "f.xml:3 <B> x: bad"
    assert reader.required(b, "x") == "1"
    with pytest.raises(ScenarioError, match=r"^f\.xml:4 <C>: missing attribute 'y'$"):
        reader.required(c, "y")
    with pytest.raises(ScenarioError, match=r"f\.xml:3 <B>: unknown element inside <A>"):
        reader.many(root, "C")
    with pytest.raises(ScenarioError, match="holds one of B, C, not two"):
        reader.one(root, ["B", "C"])
    assert isinstance(ElementReader(path, MapError).error(b, "m"), MapError)
