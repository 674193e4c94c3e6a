"""The env's ``scenario`` settings section (:class:`ScenarioConfig`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from aldm_gym.config import Rule, setting, validate
from aldm_gym.errors import ConfigError

__all__ = ["ScenarioConfig"]


@dataclass(frozen=True)
class ScenarioConfig:
    """The ``scenario`` section: play an OpenSCENARIO file on the env.

    :ivar xosc: path of a concrete scenario (``.xosc``); ``""``: no scenario (the
        env's own road and traffic).
    :ivar parameters: values for the scenario's ``ParameterDeclarations`` by name
        (numbers, booleans or strings; unknown names are errors).
    :ivar ego: the scenario object the env drives; ``""``: the one vehicle with an
        ``ObjectController``, else the one called ``Ego``.
    :ivar max_time: the episode is truncated at this simulation time [s] if the
        storyboard's stop trigger has not fired (``duration`` does not apply to a
        scenario).
    :ivar handover: when the function under test takes the ego: ``"action"``, at the
        scenario's ``ActivateControllerAction`` (never without one); ``"init"``, in
        both domains from the start, once ``Init`` has placed it (test protocols that
        name the vehicle under test and carry no controller, as Euro NCAP's files);
        an ``ActivateControllerAction`` later still changes the domains.

    With a scenario the map is its ``RoadNetwork/LogicFile`` (``road.xodr`` must not
    be set), its objects are the only traffic (``vehicles_count`` does not apply) and
    the episode ends when the stop trigger fires (docs/scenarios.md).
    """

    xosc: str = setting("", kind="str")
    parameters: Mapping[str, Any] = dataclasses.field(
        default_factory=dict, metadata={"rule": Rule(kind="any")}
    )
    ego: str = setting("", kind="str")
    max_time: float = setting(600.0, lo=0.0, lo_open=True, hi=100_000.0)
    handover: str = setting("action", choices=("action", "init"))

    def __post_init__(self) -> None:
        validate(self, "scenario")
        if not isinstance(self.parameters, Mapping):
            raise ConfigError(
                f"scenario.parameters must be a mapping of name -> value, got "
                f"{type(self.parameters).__name__}"
            )
        for name, value in self.parameters.items():
            if not isinstance(name, str):
                raise ConfigError(f"scenario.parameters keys must be names (str), got {name!r}")
            if not isinstance(value, bool | int | float | str):
                raise ConfigError(
                    f"scenario.parameters[{name!r}] must be a number, a boolean or a string, "
                    f"got {type(value).__name__}"
                )
        object.__setattr__(self, "parameters", dict(self.parameters))

    @property
    def enabled(self) -> bool:
        """Whether a scenario is set."""
        return bool(self.xosc)
