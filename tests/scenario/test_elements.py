"""The element table (aldm_gym.scenario.elements) against the schema, the docs and the
reader's own lists."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import pytest
from lxml import etree

from aldm_gym.scenario import reader
from aldm_gym.scenario.elements import ELEMENTS, STATUSES, counts, markdown_table

DOCS = Path(__file__).resolve().parents[2] / "docs" / "scenarios.md"


def _schema() -> Path | None:
    try:
        path = Path(str(resources.files("schemas") / "OpenSCENARIO_1_3_1.xsd"))
    except ModuleNotFoundError:  # scenariogeneration ships the schemas
        return None
    return path if path.is_file() else None


def test_every_element_of_the_1_3_schema_has_a_status() -> None:
    schema = _schema()
    if schema is None:
        pytest.skip("the OpenSCENARIO 1.3 schema is not installed (scenariogeneration)")
    tree = etree.parse(str(schema))
    names = {
        e.get("name")
        for e in tree.iter("{http://www.w3.org/2001/XMLSchema}element")
        if e.get("name")
    }
    assert set(ELEMENTS) == names
    assert all(status in STATUSES and note for status, note in ELEMENTS.values())


def test_the_docs_table_is_the_generated_one() -> None:
    text = DOCS.read_text()
    found = re.search(
        r"<!-- generated:elements -->\n(.*?)\n<!-- /generated:elements -->", text, re.S
    )
    assert found is not None
    assert found.group(1) == markdown_table()
    c = counts()
    assert sum(c.values()) == len(ELEMENTS) and c["played"] > c["refused"]


def test_what_the_reader_ignores_is_listed_as_ignored() -> None:
    for tag in {**reader._NO_MEANING, **reader._NEVER}:
        assert ELEMENTS[tag][0] == "ignored", tag
