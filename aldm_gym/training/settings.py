"""What a training is: the env config, the PPO hyperparameters and the run settings.

Both backends train the same task from these: :func:`env_config` (``ALDMHighway-v0``
with one detector's lanes in the observation), :class:`PPOParams` (SB3's names; the
RLlib backend maps them onto RLlib's) and the defaults of the run settings (budget,
workers, seed, checkpoint and validation periods:
:class:`~aldm_gym.training.record.RunSettings`, which ``resume`` restores from
``training.json`` unless given). Each default lives here once.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from aldm_gym.envs.config import EnvOverrides, merged_config
from aldm_gym.errors import ConfigError

DEFAULT_TIMESTEPS = 49_152
"""Default training budget [policy steps] (about 15 min on 2 cores, see docs/results.md)."""

DEFAULT_COLLISION_REWARD = -2.0
"""Collision weight of a training's reward (the env's default is -1; see docs/results.md)."""

DEFAULT_CHECKPOINT_FREQ = 4_096
"""Default checkpoint period [policy steps]."""

DEFAULT_VALIDATION_FREQ = 4_096
"""Default validation period [policy steps] (SB3 backend)."""

DEFAULT_VALIDATION_EPISODES = 20
"""Default episodes per validation (SB3 backend)."""

DEFAULT_PRETRAIN_EPOCHS = 30
"""Default passes over the demonstrations when cloning the rule-based LCA (SB3 backend,
:mod:`aldm_gym.training.sb3.pretrain`)."""

FAILURE_PENALTY = 10.0
"""Score lost per unit of failed-episode share [m/s] (one failure in 20 costs 0.5):
see :func:`validation_score`."""

KEEP_BY = ("return", "score")
"""What a training keeps as its best model (SB3 backend): the validation with the
highest mean return, or with the highest :func:`validation_score`."""

DEFAULT_ENV_RUNNERS = 1
"""Default ``--num-env-runners`` (RLlib backend)."""

VALIDATION_SEED = 20_000
"""First seed of the validation episodes (training envs use ``seed ..``, evaluation 10000..)."""

LR_SCHEDULES = ("constant", "linear")
"""Learning-rate schedules of :class:`PPOParams`."""

ALGORITHMS: dict[str, str] = {"ppo": "PPO", "maskable-ppo": "MaskablePPO"}
"""The learning algorithms by ``--algo`` name, each to its class name (``training.json``'s
``algorithm``): stable-baselines3's PPO, and sb3-contrib's MaskablePPO, which samples
only the actions the env's ``action_masks()`` allows (lane changes only towards a
detected adjacent lane)."""


def validation_score(row: Mapping[str, Any]) -> float:
    """A validation's score [m/s]: ``mean_speed - FAILURE_PENALTY * (1 - success_rate)``.

    What the lane-change results ask for (speed, without collisions or departures), on
    a scale that does not depend on the reward's weights (``aldm-gym tune`` compares
    trials by it; ``keep_by="score"`` keeps the model by it).
    """
    return float(row["mean_speed"]) - FAILURE_PENALTY * (1.0 - float(row["success_rate"]))


def check_keep_by(keep_by: str) -> None:
    """Refuse a ``keep_by`` not in :data:`KEEP_BY` (:class:`ConfigError` naming them)."""
    if keep_by not in KEEP_BY:
        raise ConfigError(f"keep_by must be one of {KEEP_BY}, got {keep_by!r}")


def algorithm_name(algo: str) -> str:
    """The class name of ``--algo`` ``algo`` (:data:`ALGORITHMS`).

    :raises ConfigError: an unknown algorithm, naming the known ones.
    """
    if algo not in ALGORITHMS:
        raise ConfigError(f"algo must be one of {tuple(ALGORITHMS)}, got {algo!r}")
    return ALGORITHMS[algo]


RUN_MINIMUM = {
    "timesteps": 1,
    "n_envs": 1,
    "num_env_runners": 0,
    "checkpoint_freq": 1,
    "validation_freq": 0,
    "validation_episodes": 0,
}
"""The least value of each bounded run setting (``seed`` is any integer)."""

MAX_N_ENVS = 64
"""Most ``n_envs`` (SB3: each is a subprocess)."""

MAX_ENV_RUNNERS = 1024
"""Most ``num_env_runners`` (RLlib)."""

MAX_SEED = 2**31 - 1
"""The largest seed a training's record holds (the command line's bound)."""

RUN_MAXIMUM = {
    "timesteps": 10**12,
    "n_envs": MAX_N_ENVS,
    "num_env_runners": MAX_ENV_RUNNERS,
    "checkpoint_freq": 10**12,
    "validation_freq": 10**12,
    "validation_episodes": 10_000,
    "seed": MAX_SEED,
}
"""The largest value of each run setting a training's record may hold (checked when it
is read, before anything is built from it)."""


MAX_N_STEPS = 1_000_000
"""The longest rollout per env [policy steps] (``--n-steps``' bound)."""

MAX_LAYERS = 16
"""The most hidden layers of the policy and value networks."""

MAX_UNITS = 4_096
"""The most units of a hidden layer."""


@dataclass
class PPOParams:
    """PPO hyperparameters (SB3 names).

    Defaults follow highway-env's PPO example for the meta actions (``gamma`` 0.8:
    at 1 Hz the reward of the next ~5 s matters; lr 5e-4, 10 epochs, batch 64), with
    the learning rate decaying linearly (see ``docs/results.md`` (b) for why).

    :ivar n_steps: rollout length per environment [policy steps].
    :ivar lr_schedule: ``"constant"``, or ``"linear"``: ``learning_rate`` decays
        linearly to 0 at the end of the budget (SB3's ``progress_remaining``).
    """

    n_steps: int = 256
    batch_size: int = 64
    n_epochs: int = 10
    learning_rate: float = 5e-4
    gamma: float = 0.8
    gae_lambda: float = 0.95
    ent_coef: float = 0.01
    clip_range: float = 0.2
    net_arch: list[int] = field(default_factory=lambda: [128, 128])
    lr_schedule: str = "linear"

    def __post_init__(self) -> None:
        if self.lr_schedule not in LR_SCHEDULES:
            raise ConfigError(
                f"lr_schedule must be one of {LR_SCHEDULES}, got {self.lr_schedule!r}"
            )
        # Bounds before anything is allocated: the rollout buffer holds n_steps rows
        # per env, the network net_arch units per layer.
        for name, lo, hi in (
            ("n_steps", 2, MAX_N_STEPS),
            ("batch_size", 1, MAX_N_STEPS),
            ("n_epochs", 1, 1_000),
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
                raise ConfigError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
        for name, low, high, open_low in (
            ("learning_rate", 0.0, 1.0, True),
            ("gamma", 0.0, 1.0, False),
            ("gae_lambda", 0.0, 1.0, False),
            ("ent_coef", 0.0, 1e3, False),
            ("clip_range", 0.0, 1e3, True),
        ):
            value = getattr(self, name)
            ok = (
                isinstance(value, int | float)
                and not isinstance(value, bool)
                and math.isfinite(value)
                and (low < value if open_low else low <= value)
                and value <= high
            )
            if not ok:
                bracket = "(" if open_low else "["
                raise ConfigError(f"{name} must be in {bracket}{low}, {high}], got {value!r}")
        arch = self.net_arch
        if (
            not isinstance(arch, list | tuple)
            or not 1 <= len(arch) <= MAX_LAYERS
            or not all(
                isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= MAX_UNITS for n in arch
            )
        ):
            raise ConfigError(
                f"net_arch must be 1 to {MAX_LAYERS} layer sizes in [1, {MAX_UNITS}], got {arch!r}"
            )

    @classmethod
    def saved(cls, record: Mapping[str, Any]) -> PPOParams:
        """The hyperparameters of a ``training.json``'s ``"ppo"`` (a record without
        ``lr_schedule`` trained with a constant rate)."""
        return cls(**{"lr_schedule": "constant", **record})

    def learning_rate_schedule(self) -> float | Callable[[float], float]:
        """What SB3's ``learning_rate`` argument takes for this schedule."""
        if self.lr_schedule == "linear":
            return functools.partial(linear_schedule, self.learning_rate)
        return self.learning_rate


def linear_schedule(start: float, progress_remaining: float) -> float:
    """``start`` scaled by SB3's ``progress_remaining`` (1 at the start, 0 at the end)."""
    return start * progress_remaining


NAMED_ENV_KEYS = (
    "detector",
    "marking_model",
    "duration",
    "vehicles_count",
    "collision_reward",
    "overtaking_reward",
)
"""Env settings :func:`env_config` takes as named arguments (not in ``env_overrides``)."""


def env_config(
    detector: str = "aldm",
    marking_model: str = "per_dash",
    duration: float | None = None,
    vehicles_count: int | None = None,
    collision_reward: float | None = None,
    overtaking_reward: float | None = None,
    env_overrides: Mapping[str, Any] | None = None,
) -> EnvOverrides:
    """The ``ALDMHighway-v0`` settings of a training (only keys that differ from the
    defaults), validated once, here.

    :param collision_reward: weight of the collision term of the reward (env: -1).
    :param overtaking_reward: weight of the overtaking term (vehicles passed minus
        passed by; env: 0).
    :param env_overrides: any other env settings, merged over the rest as the env
        merges a config (a section's keys one by one), e.g.
        ``{"detector_params": {"tracking": "model"}, "observation":
        {"line_confidence": True}}``; the keys of the named arguments above are
        refused here (give them as those arguments).
    :raises ConfigError: unknown detector or marking model; an unknown or bad setting
        in ``env_overrides`` (naming the key and the allowed ones), or one of the named
        arguments' keys there.
    """
    config: dict[str, Any] = {"detector": detector, "marking_model": marking_model}
    if duration is not None:
        config["duration"] = float(duration)
    if vehicles_count is not None:
        config["vehicles_count"] = int(vehicles_count)
    if collision_reward is not None:
        config["collision_reward"] = float(collision_reward)
    if overtaking_reward is not None:
        config["overtaking_reward"] = float(overtaking_reward)
    if env_overrides:
        if not isinstance(env_overrides, Mapping):
            raise ConfigError(
                f"env_overrides must be a mapping, got {type(env_overrides).__name__}"
            )
        named = sorted(set(env_overrides) & set(NAMED_ENV_KEYS))
        if named:
            raise ConfigError(
                f"env_overrides may not set {named}: give them as the training's own "
                f"arguments ({', '.join(NAMED_ENV_KEYS)})"
            )
        config = merged_config(config, env_overrides)
    return EnvOverrides(config)


def dotted_settings(config: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """``(key, value)`` of every setting of a nested env config, a section's key as
    ``SECTION.KEY`` (the form ``aldm-gym train --env`` takes), in the config's order."""
    for key, value in config.items():
        if isinstance(value, Mapping):
            yield from dotted_settings(value, f"{prefix}{key}.")
        else:
            yield f"{prefix}{key}", value


def check_run_settings(given: Mapping[str, int | None]) -> None:
    """Refuse a run setting below its least value (:data:`RUN_MINIMUM`).

    :raises ConfigError: naming the setting, its least value and the value given.
    """
    for name, value in given.items():
        least = RUN_MINIMUM.get(name)
        if value is not None and least is not None and value < least:
            raise ConfigError(f"{name} must be >= {least}, got {value}")
