"""One XML reader for every file aldm-gym reads: OpenSCENARIO (``.xosc``), their
catalogs and parameter-variation files, and OpenDRIVE (``.xodr``).

One parser with one setting, hardened for files from anywhere:

- no entity resolution and no DTD loading: an external entity (``<!ENTITY x SYSTEM
  "file:///etc/passwd">``) reads nothing, and an entity bomb expands nothing;
- no network access;
- lxml's limits on huge trees kept (no ``huge_tree``): a text node over 10 MB or a
  tree over 256 levels deep is refused;
- the file's size capped (:data:`MAX_BYTES`) before it is read.

Every failure is one error of the kind the caller names (a
:class:`~aldm_gym.errors.ScenarioError` for a scenario, a
:class:`~aldm_gym.errors.MapError` for a map) in one format: ``file:line: message``.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from lxml import etree

from aldm_gym.errors import AldmGymError, ScenarioError

__all__ = ["MAX_BYTES", "ElementReader", "children", "parse_xml", "where"]

MAX_BYTES = 256 * 1024 * 1024
"""The largest XML file read [bytes] (a large OpenDRIVE map is tens of MB)."""


def _parser() -> etree.XMLParser:
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_blank_text=True,
    )


def where(path: str | os.PathLike[str], element: Any, attr: str | None = None) -> str:
    """``file:line <Tag>`` (and ``attr``) of an element, the format of every error
    about a file's content."""
    base = f"{Path(path).name}:{getattr(element, 'sourceline', '?')} <{element.tag}>"
    return base if attr is None else f"{base} {attr}"


def parse_xml(
    path: str | os.PathLike[str],
    root: str | None = None,
    error: type[AldmGymError] = ScenarioError,
) -> Any:
    """Parse an XML file with the hardened parser; its ``ElementTree``.

    :param path: the file.
    :param root: the root element's tag it must have (None: any).
    :param error: the exception class of every failure (its message names the file
        and, where known, the line).
    :raises error: the file is missing, larger than :data:`MAX_BYTES`, not well-formed
        XML, not UTF-8 where it says so, or has another root.
    """
    name = os.fspath(path)
    p = Path(name)
    if not p.is_file():
        raise error(f"{name}: no such file")
    size = p.stat().st_size
    if size > MAX_BYTES:
        raise error(f"{name}: {size} bytes, more than the {MAX_BYTES} an XML file may have")
    try:
        tree = etree.parse(name, _parser())
    except etree.XMLSyntaxError as exc:
        line = exc.lineno if exc.lineno is not None else "?"
        raise error(f"{name}:{line}: malformed XML: {exc.msg}") from None
    except (OSError, ValueError, UnicodeError) as exc:  # lxml: bad encodings, unreadable
        raise error(f"{name}: cannot be read as XML: {exc}") from None
    top = tree.getroot()
    if top is None:
        raise error(f"{name}: no root element")
    if root is not None and top.tag != root:
        raise error(f"{name}:{top.sourceline}: the root is <{top.tag}>, not <{root}>")
    return tree


def children(element: Any) -> Iterator[Any]:
    """An element's child elements, without comments and processing instructions."""
    return (child for child in element if isinstance(child.tag, str))


class ElementReader:
    """Reads the elements of one file with errors in one format (:func:`where`):
    ``file:line <Tag>: message``, of the kind the file's reader names.

    :param path: the file (its name goes into every message).
    :param error: the exception class of every failure (:class:`ScenarioError` for a
        scenario, :class:`~aldm_gym.errors.MapError` for a map).
    """

    def __init__(
        self, path: str | os.PathLike[str], error: type[AldmGymError] = ScenarioError
    ) -> None:
        self.path = path
        self.error_type = error

    def where(self, el: Any, attr: str | None = None) -> str:
        """``file:line <Tag>`` (and ``attr``) of an element."""
        return where(self.path, el, attr)

    def error(self, el: Any, message: str, attr: str | None = None) -> AldmGymError:
        """The error naming the element (and ``attr``)."""
        return self.error_type(f"{self.where(el, attr)}: {message}")

    def unexpected(self, el: Any, allowed: Sequence[str]) -> AldmGymError:
        """The error of an element its parent does not take, listing what it takes."""
        parent = el.getparent()
        inside = f" inside <{parent.tag}>" if parent is not None else ""
        listed = ", ".join(f"<{a}>" for a in allowed) or "nothing"
        return self.error(el, f"unknown element{inside}; allowed there: {listed}")

    def required(self, el: Any, name: str) -> str:
        """An attribute that must be there, as written."""
        value = el.get(name)
        if value is None:
            raise self.error(el, f"missing attribute {name!r}")
        return str(value)

    def one(self, el: Any, allowed: Sequence[str]) -> Any:
        """The single child element, one of ``allowed``."""
        found = None
        for child in children(el):
            if child.tag not in allowed:
                raise self.unexpected(child, allowed)
            if found is not None:
                raise self.error(child, f"<{el.tag}> holds one of {', '.join(allowed)}, not two")
            found = child
        if found is None:
            raise self.error(el, f"needs one child: {' or '.join(f'<{a}>' for a in allowed)}")
        return found

    def many(self, el: Any, tag: str) -> list[Any]:
        """The child elements, all ``tag``, at least one."""
        out = []
        for child in children(el):
            if child.tag != tag:
                raise self.unexpected(child, [tag])
            out.append(child)
        if not out:
            raise self.error(el, f"needs at least one <{tag}>")
        return out
