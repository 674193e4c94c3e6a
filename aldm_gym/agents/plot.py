"""Figures of the agents: a training's validations, closed-loop lateral offsets.

matplotlib is imported only here, and only when a function is called.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

_TRACE_STYLE = {
    "naive": ("tab:red", "-", 1.4),
    "aldm": ("tab:blue", "-", 2.6),
    "ground_truth": ("black", "--", 1.0),
}


def plot_validation(record: dict[str, Any], path: Path) -> None:
    """Plot a ``validation.json`` record: return, collisions and speed over training.

    Horizontal lines: IDLE and the rule-based LCA on the same seeds; the dotted
    vertical line marks the kept (best) model.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    history = record["history"]
    steps = [h["steps"] for h in history]
    n = record["seeds"][1] - record["seeds"][0] + 1
    panels = (
        ("mean_return", "mean return"),
        ("collisions", f"collisions [of {n} episodes]"),
        ("mean_speed", "mean speed [m/s]"),
    )
    fig, axes = plt.subplots(len(panels), 1, figsize=(6.4, 6.4), sharex=True)
    for ax, (key, label) in zip(axes, panels, strict=True):
        ax.plot(steps, [h[key] for h in history], "o-", color="C0", label="PPO")
        colours = {"idle": "C7", "rule_based": "C2"}
        for name, base in record.get("baselines", {}).items():
            ax.axhline(base[key], color=colours.get(name, "C1"), ls="--", lw=1, label=name)
        ax.axvline(record["best_steps"], color="C3", ls=":", lw=1, label="kept (best return)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    axes[-1].set_xlabel("training steps")
    fig.suptitle(f"validation on seeds {record['seeds'][0]}..{record['seeds'][1]}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_offsets(traces: dict[tuple[str, str], list[tuple[float, float]]], path: Path) -> None:
    """Lateral offset over distance, one panel per marking model, one line per detector.

    :param traces: ``(marking model, detector) -> [(distance [m], lateral offset [m])]``
        (:attr:`~aldm_gym.agents.evaluation.EpisodeStats.trace`).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = sorted({m for m, _ in traces}, reverse=True)
    fig, axes = plt.subplots(len(models), 1, figsize=(8, 2.6 * len(models)), squeeze=False)
    for ax, model in zip(axes[:, 0], models, strict=True):
        for (m, det), trace in traces.items():
            if m != model or not trace:
                continue
            arr = np.asarray(trace)
            colour, style, width = _TRACE_STYLE.get(det, ("tab:gray", "-", 1.2))
            ax.plot(arr[:, 0], arr[:, 1], style, color=colour, lw=width, label=det)
        for y in (-1.875, 1.875):  # lane edges of the default 3.75 m lane
            ax.axhline(y, color="0.6", lw=0.8, ls=":")
        ax.set_title(f"{model} road: LKA (IDLE), first episode", fontsize=9)
        ax.set_ylabel("lateral offset [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("distance along the road [m]")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
