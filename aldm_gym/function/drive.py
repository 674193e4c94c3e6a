"""Drive ``ALDMHighway-v0`` with a function under test: its inputs from the env's
perception, its requests into the env.

:class:`FunctionDriver` is the loop's one step: it builds the :class:`FunctionInput`
of the current step (:func:`function_input`), steps the function, checks its output,
hands the acceleration and steering to the env (``env.request``) and the lane change
or set-speed step to the env's meta action, and steps the env.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from aldm_gym.envs.actions import MetaAction
from aldm_gym.envs.config import EnvOverrides
from aldm_gym.envs.lane_end import map_lane_end
from aldm_gym.errors import AldmGymWarning, InputError
from aldm_gym.function.interface import (
    DOMAINS,
    LINE_ROLES,
    EgoState,
    Function,
    FunctionInput,
    FunctionOutput,
    PerceivedLine,
    PerceivedObject,
    check_output,
)

__all__ = [
    "FunctionDriver",
    "FunctionPolicy",
    "check_function",
    "close_function",
    "env_for",
    "function_input",
    "meta_action",
]


def check_function(function: Any) -> Function:
    """``function`` if it has the :class:`Function` protocol, with ``domains`` a
    frozenset of :data:`DOMAINS`.

    :raises InputError: naming what is missing.
    """
    missing = [name for name in ("step", "reset") if not callable(getattr(function, name, None))]
    if missing or not hasattr(function, "domains"):
        missing += [] if hasattr(function, "domains") else ["domains"]
        raise InputError(
            f"{type(function).__name__} is not a function under test: it has no "
            f"{', '.join(missing)} (aldm_gym.function.Function: domains, reset(), step())"
        )
    domains = function.domains
    try:
        ok = not isinstance(domains, str) and set(domains) <= DOMAINS
    except TypeError:  # not a collection
        ok = False
    if not ok:
        raise InputError(
            f"{type(function).__name__}.domains must be a set of {sorted(DOMAINS)}, got {domains!r}"
        )
    return function  # type: ignore[no-any-return]


def close_function(function: Any) -> bool:
    """Call a function's ``close()`` (an FMU's: its instance and files), if it has one;
    whether it had one."""
    close = getattr(function, "close", None)
    if callable(close):
        close()
        return True
    return False


def env_for(function: Function, config: Mapping[str, Any], given: Any = ()) -> EnvOverrides:
    """``config`` with the env settings ``function`` needs, validated
    (:class:`~aldm_gym.envs.config.EnvOverrides`, what ``gym.make`` takes as it is).

    * Its ``env_config`` (e.g. the observation a policy was trained on) is merged in.
    * A function that takes a domain is stepped at every simulation step: its
      ``policy_frequency`` is the ``simulation_frequency`` unless it or ``config``
      says otherwise.

    :param given: the top-level keys the user set; one the function needs otherwise is
        an error.
    :raises ConfigError: naming the key the user set and the value the function needs,
        or an unknown or bad setting.
    """
    from aldm_gym.envs.config import EnvConfig, env_overrides
    from aldm_gym.errors import ConfigError

    out = dict(config)
    needs = dict(getattr(function, "env_config", None) or {})
    for key, value in needs.items():
        if key in given and out.get(key) != value:
            raise ConfigError(
                f"{key}: the function under test needs {value!r}, the settings give "
                f"{out.get(key)!r}"
            )
        out[key] = value
    if function.domains and "policy_frequency" not in needs and "policy_frequency" not in given:
        out["policy_frequency"] = out.get("simulation_frequency", EnvConfig().simulation_frequency)
    return env_overrides(config) if out == dict(config) else env_overrides(out)


def function_input(
    env: Any, observation: Mapping[str, Any] | None = None, action_mask: Any = None
) -> FunctionInput:
    """The inputs of the env's current step: the detection, the ego's motion and the
    object sensor's objects (sensor frame).

    :param env: an ``ALDMHighway-v0`` (wrapped or not) after ``reset`` or ``step``.
    :param observation, action_mask: the env's observation and ``info["action_mask"]``
        of the same step, passed through.
    """
    u = env.unwrapped
    perception = u.perception
    detection = perception.detection
    confidence = getattr(detection, "confidence", None)
    lines = []
    for i, role in enumerate(LINE_ROLES):
        points = np.array(detection.line(role), dtype=np.float64)
        c = None if confidence is None else float(np.clip(confidence[i], 0.0, 1.0))
        lines.append(PerceivedLine(role, points, c if len(points) >= 2 or c is None else 0.0))
    ego = u.vehicle
    objects = perception.objects if u.longitudinal is not None else None
    if objects is None:  # no ACC: the object sensor is read here
        objects = perception.sense_objects(u.road, ego)
    sensed = tuple(
        PerceivedObject(
            int(objects.ids[k]),
            float(objects.x[k]),
            float(objects.y[k]),
            float(objects.vx[k]),
            float(objects.length[k]),
            float(objects.width[k]),
            float(objects.vy[k]),
        )
        for k in range(len(objects))
    )
    settings = u.settings
    horizon = None
    if not u.referee.off_map:
        horizon = map_lane_end(u.highway, u.lane_position, settings.lane_end.end_width)
    return FunctionInput(
        time=u.steps / float(settings.simulation_frequency),
        step=1.0 / float(settings.policy_frequency),
        lines=tuple(lines),
        ego=EgoState(
            speed=float(ego.speed),
            yaw_rate=float(ego.yaw_rate),
            acceleration=float(ego.action["acceleration"]) if ego.action else 0.0,
            steering=float(ego.steering_iso),
        ),
        objects=sensed,
        lane_change=int(ego.lane_change),
        observation=observation,
        action_mask=None if action_mask is None else np.asarray(action_mask, dtype=bool),
        lane_end_distance=math.inf if horizon is None else horizon.distance,
        lane_end_side=0 if horizon is None else horizon.side,
    )


def meta_action(output: FunctionOutput) -> int:
    """The env's meta action for an output: its lane change, else its set-speed step,
    else IDLE (one meta action per step: a lane change goes first)."""
    if output.lane_change:
        return int(MetaAction.LANE_LEFT if output.lane_change > 0 else MetaAction.LANE_RIGHT)
    if output.speed_step:
        return int(MetaAction.FASTER if output.speed_step > 0 else MetaAction.SLOWER)
    return int(MetaAction.IDLE)


class FunctionDriver:
    """An ``ALDMHighway-v0`` driven by a function under test, step by step.

    :param env: the env (meta actions: ``action.type="DiscreteMetaAction"``).
    :param function: a :class:`Function`.

    A function that takes a domain is stepped once per env step: at the default
    ``policy_frequency`` of 1 Hz it would steer blind for a second, so the driver warns;
    :func:`env_for` gives the settings that step it at every simulation step.

    Example::

        env = gym.make("ALDMHighway-v0", config=env_for(MyLKA(), {}))
        driver = FunctionDriver(env, MyLKA())
        obs, info = driver.reset(seed=0)
        while True:
            obs, reward, terminated, truncated, info = driver.step()
            if terminated or truncated:
                break

    :raises InputError: the env's actions are continuous, or ``function`` lacks the
        protocol.
    """

    def __init__(self, env: Any, function: Function) -> None:
        self._policy = FunctionPolicy(env, function)  # checks the env and the function
        self.env = env
        self.function = function
        settings = env.unwrapped.settings
        if function.domains and settings.policy_frequency < settings.simulation_frequency:
            warnings.warn(
                f"{type(function).__name__} takes the {' and '.join(sorted(function.domains))} "
                f"domain but is stepped at policy_frequency={settings.policy_frequency} Hz "
                f"while the simulation runs at {settings.simulation_frequency} Hz; "
                "config=env_for(function, config) steps it at every simulation step",
                AldmGymWarning,
                stacklevel=2,
            )
        self.observation: Any = None
        self.info: dict[str, Any] = {}

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the env (``kwargs``: ``seed``, ``options``) and the function."""
        self.observation, self.info = self.env.reset(**kwargs)
        self.function.reset()
        return self.observation, self.info

    def step(self) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Step the function on this step's inputs, then the env on its requests;
        the env's ``(observation, reward, terminated, truncated, info)``.

        :raises InputError: the function's output is not a valid
            :class:`FunctionOutput` for its domains.
        """
        action, _ = self._policy.predict(
            self.observation, action_masks=self.info.get("action_mask")
        )
        result = self.env.step(action)
        self.observation, self.info = result[0], result[4]
        return result


class FunctionPolicy:
    """A function under test behind SB3's ``predict``, for the loops that step an env
    with a policy (:func:`~aldm_gym.agents.episodes.run_episodes`, the closed-loop
    comparison, ``evaluate``).

    ``predict`` is called with the observation of the env's current step, just before
    ``env.step``: it steps the function on that step's inputs, hands its acceleration
    and steering to the env (``env.request``) and returns the meta action of its lane
    change or set-speed step.

    :param env: the env the loop steps (wrapped or not).
    :param function: a :class:`Function`.
    """

    uses_action_masks = True
    """The loop passes ``info["action_mask"]`` (a masked policy inside may need it)."""

    def __init__(self, env: Any, function: Function) -> None:
        if env.unwrapped.action_type.continuous:
            raise InputError(
                "a function under test drives an env with meta actions "
                "(action.type='DiscreteMetaAction'); its requests replace the action"
            )
        self.env = env
        self.function = check_function(function)
        self.domains = frozenset(function.domains)

    def reset(self) -> None:
        """Reset the function (the loop calls this at each episode's start)."""
        self.function.reset()

    def predict(
        self,
        observation: Mapping[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
        action_masks: Any = None,
    ) -> tuple[np.int64, Any]:
        """Step the function; ``(meta action, state)``."""
        inputs = function_input(self.env, observation, action_masks)
        output = self.function.step(inputs)
        check_output(output, self.domains, type(self.function).__name__)
        self.env.unwrapped.request(
            steering=output.steering,
            curvature=output.curvature,
            acceleration=output.acceleration,
        )
        return np.int64(meta_action(output)), state
