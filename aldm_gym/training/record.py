"""A training's record (``training.json``): what was trained, how, and on which env.

:class:`TrainingRecord` is the record as the code reads it: typed, checked once when
it is made (:meth:`TrainingRecord.from_dict`, :meth:`TrainingRecord.read`), and
serialized only at the file (:meth:`TrainingRecord.to_json`), as Gymnasium's
``EnvSpec`` is. The file keeps its flat layout, so that a record written before this
class existed reads the same::

    {"algorithm": "PPO", "backend": "sb3", "env_id": "ALDMHighway-v0",
     "env_config": {...}, "ppo": {...},
     "timesteps": 49152, "n_envs": 1, "seed": 0, "checkpoint_freq": 4096,
     "validation_freq": 4096, "validation_episodes": 20,      (SB3)
     "num_env_runners": 1,                                      (RLlib)
     "keep_by": "return", "pretrain": {...}}                    (SB3)

A key missing from an older record takes the value that record was trained with
(``algorithm`` PPO, ``backend`` sb3, ``lr_schedule`` constant, ``keep_by`` return,
each run setting its default).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aldm_gym.envs.config import EnvOverrides
from aldm_gym.errors import AldmGymError, CheckpointError, ConfigError
from aldm_gym.training.outputs import TRAINING_FILE, find_training_file, write_bytes_atomic
from aldm_gym.training.settings import (
    ALGORITHMS,
    DEFAULT_CHECKPOINT_FREQ,
    DEFAULT_ENV_RUNNERS,
    DEFAULT_TIMESTEPS,
    DEFAULT_VALIDATION_EPISODES,
    DEFAULT_VALIDATION_FREQ,
    KEEP_BY,
    RUN_MAXIMUM,
    RUN_MINIMUM,
    PPOParams,
)

__all__ = [
    "BACKEND_RUN_SETTINGS",
    "MAX_RECORD_BYTES",
    "RunSettings",
    "TrainingRecord",
    "model_record",
    "resolve_run",
]

MAX_RECORD_BYTES = 1 << 20
"""The largest ``training.json`` read [bytes] (a record is a few kB)."""


@dataclass(frozen=True)
class RunSettings:
    """How long and how a training runs (``resume`` restores them unless given).

    :ivar timesteps: the training's budget [policy steps] (SB3) or [env steps] (RLlib).
    :ivar seed: seed of the envs (``seed + i`` for the i-th) and the network.
    :ivar checkpoint_freq: a checkpoint every this many steps.
    :ivar n_envs: envs run in parallel (SB3).
    :ivar validation_freq: a validation every this many steps, 0: none (SB3).
    :ivar validation_episodes: episodes per validation (SB3).
    :ivar num_env_runners: Ray env runners (RLlib).
    """

    timesteps: int = DEFAULT_TIMESTEPS
    seed: int = 0
    checkpoint_freq: int = DEFAULT_CHECKPOINT_FREQ
    n_envs: int = 1
    validation_freq: int = DEFAULT_VALIDATION_FREQ
    validation_episodes: int = DEFAULT_VALIDATION_EPISODES
    num_env_runners: int = DEFAULT_ENV_RUNNERS

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ConfigError(f"{f.name} must be an integer, got {value!r}")
            least = RUN_MINIMUM.get(f.name, 0)
            most = RUN_MAXIMUM[f.name]
            if not least <= value <= most:
                raise ConfigError(f"{f.name} must be in [{least}, {most}], got {value}")

    def of(self, backend: str) -> dict[str, int]:
        """The settings ``backend`` uses, by name (:data:`BACKEND_RUN_SETTINGS`)."""
        return {name: getattr(self, name) for name in BACKEND_RUN_SETTINGS[backend]}


BACKEND_RUN_SETTINGS: dict[str, tuple[str, ...]] = {
    "sb3": (
        "timesteps",
        "n_envs",
        "seed",
        "checkpoint_freq",
        "validation_freq",
        "validation_episodes",
    ),
    "rllib": ("timesteps", "num_env_runners", "seed", "checkpoint_freq"),
}
"""Each backend's run settings (of :class:`RunSettings`), in the record's order."""

_RUN_NAMES = tuple(f.name for f in dataclasses.fields(RunSettings))


def _check_backend(backend: Any) -> None:
    """Refuse a backend that is not a key of :data:`BACKEND_RUN_SETTINGS`."""
    if not isinstance(backend, str) or backend not in BACKEND_RUN_SETTINGS:
        raise ConfigError(f"backend must be one of {tuple(BACKEND_RUN_SETTINGS)}, got {backend!r}")


def _check_pretrain(pretrain: Any, backend: str) -> None:
    """Refuse a cloning record a resume cannot use (:class:`ConfigError` naming it)."""
    from aldm_gym.training.sb3.pretrain import MAX_PRETRAIN_EPISODES

    if backend != "sb3":
        raise ConfigError(f"pretrain is an SB3 setting; the {backend} backend has none")
    if not isinstance(pretrain, Mapping):
        raise ConfigError(f"pretrain must be a mapping, got {type(pretrain).__name__}")
    for name, least, most in (("episodes", 0, MAX_PRETRAIN_EPISODES), ("epochs", 1, 10**6)):
        value = pretrain.get(name)
        if isinstance(value, bool) or not isinstance(value, int) or not least <= value <= most:
            raise ConfigError(
                f"pretrain.{name} must be an integer in [{least}, {most}], got {value!r}"
            )


@dataclass(frozen=True)
class TrainingRecord:
    """What a training is: written to ``training.json`` once the trainer is built, read
    by a resume and by every command that loads the trained model.

    :ivar backend: ``"sb3"`` or ``"rllib"``.
    :ivar algorithm: a class name of :data:`~aldm_gym.training.settings.ALGORITHMS`.
    :ivar env_config: the env the policy was trained on (settings that differ from the
        defaults).
    :ivar ppo: the hyperparameters.
    :ivar run: the run settings (the file holds the backend's own, flat).
    :ivar keep_by: what the best model is kept by (SB3; None for RLlib).
    :ivar pretrain: the cloning's settings, then its report (SB3; None: no cloning).
    :ivar env_id: the Gymnasium id of the env.
    """

    backend: str
    algorithm: str
    env_config: EnvOverrides
    ppo: PPOParams = field(default_factory=PPOParams)
    run: RunSettings = field(default_factory=RunSettings)
    keep_by: str | None = None
    pretrain: Mapping[str, Any] | None = None
    env_id: str = "ALDMHighway-v0"

    def __post_init__(self) -> None:
        _check_backend(self.backend)
        if self.algorithm not in ALGORITHMS.values():
            raise ConfigError(
                f"algorithm must be one of {tuple(ALGORITHMS.values())}, got {self.algorithm!r}"
            )
        if self.keep_by is not None and self.keep_by not in KEEP_BY:
            raise ConfigError(f"keep_by must be one of {KEEP_BY}, got {self.keep_by!r}")
        if self.keep_by is not None and self.backend != "sb3":
            raise ConfigError(f"keep_by is an SB3 setting; the {self.backend} backend has none")
        if self.pretrain is not None:
            _check_pretrain(self.pretrain, self.backend)
        if not isinstance(self.env_config, EnvOverrides):
            object.__setattr__(self, "env_config", EnvOverrides(self.env_config))

    @property
    def run_settings(self) -> dict[str, int]:
        """The backend's run settings, by name (as the file holds them)."""
        return self.run.of(self.backend)

    def to_dict(self) -> dict[str, Any]:
        """The record in the file's layout (a plain, JSON-ready dict)."""
        out: dict[str, Any] = {
            "algorithm": self.algorithm,
            "backend": self.backend,
            "env_id": self.env_id,
            "env_config": self.env_config.to_dict(),
            "ppo": dataclasses.asdict(self.ppo),
            **self.run_settings,
        }
        if self.keep_by is not None:
            out["keep_by"] = self.keep_by
        if self.pretrain is not None:
            out["pretrain"] = json.loads(json.dumps(dict(self.pretrain)))
        return out

    def to_json(self) -> str:
        """The record as the file's text (indented JSON)."""
        return json.dumps(self.to_dict(), indent=2) + "\n"

    def write(self, path: Path) -> None:
        """Write the record to ``path`` atomically."""
        write_bytes_atomic(Path(path), self.to_json().encode())

    @classmethod
    def from_dict(cls, data: Any) -> TrainingRecord:
        """A record from the file's layout, checked: every key known, every value in
        its range, the env config valid.

        :raises ConfigError: naming the key and the allowed ones, or the bad value.
        """
        if not isinstance(data, Mapping):
            raise ConfigError(f"a training record is a JSON object, got {type(data).__name__}")
        known = ("algorithm", "backend", "env_id", "env_config", "ppo", "keep_by", "pretrain")
        unknown = sorted(set(data) - set(known) - set(_RUN_NAMES))
        if unknown:
            raise ConfigError(
                f"unknown key(s) {unknown}; allowed keys: {sorted((*known, *_RUN_NAMES))}"
            )
        backend = data.get("backend", "sb3")
        _check_backend(backend)  # before its run settings are looked up
        if "env_config" not in data:
            raise ConfigError("no env_config")
        if not isinstance(data["env_config"], Mapping):
            raise ConfigError(
                f"env_config must be an object, got {type(data['env_config']).__name__}"
            )
        ppo = data.get("ppo", {})
        if not isinstance(ppo, Mapping):
            raise ConfigError(f"ppo must be an object, got {type(ppo).__name__}")
        try:
            params = PPOParams.saved(ppo)
        except TypeError as exc:
            raise ConfigError(f"ppo: {exc}") from None
        run = {name: data[name] for name in _RUN_NAMES if name in data}
        others = sorted(set(run) - set(BACKEND_RUN_SETTINGS[backend]))
        if others:
            raise ConfigError(f"{others} are not run settings of the {backend} backend")
        keep_by = data.get("keep_by")
        if backend == "sb3" and keep_by is None:
            keep_by = "return"  # before keep_by existed: the return
        return cls(
            backend=backend,
            algorithm=data.get("algorithm", "PPO"),
            env_config=EnvOverrides(data["env_config"]),
            ppo=params,
            run=RunSettings(**run),
            keep_by=keep_by,
            pretrain=data.get("pretrain"),
            env_id=str(data.get("env_id", "ALDMHighway-v0")),
        )

    @classmethod
    def from_json(cls, text: str | bytes) -> TrainingRecord:
        """A record from the file's text (:meth:`from_dict`).

        :raises ConfigError: not JSON, or as :meth:`from_dict`.
        """
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise ConfigError(f"not JSON ({exc})") from None
        return cls.from_dict(data)

    @classmethod
    def read(cls, path: Path) -> TrainingRecord:
        """The record in the file ``path``.

        :raises FileNotFoundError: no such file.
        :raises CheckpointError: it is not a training record (naming the file and why).
        """
        path = Path(path)
        size = path.stat().st_size
        if size > MAX_RECORD_BYTES:
            raise CheckpointError(
                f"{path}: not a training record ({size} bytes; a record is at most "
                f"{MAX_RECORD_BYTES})"
            )
        try:
            return cls.from_json(path.read_bytes())
        except (AldmGymError, RecursionError) as exc:
            raise CheckpointError(f"{path}: not a training record ({exc})") from None


def resolve_run(
    given: Mapping[str, int | None], saved: TrainingRecord | None, backend: str = "sb3"
) -> tuple[RunSettings, list[str]]:
    """The run settings of a training and, for a resume, what was restored/overridden.

    :param given: each of the backend's run settings as passed (None: not given).
    :param saved: the record being resumed, or None for a new training.
    :param backend: whose settings (a key of :data:`BACKEND_RUN_SETTINGS`).
    :return: the settings (a setting given wins; else a resume's saved one; else the
        default), and lines saying which were restored from ``saved`` and which were
        overridden (empty for a new training).
    :raises ConfigError: a setting out of its range.
    """
    base = RunSettings() if saved is None else saved.run
    chosen = {name: given.get(name) for name in BACKEND_RUN_SETTINGS[backend]}
    settings = dataclasses.replace(
        base, **{name: int(value) for name, value in chosen.items() if value is not None}
    )
    if saved is None:
        return settings, []
    restored, overridden = [], []
    for name, value in chosen.items():
        was = getattr(base, name)
        if value is None or int(value) == was:
            restored.append(f"{name}={was}")
        else:
            overridden.append(f"{name}={int(value)} (was {was})")
    report = ["restored: env config, PPO hyperparameters, " + ", ".join(restored)]
    if overridden:
        report.append("overridden: " + ", ".join(overridden))
    return settings, report


def model_record(model_path: Path) -> TrainingRecord:
    """The record of a trained model: the ``training.json`` beside it, or one folder up
    (a checkpoint's).

    :raises FileNotFoundError: there is none.
    :raises CheckpointError: it is not a training record.
    """
    path = find_training_file(Path(model_path))
    if path is None:
        raise FileNotFoundError(
            f"no {TRAINING_FILE} next to {model_path} (written by aldm-gym train)"
        )
    return TrainingRecord.read(path)
