"""Behaviour cloning of the rule-based LCA: a warm start for PPO and MaskablePPO.

A policy trained from scratch finds the lane-change skill late and unevenly across
seeds (``docs/results.md`` (b)). Cloning a competent teacher first and improving on it
with PPO is the recipe of DQfD and kickstarting (Hester et al., 2018; Schmitt et al.,
2018) in its simplest form: :func:`collect_demonstrations` plays the rule-based LCA
(:class:`~aldm_gym.agents.policies.RuleBasedLCA`) on its own episode seeds, and
:func:`clone` fits the new model's actor to its actions (cross-entropy over the
actions the env allows) and its critic to the discounted returns of those episodes
(Monte-Carlo, not bootstrapped: an episode's last steps see only the reward up to its
end), on observations normalised by the training's ``VecNormalize`` (whose statistics
start from the demonstrations'). PPO then continues from the clone.

The teacher's cooldown between lane changes is not in the observation; the clone
learns it only as far as the vehicles and lines show it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from aldm_gym import ENV_ID
from aldm_gym.agents.policies import RuleBasedLCA
from aldm_gym.envs.actions import MetaAction
from aldm_gym.errors import ConfigError

PRETRAIN_SEED = 30_000
"""First seed of the demonstration episodes: those of training seed ``s`` are
``PRETRAIN_SEED + MAX_PRETRAIN_EPISODES * s + i``, apart from the evaluation seeds
(10000.., up to 20000 episodes), the validation seeds (20000.., up to 10000) and the
training envs' first seeds (``s + i``, ``s`` below 30000)."""

MAX_PRETRAIN_EPISODES = 10_000
"""Most demonstration episodes per training."""

BATCH_SIZE = 256
"""Minibatch of the cloning's gradient steps [samples]."""

LEARNING_RATE = 1e-3
"""Adam learning rate of the cloning (its own optimiser, not PPO's)."""

VALUE_WEIGHT = 0.5
"""Weight of the critic's squared error beside the actor's cross-entropy."""


@dataclass(frozen=True)
class Demonstrations:
    """The teacher's steps, in play order.

    :ivar observations: the env's observation dict, each entry ``(N, ...)`` float32.
    :ivar actions: the teacher's meta actions ``(N,)``.
    :ivar masks: the env's action masks at each step ``(N, 5)`` bool.
    :ivar returns: discounted return from each step to its episode's end ``(N,)``.
    :ivar episodes: episodes played.
    """

    observations: dict[str, np.ndarray]
    actions: np.ndarray
    masks: np.ndarray
    returns: np.ndarray
    episodes: int

    def __len__(self) -> int:
        return int(self.actions.shape[0])


@dataclass(frozen=True)
class CloneReport:
    """What a cloning did (saved as ``training.json``'s ``"pretrain"``).

    :ivar teacher: the cloned policy.
    :ivar episodes: demonstration episodes.
    :ivar steps: their steps cloned (a MaskablePPO clone leaves out steps whose action
        the mask rules out).
    :ivar epochs: passes over the demonstrations.
    :ivar seeds: first and last demonstration episode seed.
    :ivar accuracy: share of the demonstration steps where the clone's most likely
        action is the teacher's.
    :ivar accuracy_lane_change: the same over the teacher's lane-change steps (NaN
        when it changed no lane).
    :ivar value_rmse: the critic's RMS error on the returns.
    """

    teacher: str
    episodes: int
    steps: int
    epochs: int
    seeds: tuple[int, int]
    accuracy: float
    accuracy_lane_change: float
    value_rmse: float

    def record(self) -> dict[str, Any]:
        """A JSON-ready dict (NaN as None)."""
        out = asdict(self)
        out["seeds"] = list(self.seeds)
        if out["accuracy_lane_change"] != out["accuracy_lane_change"]:
            out["accuracy_lane_change"] = None
        return out

    def text(self) -> str:
        """One line for the training's log."""
        lc = self.accuracy_lane_change
        lc_text = "no lane changes" if lc != lc else f"{lc:.3f} of its lane changes"
        return (
            f"cloned the {self.teacher} on {self.episodes} episodes ({self.steps} steps, "
            f"seeds {self.seeds[0]}..{self.seeds[1]}, {self.epochs} epochs): the clone "
            f"takes its action on {self.accuracy:.3f} of the steps ({lc_text}); "
            f"critic RMS error {self.value_rmse:.3f}"
        )


def check_pretrain(episodes: int, epochs: int) -> None:
    """Refuse cloning settings out of range.

    :raises ConfigError: ``episodes`` outside ``0..MAX_PRETRAIN_EPISODES`` (0: no
        cloning) or ``epochs`` < 1, naming the setting.
    """
    if not 0 <= episodes <= MAX_PRETRAIN_EPISODES:
        raise ConfigError(
            f"pretrain_episodes must be in 0..{MAX_PRETRAIN_EPISODES}, got {episodes}"
        )
    if epochs < 1:
        raise ConfigError(f"pretrain_epochs must be >= 1, got {epochs}")


def demonstration_seeds(seed: int, episodes: int) -> range:
    """The demonstration episode seeds of training seed ``seed``.

    :raises ConfigError: ``episodes`` outside ``1..MAX_PRETRAIN_EPISODES``.
    """
    if not 1 <= episodes <= MAX_PRETRAIN_EPISODES:
        raise ConfigError(
            f"pretrain_episodes must be in 1..{MAX_PRETRAIN_EPISODES}, got {episodes}"
        )
    first = PRETRAIN_SEED + MAX_PRETRAIN_EPISODES * seed
    return range(first, first + episodes)


def discounted_returns(rewards: np.ndarray, ends: np.ndarray, gamma: float) -> np.ndarray:
    """Return from each step to the end of its episode, ``sum_k gamma^k r_{t+k}``.

    :param rewards: rewards in play order ``(N,)``.
    :param ends: True at each episode's last step ``(N,)``.
    :param gamma: discount per step, in [0, 1].
    """
    out = np.zeros(len(rewards))
    g = 0.0
    for i in range(len(rewards) - 1, -1, -1):
        if ends[i]:
            g = 0.0
        g = float(rewards[i]) + gamma * g
        out[i] = g
    return out


def collect_demonstrations(
    env_config: Mapping[str, Any], seeds: range, gamma: float, progress: bool = False
) -> Demonstrations:
    """Play the rule-based LCA on ``seeds`` in ``ALDMHighway-v0`` with ``env_config``.

    :param gamma: the discount of the returns (the training's).
    :param progress: a tqdm bar over the episodes.
    :raises ConfigError: no seeds.
    """
    if len(seeds) == 0:
        raise ConfigError("no demonstration episodes to play (empty seeds)")
    env = gym.make(ENV_ID, config=env_config)
    teacher = RuleBasedLCA()
    obs_rows: list[dict[str, np.ndarray]] = []
    actions: list[int] = []
    masks: list[np.ndarray] = []
    rewards: list[float] = []
    ends: list[bool] = []
    try:
        for seed in tqdm(seeds, desc="demonstrations", unit="ep", disable=not progress):
            obs, info = env.reset(seed=int(seed))
            teacher.reset()
            done = False
            while not done:
                action = int(teacher.act(obs))
                obs_rows.append(obs)
                actions.append(action)
                masks.append(np.array(info["action_mask"], dtype=bool))
                obs, reward, terminated, truncated, info = env.step(action)
                done = bool(terminated or truncated)
                rewards.append(float(reward))
                ends.append(done)
    finally:
        env.close()
    observations = {
        key: np.stack([np.asarray(o[key]) for o in obs_rows]).astype(np.float32)
        for key in obs_rows[0]
    }
    return Demonstrations(
        observations=observations,
        actions=np.asarray(actions, dtype=np.int64),
        masks=np.stack(masks),
        returns=discounted_returns(np.asarray(rewards), np.asarray(ends), gamma),
        episodes=len(seeds),
    )


def clone(
    model: Any, demos: Demonstrations, epochs: int, seed: int, seeds: range, masked: bool
) -> CloneReport:
    """Fit ``model``'s actor to the demonstrations' actions and its critic to their
    returns, on observations normalised by the model's ``VecNormalize`` (whose
    statistics are first updated with the demonstrations').

    :param model: a new SB3 ``PPO`` or sb3-contrib ``MaskablePPO`` on a
        ``VecNormalize``-d env.
    :param epochs: passes over the demonstrations (minibatches of :data:`BATCH_SIZE`).
    :param seed: seed of the minibatch order.
    :param seeds: the demonstration seeds (for the report).
    :param masked: the policy takes action masks (MaskablePPO); steps whose action
        the mask rules out are then left out (they would have log-probability -inf).
    :raises ConfigError: ``epochs`` < 1 or no demonstration steps.
    """
    import torch

    if epochs < 1:
        raise ConfigError(f"pretrain_epochs must be >= 1, got {epochs}")
    if len(demos) == 0:
        raise ConfigError("no demonstration steps to clone")
    keep = np.ones(len(demos), dtype=bool)
    if masked:
        keep = demos.masks[np.arange(len(demos)), demos.actions]
        if not keep.any():
            raise ConfigError("every demonstration step's action is ruled out by its mask")
    venv = model.get_vec_normalize_env()
    observations = demos.observations
    if venv is not None:
        if venv.norm_obs:
            for key, rms in venv.obs_rms.items():
                rms.update(observations[key])
        observations = venv.normalize_obs(observations)
    obs = {
        k: torch.as_tensor(np.asarray(v, dtype=np.float32)[keep]) for k, v in observations.items()
    }
    actions = torch.as_tensor(demos.actions[keep])
    masks = torch.as_tensor(demos.masks[keep])
    returns = torch.as_tensor(demos.returns[keep], dtype=torch.float32)

    policy = model.policy

    def mask_of(idx: Any) -> dict[str, Any]:
        """MaskablePPO's keyword for the masks of the rows ``idx`` (PPO: none)."""
        return {"action_masks": masks[idx]} if masked else {}

    policy.set_training_mode(True)
    optimiser = torch.optim.Adam(policy.parameters(), lr=LEARNING_RATE)
    rng = np.random.default_rng(seed)
    n = int(keep.sum())
    for _ in range(epochs):
        order = rng.permutation(n)
        for start in range(0, n, BATCH_SIZE):
            idx = torch.as_tensor(order[start : start + BATCH_SIZE])
            batch = {k: v[idx] for k, v in obs.items()}
            values, log_prob, _ = policy.evaluate_actions(batch, actions[idx], **mask_of(idx))
            loss = -log_prob.mean() + VALUE_WEIGHT * ((values.flatten() - returns[idx]) ** 2).mean()
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
    policy.set_training_mode(False)
    with torch.no_grad():
        dist = policy.get_distribution(obs, **mask_of(slice(None)))
        chosen = dist.distribution.probs.argmax(dim=1)
        values = policy.predict_values(obs).flatten()
    hit = (chosen == actions).numpy()
    lane = np.isin(actions.numpy(), (MetaAction.LANE_LEFT, MetaAction.LANE_RIGHT))
    return CloneReport(
        teacher="rule-based LCA",
        episodes=demos.episodes,
        steps=n,
        epochs=epochs,
        seeds=(seeds[0], seeds[-1]),
        accuracy=float(hit.mean()),
        accuracy_lane_change=float(hit[lane].mean()) if lane.any() else float("nan"),
        value_rmse=float(torch.sqrt(((values - returns) ** 2).mean())),
    )
