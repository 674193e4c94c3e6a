"""One evaluation loop for every policy: LKA, rule-based LCA, a PPO model alike.

:func:`run_episode` plays one seeded episode of an ``ALDMHighway-v0`` environment with
any object exposing SB3's ``predict(obs, deterministic=True) -> (action, state)`` and
collects ground-truth metrics from ``info``; :func:`summarize` aggregates episodes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from aldm_gym.envs.actions import MetaAction
from aldm_gym.errors import InputError


class Policy(Protocol):
    """What :func:`run_episode` needs of a policy: SB3's ``predict``.

    ``IdlePolicy``, ``RuleBasedLCA``, ``LKAController`` and SB3 models all satisfy it.
    A policy whose ``uses_action_masks`` attribute is true (a MaskablePPO model) is also
    given ``action_masks=info["action_mask"]``.
    """

    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """``(action, state)``."""
        ...


@dataclass
class EpisodeStats:
    """Ground-truth outcome of one episode.

    :ivar seed: the episode's seed.
    :ivar steps: policy steps played.
    :ivar distance: distance driven [m] (``info["distance"]``).
    :ivar duration: simulated time [s].
    :ivar departures: lane departures (a wheel over a marking without a lane change).
    :ivar collided: the ego crashed.
    :ivar offsets: |lateral offset| from the lane centre at each policy step without a
        lane change under way [m].
    :ivar both_correct: steps with both ego lines correct (see ``info["detection"]``).
    :ivar previews: preview of each ego line at each step [m] (NaN when missing).
    :ivar lane_changes_ok: lane changes that ended, per ground truth, in the lane next
        to the starting one in the commanded direction.
    :ivar lane_changes_failed: lane-change commands refused (adjacent line not
        detected), aborted, or ending in another lane.
    :ivar speeds: ego speed at each step [m/s].
    :ivar reward: sum of rewards.
    :ivar trace: ``(distance driven [m], signed lateral offset [m])`` per step.
    :ivar collision: where the other vehicle was in a collision (``info["collision"]``:
        ``"front"``, ``"rear"``, ``"side"``), ``""`` without one.
    :ivar target_correct: steps whose ACC target was the true in-lane leader (or
        neither exists), per ``info["target"]``.
    :ivar target_missed: steps with a true leader within range not selected.
    :ivar target_false: steps with a selected target not in the true ego lane.
    :ivar phantom_braking: phantom-braking events (braking for a false target; a run
        of consecutive steps counts once).
    :ivar aeb_activations: AEB activations.
    :ivar min_time_gap: smallest time gap to the true leader [s] (``inf``: never one).
    """

    seed: int
    steps: int = 0
    distance: float = 0.0
    duration: float = 0.0
    departures: int = 0
    collided: bool = False
    offsets: list[float] = field(default_factory=list)
    both_correct: int = 0
    previews: list[float] = field(default_factory=list)
    lane_changes_ok: int = 0
    lane_changes_failed: int = 0
    speeds: list[float] = field(default_factory=list)
    reward: float = 0.0
    trace: list[tuple[float, float]] = field(default_factory=list)
    collision: str = ""
    target_correct: int = 0
    target_missed: int = 0
    target_false: int = 0
    phantom_braking: int = 0
    aeb_activations: int = 0
    min_time_gap: float = float("inf")

    @property
    def success(self) -> bool:
        """No collision and no departure."""
        return not self.collided and self.departures == 0


def _scalar_action(action: Any) -> Any:
    arr = np.asarray(action)
    return int(arr.reshape(-1)[0]) if arr.dtype.kind in "iu" and arr.size == 1 else action


def run_episode(env: Any, policy: Policy, seed: int, max_steps: int | None = None) -> EpisodeStats:
    """Play one episode with ``policy`` from ``env.reset(seed=seed)``.

    :param env: an ``ALDMHighway-v0`` environment (possibly wrapped).
    :param policy: anything with SB3's ``predict``; ``reset()`` is called if it has one.
    :param max_steps: stop after this many policy steps (default: the episode's end).
    """
    obs, info = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset()
    stats = EpisodeStats(seed=seed)
    dt = 1.0 / float(env.unwrapped.config["policy_frequency"])  # highway-env's key
    pending: tuple[int, int, int] | None = None  # (direction, start lane, completed count)
    aborted = int(info.get("lane_changes_aborted", 0))
    phantom_before = False
    done = False
    masked = bool(getattr(policy, "uses_action_masks", False))
    while not done and (max_steps is None or stats.steps < max_steps):
        if masked:
            action, _ = policy.predict(obs, deterministic=True, action_masks=info["action_mask"])
        else:
            action, _ = policy.predict(obs, deterministic=True)
        action = _scalar_action(action)
        lane_before = int(info["lane_index"])
        completed_before = int(info["lane_changes_completed"])
        obs, reward, terminated, truncated, info = env.step(action)
        done = bool(terminated or truncated)
        stats.steps += 1
        stats.duration += dt
        stats.reward += float(reward)
        stats.speeds.append(float(info["speed"]))
        # The way driven, not the arc length: a map's s restarts on every road.
        stats.distance = float(info["distance"])
        stats.trace.append((stats.distance, float(info["lateral_offset"])))
        stats.departures += int(bool(info["lane_departure"]))
        stats.collided |= bool(info["crashed"])
        if info.get("collision"):
            stats.collision = str(info["collision"])
        tgt = info.get("target")
        if tgt is not None:
            stats.target_correct += int(bool(tgt["correct"]))
            stats.target_missed += int(bool(tgt["missed"]))
            stats.target_false += int(bool(tgt["false"]))
            stats.phantom_braking += int(bool(tgt["phantom_braking"]) and not phantom_before)
            phantom_before = bool(tgt["phantom_braking"])
            stats.aeb_activations = int(tgt["aeb_activations"])
            stats.min_time_gap = min(stats.min_time_gap, float(tgt["time_gap"]))
        det = info["detection"]
        stats.both_correct += int(det["ego_left"]["correct"] and det["ego_right"]["correct"])
        stats.previews += [det["ego_left"]["preview"], det["ego_right"]["preview"]]
        if (
            isinstance(action, int)
            and action in (MetaAction.LANE_LEFT, MetaAction.LANE_RIGHT)
            and pending is None
        ):
            if info["lane_change_refused"]:
                stats.lane_changes_failed += 1
            elif info["lane_change"] != 0 or info["lane_changes_completed"] > completed_before:
                direction = (
                    -1 if action == MetaAction.LANE_LEFT else 1
                )  # lane ids grow to the right
                pending = (direction, lane_before, completed_before)
        if pending is not None:
            direction, start, count = pending
            if int(info["lane_changes_completed"]) > count:
                ok = int(info["lane_index"]) == start + direction
                stats.lane_changes_ok += int(ok)
                stats.lane_changes_failed += int(not ok)
                pending = None
            elif int(info.get("lane_changes_aborted", 0)) > aborted:
                stats.lane_changes_failed += 1
                pending = None
        aborted = int(info.get("lane_changes_aborted", 0))
        if info["lane_change"] == 0 and pending is None:
            stats.offsets.append(abs(float(info["lateral_offset"])))
    return stats


def run_episodes(
    env: Any,
    policy: Policy,
    seeds: Iterable[int],
    progress: Callable[[int], None] | None = None,
) -> list[EpisodeStats]:
    """:func:`run_episode` for each seed; ``progress(1)`` after each episode."""
    out = []
    for seed in seeds:
        out.append(run_episode(env, policy, int(seed)))
        if progress is not None:
            progress(1)
    return out


def summarize(episodes: list[EpisodeStats]) -> dict[str, float]:
    """Aggregate episodes into the comparison's metrics.

    :return: ``km`` driven, ``departures_per_km``, ``rms_offset_m`` and ``max_offset_m``
        (|offset from the lane centre| outside lane changes), ``both_correct`` (share of
        steps with both ego lines correct), ``mean_preview_m`` (missing lines count 0),
        ``collisions`` (episodes), ``lane_changes_ok``, ``lane_changes_failed``,
        ``mean_speed`` [m/s], ``success_rate`` (episodes without collision or departure),
        ``episodes``; ACC target selection (``info["target"]``): ``target_accuracy``,
        ``missed_rate`` and ``false_rate`` (shares of steps), ``phantom_braking``
        (events), ``aeb_activations``, ``rear_end_collisions`` (the ego ran into the
        vehicle ahead: ``info["collision"] == "front"``), ``min_time_gap`` [s] (the
        smallest over all episodes).
    """
    if not episodes:
        raise InputError("summarize needs at least one episode")
    km = sum(e.distance for e in episodes) / 1000.0
    nan = float("nan")
    offsets = np.concatenate([np.asarray(e.offsets, dtype=float) for e in episodes])
    previews = np.nan_to_num(np.concatenate([np.asarray(e.previews) for e in episodes]), nan=0.0)
    steps = sum(e.steps for e in episodes)
    speeds = np.concatenate([np.asarray(e.speeds) for e in episodes])
    return {
        "episodes": len(episodes),
        "km": km,
        "departures_per_km": sum(e.departures for e in episodes) / km if km > 0 else float("nan"),
        "rms_offset_m": float(np.sqrt(np.mean(offsets**2))) if len(offsets) else float("nan"),
        "max_offset_m": float(offsets.max()) if len(offsets) else float("nan"),
        "both_correct": sum(e.both_correct for e in episodes) / steps if steps else float("nan"),
        "mean_preview_m": float(previews.mean()) if len(previews) else float("nan"),
        "collisions": sum(int(e.collided) for e in episodes),
        "lane_changes_ok": sum(e.lane_changes_ok for e in episodes),
        "lane_changes_failed": sum(e.lane_changes_failed for e in episodes),
        "mean_speed": float(speeds.mean()) if len(speeds) else float("nan"),
        "success_rate": sum(int(e.success) for e in episodes) / len(episodes),
        "target_accuracy": sum(e.target_correct for e in episodes) / steps if steps else nan,
        "missed_rate": sum(e.target_missed for e in episodes) / steps if steps else nan,
        "false_rate": sum(e.target_false for e in episodes) / steps if steps else nan,
        "phantom_braking": sum(e.phantom_braking for e in episodes),
        "aeb_activations": sum(e.aeb_activations for e in episodes),
        "rear_end_collisions": sum(int(e.collision == "front") for e in episodes),
        "min_time_gap": min(e.min_time_gap for e in episodes),
    }
