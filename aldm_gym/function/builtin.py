"""Functions under test that come with the package or wrap what a user has.

* :class:`BuiltinFunction`: the env's own function (LKA on the detected trajectory,
  ACC/AEB, the rule-based lane change on request). It takes no domain: its requests are
  the env's built-in controllers themselves, and it decides only the lane changes.
* :class:`PolicyFunction`: a policy with SB3's ``predict`` (a trained model, or
  :class:`~aldm_gym.agents.policies.RuleBasedLCA`) on the env's observation. A meta-
  action policy is the function's lane-change and set-speed layer; a continuous one
  (steering, acceleration) takes both domains.
* :class:`CallableFunction`: a plain callable ``inputs -> FunctionOutput``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from aldm_gym.agents.policies import RuleBasedLCA
from aldm_gym.envs.actions import MetaAction, meta_action_index
from aldm_gym.errors import InputError
from aldm_gym.function.interface import DOMAINS, FunctionInput, FunctionOutput

__all__ = ["LANE_CHANGE_MODES", "BuiltinFunction", "CallableFunction", "PolicyFunction"]

LANE_CHANGE_MODES = ("none", "rule_based")
""":class:`BuiltinFunction`'s lane changes: never asked for (a scenario's default: the
ego keeps its lane), or the rule-based LCA's (:class:`RuleBasedLCA`)."""


def _meta_output(action: int) -> FunctionOutput:
    """A meta action as a function's output (lane change or set-speed step)."""
    if action == MetaAction.LANE_LEFT:
        return FunctionOutput(lane_change=1)
    if action == MetaAction.LANE_RIGHT:
        return FunctionOutput(lane_change=-1)
    if action == MetaAction.FASTER:
        return FunctionOutput(speed_step=1)
    if action == MetaAction.SLOWER:
        return FunctionOutput(speed_step=-1)
    return FunctionOutput()


class BuiltinFunction:
    """The env's own function: LKA on the detected trajectory, ACC/AEB, and lane
    changes by ``lane_changes`` (:data:`LANE_CHANGE_MODES`).

    :param lane_changes: ``"none"``: never (the IDLE meta action); ``"rule_based"``: the
        rule-based LCA decides on the observation.
    """

    domains: frozenset[str] = frozenset()
    """None: the env's LKA steers and its ACC/AEB sets the speed."""

    def __init__(self, lane_changes: str = "none") -> None:
        if lane_changes not in LANE_CHANGE_MODES:
            raise InputError(
                f"lane_changes must be one of {', '.join(LANE_CHANGE_MODES)}, got {lane_changes!r}"
            )
        self.lane_changes = lane_changes
        self._lca = RuleBasedLCA() if lane_changes == "rule_based" else None

    def reset(self) -> None:
        """Forget the lane-change cooldown."""
        if self._lca is not None:
            self._lca.reset()

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        """No request but the rule-based LCA's lane change or set-speed step."""
        if self._lca is None:
            return FunctionOutput()
        if inputs.observation is None:
            raise InputError("the rule-based lane change decides on the env's observation")
        return _meta_output(self._lca.act(dict(inputs.observation)))


class PolicyFunction:
    """A policy with SB3's ``predict`` as a function under test.

    :param policy: anything with ``predict(observation, deterministic=True)``; a
        ``uses_action_masks`` policy (MaskablePPO) also gets the env's action mask.
    :param continuous: the policy's action is ``(steering [rad], acceleration [m/s²])``
        (``ContinuousAction``): it takes both domains. Otherwise its action is a meta
        action: it decides lane changes and the set speed; the env's LKA and ACC/AEB
        drive.
    :param env_config: the env settings the policy needs (the observation it was
        trained on).
    :param name: for messages.
    """

    def __init__(
        self,
        policy: Any,
        continuous: bool = False,
        env_config: Mapping[str, Any] | None = None,
        name: str = "policy",
    ) -> None:
        if not callable(getattr(policy, "predict", None)):
            raise InputError(f"{name} has no predict(observation) (SB3's policy interface)")
        self.policy = policy
        self.continuous = bool(continuous)
        self.domains = DOMAINS if self.continuous else frozenset()
        self.env_config: dict[str, Any] = dict(env_config or {})
        self.name = name

    @classmethod
    def from_model(cls, path: Any) -> PolicyFunction:
        """A trained model (what ``aldm-gym evaluate --model`` takes: an SB3 ``.zip``,
        an RLlib checkpoint folder, or a training's output folder), with the
        observation it was trained on.

        :raises FileNotFoundError, CheckpointError, MissingRLDependencies: see
            :func:`~aldm_gym.training.models.load_policy`.
        """
        from aldm_gym.training.models import load_policy

        policy, record = load_policy(path)
        trained = record.env_config
        env_config = (
            {"observation": dict(trained["observation"])} if "observation" in trained else {}
        )
        return cls(
            policy,
            continuous=trained.settings.action.type == "ContinuousAction",
            env_config=env_config,
            name=str(path),
        )

    def reset(self) -> None:
        """Reset the policy's own state, if it has a ``reset``."""
        reset = getattr(self.policy, "reset", None)
        if callable(reset):
            reset()

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        """The policy's action on the step's observation, as requests."""
        if inputs.observation is None:
            raise InputError(f"{self.name} acts on the env's observation; the input has none")
        kwargs: dict[str, Any] = {"deterministic": True}
        if getattr(self.policy, "uses_action_masks", False) and inputs.action_mask is not None:
            kwargs["action_masks"] = inputs.action_mask
        action, _ = self.policy.predict(dict(inputs.observation), **kwargs)
        if self.continuous:
            a = np.asarray(action, dtype=np.float64).reshape(-1)
            if a.shape != (2,):
                raise InputError(f"{self.name}: a continuous action has 2 values, got {action!r}")
            return FunctionOutput(steering=float(a[0]), acceleration=float(a[1]))
        return _meta_output(meta_action_index(action))


class CallableFunction:
    """A callable ``fn(inputs: FunctionInput) -> FunctionOutput`` as a function.

    :param fn: the callable.
    :param domains: the domains it takes (default: its own ``domains`` attribute, else
        both).
    """

    def __init__(self, fn: Callable[[FunctionInput], FunctionOutput], domains: Any = None) -> None:
        if not callable(fn):
            raise InputError(f"{fn!r} is not callable")
        self.fn = fn
        chosen = domains if domains is not None else getattr(fn, "domains", DOMAINS)
        self.domains = frozenset(chosen)

    def reset(self) -> None:
        """Nothing to forget (a plain callable has no episode state)."""

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        """``fn(inputs)``."""
        return self.fn(inputs)
