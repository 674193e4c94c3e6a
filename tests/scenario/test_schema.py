"""Children the schema allows once (aldm_gym.scenario.schema): the table against the
XSD, and the reader refusing a repeated one."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest
from lxml import etree

from aldm_gym.errors import ScenarioError
from aldm_gym.scenario.reader import read_scenario
from aldm_gym.scenario.schema import LENIENT, REQUIRED_ATTRIBUTES, SINGLE_CHILDREN
from tests.scenario._build import write
from tests.scenario.test_elements import _schema

XS = "{http://www.w3.org/2001/XMLSchema}"


def _children(node: Any, types: dict, groups: dict, once: bool, out: list) -> list:
    """``(name, type, may repeat)`` of the elements a complexType's content declares."""
    for c in node:
        repeats = c.get("maxOccurs", "1") != "1"
        if c.tag == XS + "element":
            out.append((c.get("name"), c.get("type"), repeats or not once))
        elif c.tag in (XS + "sequence", XS + "choice", XS + "all"):
            _children(c, types, groups, once and not repeats, out)
        elif c.tag == XS + "group":
            _children(groups[c.get("ref")], types, groups, once and not repeats, out)
        elif c.tag in (XS + "complexContent", XS + "simpleContent"):
            for ext in c:
                if ext.get("base") in types:
                    _children(types[ext.get("base")], types, groups, once, out)
                _children(ext, types, groups, once, out)
    return out


def _xsd() -> tuple[dict, dict, dict[str, set[str]]]:
    """The schema's complex types, groups, and element name -> its types."""
    schema = _schema()
    if schema is None:
        pytest.skip("the OpenSCENARIO 1.3 schema is not installed (scenariogeneration)")
    xsd = etree.parse(str(schema)).getroot()
    types = {t.get("name"): t for t in xsd.iter(XS + "complexType") if t.get("name")}
    groups = {g.get("name"): g for g in xsd.iter(XS + "group") if g.get("name")}
    of_element: dict[str, set[str]] = defaultdict(set)
    for t in types.values():
        for name, type_name, _ in _children(t, types, groups, True, []):
            of_element[name].add(type_name)
    for e in xsd.findall(XS + "element"):
        of_element[e.get("name")].add(e.get("type"))
    return types, groups, of_element


def test_the_required_attributes_are_the_schemas() -> None:
    types, _, of_element = _xsd()

    def required(type_name: str) -> set[str]:
        node = types[type_name]
        out = {a.get("name") for a in node.iter(XS + "attribute") if a.get("use") == "required"}
        for ext in node.iter(XS + "extension"):
            if ext.get("base") in types:
                out |= required(ext.get("base"))
        return out

    derived = {}
    for name, type_names in of_element.items():
        sets = [required(t) for t in type_names if t in types]
        common = set.intersection(*sets) if sets else set()
        if common:  # an element name of several types: the attributes all require
            derived[name] = frozenset(common)
    assert derived == REQUIRED_ATTRIBUTES
    assert all(attr in REQUIRED_ATTRIBUTES[tag] for tag, attr in LENIENT)


def test_the_table_is_the_schemas() -> None:
    types, groups, of_element = _xsd()
    derived = {}
    for name, type_names in of_element.items():
        sets = [
            {n for n, _, repeats in _children(types[t], types, groups, True, []) if not repeats}
            for t in type_names
            if t in types
        ]
        common = set.intersection(*sets) if sets else set()
        if common:  # an element name of several types: the children single in all
            derived[name] = frozenset(common)
    assert derived == SINGLE_CHILDREN


def _one_event(tmp_path: Path) -> Path:
    """A scenario whose target slows down to 10 m/s at 1 s."""
    from scenariogeneration import xosc

    from tests.scenario._build import at_time, step_speed

    ev = xosc.Event("slower", xosc.Priority.override)
    ev.add_action("slower_action", step_speed(10.0))
    ev.add_trigger(at_time(1.0))
    return write(tmp_path, [("Target", [ev])])


@pytest.mark.parametrize(
    ("parent", "child"),
    [("Event", "StartTrigger"), ("BoundingBox", "Dimensions"), ("TeleportAction", "Position")],
)
def test_a_repeated_single_child_is_refused(tmp_path: Path, parent: str, child: str) -> None:
    path = _one_event(tmp_path)
    tree = etree.parse(str(path))
    node = tree.getroot().iter(parent).__next__().find(child)
    node.addnext(etree.fromstring(etree.tostring(node)))
    tree.write(str(path))
    with pytest.raises(ScenarioError, match=rf"scenario.xosc:\d+ <{parent}>: a second <{child}>"):
        read_scenario(path)


@pytest.mark.parametrize(
    "parent", ["SpeedActionDynamics", "LogicFile", "Performance", "FileHeader"]
)
def test_an_unknown_element_is_refused_where_the_player_reads_in_part(
    tmp_path: Path, parent: str
) -> None:
    """An element the schema does not know is refused wherever it is, also inside
    elements the player reads only some children or attributes of."""
    from scenariogeneration import xosc

    from tests.scenario._build import at_time

    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    ev = xosc.Event("slower", xosc.Priority.override)
    ev.add_action("slower_action", xosc.AbsoluteSpeedAction(10.0, dyn))
    ev.add_trigger(at_time(1.0))
    path = write(tmp_path, [("Target", [ev])])
    tree = etree.parse(str(path))
    etree.SubElement(next(tree.getroot().iter(parent)), "SpeedActionDynamic")
    tree.write(str(path))
    with pytest.raises(
        ScenarioError,
        match=rf"scenario.xosc:\d+ <SpeedActionDynamic>: not an element of OpenSCENARIO 1.3 "
        rf"inside <{parent}> \(did you mean <SpeedActionDynamics>\?\)",
    ):
        read_scenario(path)


@pytest.mark.parametrize(
    ("tag", "attr"),
    [("Event", "priority"), ("Condition", "delay"), ("LanePosition", "roadId"),
     ("SimulationTimeCondition", "rule"), ("Vehicle", "vehicleCategory")],
)  # fmt: skip
def test_a_missing_required_attribute_is_refused(tmp_path: Path, tag: str, attr: str) -> None:
    path = _one_event(tmp_path)
    tree = etree.parse(str(path))
    node = next(tree.getroot().iter(tag))
    del node.attrib[attr]
    tree.write(str(path))
    with pytest.raises(
        ScenarioError,
        match=rf"scenario.xosc:\d+ <{tag}>: missing attribute '{attr}' \(the schema requires it\)",
    ):
        read_scenario(path)


def test_what_files_for_esmini_leave_out_is_taken_as_esmini_takes_it(tmp_path: Path) -> None:
    path = _one_event(tmp_path)
    tree = etree.parse(str(path))
    for node in tree.getroot().iter("SpeedActionDynamics"):  # step shapes
        del node.attrib["dynamicsDimension"], node.attrib["value"]
    for node in tree.getroot().iter("Condition"):
        del node.attrib["conditionEdge"]
    tree.write(str(path))
    read_scenario(path)  # plays


@pytest.mark.parametrize(
    ("where", "text"), [("Event", "oops"), ("Actions", "stray words between elements")]
)
def test_text_where_the_schema_has_none_is_refused(tmp_path: Path, where: str, text: str) -> None:
    path = _one_event(tmp_path)
    tree = etree.parse(str(path))
    node = next(tree.getroot().iter(where))
    if where == "Event":
        node.text = text
    else:
        node[0].tail = text
    tree.write(str(path))
    with pytest.raises(ScenarioError, match=rf"<{where}>: text '{text[:20]}.*' where the schema"):
        read_scenario(path)
