"""``argparse`` argument types of the ``aldm-gym`` command line (clear errors on bad values).

Every type raises ``argparse.ArgumentTypeError``, so a bad value ends in the
subcommand's usage, one line ``aldm-gym <command>: error: argument --x: ...`` and
exit code 2. What only shows when the command runs (an OpenDRIVE file that does not
parse, a corrupt model, an output folder that cannot be created) is raised as
:class:`BadArgument`, which :func:`aldm_gym.cli.main` reports the same way.

Path types check what can be checked without side effects (no folder is created while
parsing): :func:`output_dir` and :func:`image_file` refuse an existing path of the
wrong kind and a parent that is a file or not writable; :func:`make_output_dir`
creates the folder when the command runs.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

MAX_SEED = 2**31 - 1
"""Largest seed accepted (envs are seeded ``seed + i``; SB3 needs seeds below 2**32)."""

IMAGE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff")
"""File types :func:`image_file` accepts (formats matplotlib writes)."""


class BadArgument(Exception):
    """An argument that parsed but proved unusable when the command ran.

    :func:`aldm_gym.cli.main` turns it into the subcommand's usage error (exit code 2).

    :param argument: the option, e.g. ``"--xodr"``.
    :param message: what is wrong with it (line breaks become spaces: one line).
    """

    def __init__(self, argument: str, message: str) -> None:
        super().__init__(f"argument {argument}: {' '.join(message.splitlines())}")
        self.argument = argument


def _number(text: str, kind: type) -> float:
    try:
        value = kind(text)
    except ValueError:
        name = "an integer" if kind is int else "a number"
        raise argparse.ArgumentTypeError(f"must be {name}, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text}")
    return value


def finite_float(text: str) -> float:
    """Any finite number."""
    return _number(text, float)


def positive_int(text: str) -> int:
    """An integer >= 1."""
    value = int(_number(text, int))
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0."""
    value = int(_number(text, int))
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def int_in(lo: int, hi: int) -> Callable[[str], int]:
    """The type of an integer in ``[lo, hi]``."""

    def parse(text: str) -> int:
        value = int(_number(text, int))
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be in [{lo}, {hi}], got {value}")
        return value

    parse.__name__ = f"integer in [{lo}, {hi}]"
    return parse


def seed(text: str) -> int:
    """A seed: an integer in ``[0, MAX_SEED]``."""
    value = int(_number(text, int))
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be in [0, 2**31 - 1], got {value}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _number(text, float)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text, float)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return value


def fraction(text: str) -> float:
    """A number in [0, 1)."""
    value = _number(text, float)
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"must be in [0, 1), got {value}")
    return value


def config_setting(module: str, cls: str, name: str, kind: type = float) -> Callable[[str], Any]:
    """The type of a value of config field ``cls.name`` (a :func:`aldm_gym.config.setting`).

    The value is checked against the field's own rule, so the command line accepts what
    the config accepts and the bound lives in one place. ``module.cls`` is imported only
    when the argument is given (building the parser stays light).

    :param kind: ``int`` or ``float``.
    """

    def parse(text: str) -> Any:
        from aldm_gym.config import check_value, rules

        value = _number(text, kind)
        config = getattr(importlib.import_module(module), cls)
        try:
            return check_value("", name, value, rules(config)[name], config())
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix(f".{name} ")) from None

    parse.__name__ = name
    return parse


def key_value(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` (e.g. ``occlusion=true``, ``visibility=120``,
    ``worn_stretch_length=[20,60]``): the value read as JSON when it parses
    (numbers, ``true``/``false``, ``null``, lists), else as the string itself. The
    key's name and value are checked where they are used."""
    import json

    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"must be KEY=VALUE, got {text!r}")
    try:
        parsed: Any = json.loads(value)
    except json.JSONDecodeError:
        parsed = value
    if isinstance(parsed, float) and not math.isfinite(parsed):
        raise argparse.ArgumentTypeError(f"{key} must be finite, got {value}")
    return key, parsed


MAX_CONFIG_BYTES = 1 << 20
"""The largest ``--config`` file read [bytes]: an env's settings are a few kB."""


def config_file(text: str) -> list[tuple[str, Any]]:
    """``--config FILE``: an env settings tree in YAML or JSON (as ``gym.make``'s
    ``config``), checked as the env checks it; returned as the ``--env`` pairs it
    stands for (``SECTION.KEY``), so that ``--env`` given beside it wins."""
    import json

    import yaml

    from aldm_gym.training.settings import dotted_settings

    path = existing_file(text)
    if path.stat().st_size > MAX_CONFIG_BYTES:
        raise argparse.ArgumentTypeError(
            f"{path} is {path.stat().st_size} bytes; an env config is at most {MAX_CONFIG_BYTES}"
        )
    raw = path.read_bytes()
    try:
        if path.suffix.lower() == ".json":
            tree = json.loads(raw)
        else:  # YAML (a superset of JSON)
            tree = yaml.safe_load(raw)
    except (ValueError, yaml.YAMLError) as exc:
        raise argparse.ArgumentTypeError(
            f"{path}: not {'JSON' if path.suffix.lower() == '.json' else 'YAML'}: "
            + " ".join(str(exc).split())
        ) from None
    if tree is None:
        tree = {}
    if not isinstance(tree, dict):
        raise argparse.ArgumentTypeError(
            f"{path}: an env config is a mapping of settings, got {type(tree).__name__}"
        )
    try:
        check_env(tree, "--config")
    except BadArgument as exc:
        raise argparse.ArgumentTypeError(f"{path}: {str(exc).partition(': ')[2]}") from None
    return list(dotted_settings(tree))


def add_env_argument(parser: argparse.ArgumentParser, note: str) -> None:
    """Declare ``--env KEY=VALUE`` (repeatable): any ``ALDMHighway-v0`` setting; and
    ``--config FILE``: many at once, from a YAML or JSON file (``--env`` wins).
    :func:`aldm_gym.cli.main` puts the file's settings before the ``--env`` pairs."""
    parser.add_argument(
        "--env",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="any other ALDMHighway-v0 setting, repeatable; a section's as SECTION.KEY, e.g. "
        "detector_params.tracking=model observation.line_confidence=true "
        f"sensor.preset=camera (docs/env.md; {note})",
    )
    parser.add_argument(
        "--config",
        dest="env_file",
        type=config_file,
        default=None,
        metavar="FILE",
        help="env settings from a YAML or JSON file (the settings tree gym.make takes); "
        "--env given beside it wins",
    )


FUNCTION_HELP = (
    "the function under test: builtin (the env's own; builtin:rule_based with lane changes), "
    "a .fmu, a training output folder or model (SB3 .zip, RLlib checkpoint), or "
    "module:attr / file.py:attr naming a class or callable with aldm_gym.function's "
    "interface"
)
"""The ``--function`` help text (here, not in :mod:`aldm_gym.function`: building the
parser must not import the env)."""


def add_function_argument(parser: argparse.ArgumentParser) -> None:
    """Declare ``--function SPEC`` (:func:`aldm_gym.function.load_function`)."""
    parser.add_argument("--function", default="builtin", metavar="SPEC", help=FUNCTION_HELP)


def function_spec(args: argparse.Namespace) -> Any:
    """The ``--function`` loaded (:class:`BadArgument` naming it when it cannot be)."""
    from aldm_gym.errors import AldmGymError
    from aldm_gym.function import load_function

    try:
        return load_function(args.function)
    except AldmGymError as exc:
        message = str(exc).removeprefix(f"--function {args.function}: ")
        raise BadArgument("--function", message) from None


def nested_pairs(pairs: list[tuple[str, Any]], flag: str = "--env") -> dict[str, Any]:
    """``KEY=VALUE`` pairs with dotted keys as a nested config (``a.b=v`` ->
    ``{"a": {"b": v}}``); :class:`BadArgument` naming ``flag`` where a key gives a
    value to a section or a section to a value. The keys themselves are checked where
    the config is used."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        *sections, name = key.split(".")
        node = out
        for part in sections:
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise BadArgument(flag, f"{key}: {part} was given a value, not a section")
            node = child
        if isinstance(node.get(name), dict):
            raise BadArgument(flag, f"{key}: {name} is a section; give SECTION.KEY=VALUE")
        node[name] = value
    return out


def check_env(overrides: Mapping[str, Any], flag: str = "--env") -> Any:
    """Env settings (:func:`nested_pairs`) validated as the env validates them, once:
    the :class:`~aldm_gym.envs.config.EnvOverrides` that passes on to ``gym.make``;
    :class:`BadArgument` naming ``flag``, the key and the allowed ones."""
    from aldm_gym.envs.config import EnvOverrides
    from aldm_gym.errors import ConfigError

    try:
        return EnvOverrides(overrides)
    except ConfigError as exc:
        raise BadArgument(flag, str(exc)) from None


def check_parent(path: Path) -> None:
    """The nearest existing ancestor of ``path`` is a writable folder (else
    ``argparse.ArgumentTypeError``)."""
    parent = path.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"{path}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{path}: {parent} is not writable")


def output_dir(text: str) -> Path:
    """An output folder: an existing folder, or a path where one can be created."""
    path = Path(text)
    if path.exists():
        if not path.is_dir():
            raise argparse.ArgumentTypeError(f"{path} exists and is not a folder")
        if not os.access(path, os.W_OK | os.X_OK):
            raise argparse.ArgumentTypeError(f"{path} is not writable")
        return path
    check_parent(path)
    return path


def image_file(text: str) -> Path:
    """An image to write: a file name with one of :data:`IMAGE_SUFFIXES`, not a folder."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{path} is a folder; give a file name such as x.png")
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        raise argparse.ArgumentTypeError(
            f"{path}: unknown image type {path.suffix!r}; use one of {', '.join(IMAGE_SUFFIXES)}"
        )
    if path.exists() and not os.access(path, os.W_OK):
        raise argparse.ArgumentTypeError(f"{path} is not writable")
    check_parent(path)
    return path


def trace_file(text: str) -> Path:
    """An ASAM OSI trace to write: a ``.mcap`` or ``.osi`` file name in a writable place."""
    path = Path(text)
    if path.suffix.lower() not in (".mcap", ".osi"):
        raise argparse.ArgumentTypeError(f"{path}: give a .mcap or .osi file name")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{path} is a folder")
    check_parent(path)
    return path


def existing_file(text: str) -> Path:
    """A readable file that exists."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{path} does not exist")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{path} is not a file")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{path} is not readable")
    return path


def xodr_file(text: str) -> Path:
    """An OpenDRIVE file that exists, or the name of a shipped example map
    (``motorway`` or ``motorway.xodr``: :func:`aldm_gym.roads.shipped_map`). A file
    of the working folder wins: ``motorway`` is ``./motorway`` or ``./motorway.xodr``
    when either exists, else the shipped map."""
    from aldm_gym.roads.opendrive.parse import SHIPPED_MAPS, not_found, shipped_map

    path = Path(text)
    if not path.exists():
        stem = path.name.removesuffix(".xodr")
        if path.name == text and Path(stem + ".xodr").exists():
            return existing_file(stem + ".xodr")
        if path.name == text and stem in SHIPPED_MAPS:
            return shipped_map(stem)
        if stem in SHIPPED_MAPS:
            raise argparse.ArgumentTypeError(
                f"{not_found(text)}; or give just its name: --xodr {stem}"
            )
        raise argparse.ArgumentTypeError(
            f"{path} does not exist (shipped maps by name: {', '.join(SHIPPED_MAPS)})"
        )
    return existing_file(text)


def model_path(text: str) -> Path:
    """A trained model: a readable ``.zip`` file (stable-baselines3) or a folder (an
    RLlib checkpoint, checked when the command loads it)."""
    path = Path(text)
    if path.is_dir():
        if not os.access(path, os.R_OK | os.X_OK):
            raise argparse.ArgumentTypeError(f"{path} is not readable")
        return path
    return existing_file(text)


def ray_address(text: str) -> str:
    """A Ray cluster address: ``auto`` or ``host:port`` (port 1-65535)."""
    if text == "auto":
        return text
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"must be 'auto' or host:port, got {text!r}")
    return text


def make_output_dir(path: Path, argument: str = "--out") -> Path:
    """Create the output folder ``path`` (and its parents) when the command runs.

    :raises BadArgument: naming ``argument`` when the folder cannot be created.
    """
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadArgument(argument, f"cannot create {path}: {exc.strerror or exc}") from None
    return path
