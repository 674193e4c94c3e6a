"""The env's ``osi`` settings section (:class:`OsiConfig`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from aldm_gym.config import setting, validate
from aldm_gym.errors import ConfigError

__all__ = ["OSI_EVERY", "OsiConfig"]

OSI_EVERY = ("step", "frame")
"""When the env writes: once per env step (its last sensor frame), or every frame."""


@dataclass(frozen=True)
class OsiConfig:
    """The ``osi`` section: write each step as ASAM OSI to a trace file.

    :ivar trace: path of the trace, ``*.mcap`` (one file, channels ``SensorView`` and
        ``SensorData``) or ``*.osi`` (``<stem>_sv.osi`` and ``<stem>_sd.osi``);
        ``{episode}`` in the name is replaced by the episode's number (from 0), else
        episode ``n > 0`` goes to ``<stem>_<n><suffix>``. ``""``: no trace.
    :ivar every: ``"step"``: one SensorView and one SensorData per env step (its last
        simulation step's sensor frame); ``"frame"``: one per simulation step, every
        sensor frame (``simulation_frequency / policy_frequency`` times the messages).
    """

    trace: str = setting("", kind="str")
    every: str = setting("step", choices=OSI_EVERY)

    def __post_init__(self) -> None:
        validate(self, "osi")
        if self.trace and Path(self.trace).suffix.lower() not in (".mcap", ".osi"):
            raise ConfigError(f"osi.trace must end in .mcap or .osi, got {self.trace!r}")

    @property
    def enabled(self) -> bool:
        """Whether a trace is written."""
        return bool(self.trace)

    def episode_path(self, episode: int) -> Path:
        """The trace file of episode ``episode`` (from 0)."""
        if "{episode}" in self.trace:
            return Path(self.trace.replace("{episode}", str(episode)))
        path = Path(self.trace)
        return path if episode == 0 else path.with_name(f"{path.stem}_{episode}{path.suffix}")
