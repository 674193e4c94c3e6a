"""Figures of the agents: a training's validations, closed-loop lateral offsets.

matplotlib is imported only here, and only when a function is called.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

_TRACES = {
    # Drawn in this order: the wide translucent ALDM line first, so identical traces
    # (every detector on an editor road) show as black on blue with red dashes on top.
    "aldm": {"color": "tab:blue", "lw": 5.0, "alpha": 0.45, "label": "ALDM", "zorder": 2},
    "aldm_tracking": {"color": "tab:cyan", "lw": 2.4, "label": "ALDM tracking", "zorder": 2.5},
    "aldm_filter": {"color": "tab:purple", "lw": 1.6, "label": "ALDM filter", "zorder": 2.7},
    "ground_truth": {"color": "black", "lw": 1.2, "label": "ground truth", "zorder": 3},
    "naive": {"color": "tab:red", "lw": 1.8, "ls": (0, (5, 3)), "label": "naive", "zorder": 4},
}
"""matplotlib style of each detector's offset trace (others: grey)."""


def plot_validation(record: dict[str, Any], path: Path, label: str = "PPO") -> None:
    """Plot a ``validation.json`` record: return, collisions and speed over training.

    Horizontal lines: IDLE and the rule-based LCA on the same seeds; the dotted
    vertical line marks the kept (best) model.

    :param label: the trained policy's legend (its algorithm).
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
        ax.plot(steps, [h[key] for h in history], "o-", color="C0", label=label)
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


RUN_MARKERS = "os^D"
"""Markers of the runs of :func:`plot_learning_curves`: runs 0-9 ``o``, 10-19 ``s``
... (matplotlib's ten default colours repeat in each ten)."""


def plot_learning_curves(
    groups: Mapping[str, list[tuple[str, dict[str, Any]]]], path: Path, label: str = "PPO"
) -> None:
    """Validation curves of several trainings: mean speed and collisions over training
    steps, one column per group (e.g. per detector), one line per training (seed).

    :param groups: ``title -> [(run label, validation.json record)]``; the dashed lines
        are the first record's baselines (IDLE, rule-based LCA) on the same seeds, and
        a ring marks each run's kept model.
    :param label: the trained policies' name in the titles.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    titles = list(groups)
    # Many runs in a column (a search's trials): their legend goes beside each column's
    # panels, with room for it in every column
    crowded = max((len(runs) for runs in groups.values()), default=0) > 6
    fig, axes = plt.subplots(
        2,
        len(titles),
        figsize=((4.6 + (2.0 if crowded else 0.0)) * len(titles), 6.0),
        sharex=True,
        squeeze=False,
    )
    colours = {"idle": "C7", "rule_based": "C2"}
    names = {"idle": "IDLE", "rule_based": "rule-based LCA"}
    for col, title in enumerate(titles):
        runs = groups[title]
        for key, ax in zip(("mean_speed", "collisions"), axes[:, col], strict=True):
            for i, (run, record) in enumerate(runs):
                steps = [h["steps"] for h in record["history"]]
                values = [h[key] for h in record["history"]]
                # ten colours, then the next ten runs with another marker
                style = dict(color=f"C{i % 10}", marker=RUN_MARKERS[i // 10 % len(RUN_MARKERS)])
                ax.plot(steps, values, "-", ms=3, lw=1.2, label=run, **style)
                kept = [h[key] for h in record["history"] if h["steps"] == record["best_steps"]]
                if kept:
                    ax.plot(
                        record["best_steps"], kept[0], "o", ms=9, mfc="none", color=style["color"]
                    )
            if runs:
                for name, base in runs[0][1].get("baselines", {}).items():
                    ax.axhline(
                        base[key],
                        color=colours.get(name, "C1"),
                        ls="--",
                        lw=1,
                        label=names.get(name, name),
                    )
            ax.grid(alpha=0.3)
        seeds = runs[0][1]["seeds"] if runs else [0, 0]
        n = seeds[1] - seeds[0] + 1
        axes[0, col].set_title(f"{label}, {title} observations", fontsize=10)
        axes[0, col].set_ylabel("mean speed [m/s]")
        axes[1, col].set_ylabel(f"collisions [of {n} episodes]")
        axes[1, col].set_xlabel("training steps")
        if crowded:
            axes[0, col].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
        else:
            axes[0, col].legend(fontsize=7, loc="lower right")
    fig.suptitle("validation during training (ring: the kept model)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_offsets(
    traces: dict[tuple[str, str], list[tuple[float, float]]],
    path: Path,
    crashed: Mapping[tuple[str, str], bool] | None = None,
) -> None:
    """Lateral offset over distance, one panel per marking model, one line per detector.

    :param traces: ``(marking model, detector) -> [(distance [m], lateral offset [m])]``
        (:attr:`~aldm_gym.agents.episodes.EpisodeStats.trace`).
    :param crashed: ``(marking model, detector) -> True`` where that episode ended in a
        collision: its trace ends in a cross.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    crashed = crashed or {}
    models = sorted({m for m, _ in traces}, reverse=True)
    order = list(_TRACES)
    fig, axes = plt.subplots(len(models), 1, figsize=(8, 3.0 * len(models)), squeeze=False)
    # one symmetric range for all panels, the lane edges always inside it
    # (an episode that leaves a map ends in an infinite offset: not a limit)
    offsets = [np.abs(np.asarray(t, dtype=float)[:, 1]) for t in traces.values() if t]
    worst = max((float(np.max(o[np.isfinite(o)], initial=0.0)) for o in offsets), default=0.0)
    limit = max(2.4, 1.1 * worst)
    for ax, model in zip(axes[:, 0], models, strict=True):
        dets = sorted(
            (d for m, d in traces if m == model and traces[(m, d)]),
            key=lambda d: order.index(d) if d in order else len(order),
        )
        for det in dets:
            arr = np.asarray(traces[(model, det)])
            style = _TRACES.get(det, {"color": "tab:gray", "lw": 1.2, "label": det})
            ax.plot(arr[:, 0], arr[:, 1], **style)
            if crashed.get((model, det), False):
                ax.plot(
                    arr[-1, 0],
                    arr[-1, 1],
                    "X",
                    color=style["color"],
                    mec="black",
                    ms=12,
                    zorder=5,
                    label=f"{style['label']}: collision",
                )
                ax.annotate(
                    "collision",
                    (arr[-1, 0], arr[-1, 1]),
                    xytext=(8, 6),
                    textcoords="offset points",
                    fontsize=10,
                    color=style["color"],
                    fontweight="bold",
                )
        for y in (-1.875, 1.875):  # lane edges of the default 3.75 m lane
            ax.axhline(y, color="0.55", lw=0.9, ls=":", zorder=1)
        ax.set_ylim(-limit, limit)
        ax.set_title(f"{model} road: LKA (IDLE), first episode", fontsize=11)
        ax.set_ylabel("lateral offset [m], left +", fontsize=10)
        ax.tick_params(labelsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=9, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    axes[-1, 0].set_xlabel("distance along the road [m] (dotted: lane edges)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_target_selection(
    curves: Mapping[tuple[str, str], list[float]], edges: tuple[float, ...], path: Path
) -> None:
    """Target-selection accuracy over the vehicle's distance, per marking model × detector.

    :param curves: ``(marking model, detector) ->`` share of correct scenes per bin (%
        of 1) (:func:`~aldm_gym.agents.target_scenes.compare_target_selection`).
    :param edges: the bins' edges [m].
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from aldm_gym.agents.target_scenes import CUT_IN_RANGE

    centres = 0.5 * (np.asarray(edges[:-1]) + np.asarray(edges[1:]))
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    models = sorted({m for m, _ in curves}, key=lambda m: m != "per_dash")
    for ax, model in zip(axes, models, strict=False):
        for (m, det), acc in curves.items():
            if m != model:
                continue
            style = dict(_TRACES.get(det, {"color": "grey", "label": det}))
            style.pop("alpha", None)
            ax.plot(centres, 100.0 * np.asarray(acc), marker="o", **style)
        ax.axvspan(*CUT_IN_RANGE, color="0.9", zorder=0)
        ax.text(
            0.5 * sum(CUT_IN_RANGE), 2, "cut-ins", ha="center", va="bottom", fontsize=9, color="0.3"
        )
        ax.text(
            CUT_IN_RANGE[1] + 3, 2, "in the ego or a\nneighbouring lane", fontsize=9, color="0.3"
        )
        ax.set_title(f"{model} road")
        ax.set_xlabel("distance of the vehicle ahead [m] (grey: cut-in scenes)")
        ax.set_ylim(-5, 105)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("target selection correct [%]")
    axes[0].legend(loc="center right", bbox_to_anchor=(1.0, 0.68))
    fig.suptitle("ACC target selection on the detected lanes (curves R 500-1500 m)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
