"""Figures of :mod:`aldm_gym.agents.figures`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from aldm_gym.agents.figures import RUN_MARKERS, plot_learning_curves


def _record(speed: float) -> dict[str, Any]:
    history = [
        {"steps": s, "mean_speed": speed + 0.01 * s / 64, "collisions": 0} for s in (0, 64, 128)
    ]
    return {
        "history": history,
        "best_steps": 64,
        "seeds": [20000, 20019],
        "baselines": {"idle": {"mean_speed": 24.0, "collisions": 0}},
    }


def test_crowded_learning_curves_keep_legends_beside_their_column(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Twelve runs in each of three columns: every legend lies between its column's
    panel and the next column, the panels keep most of the width of a figure with one
    run per column, and runs 10 and 11 differ from runs 0 and 1 by marker."""
    import matplotlib.pyplot as plt

    figures: list[Any] = []
    real_close = plt.close
    monkeypatch.setattr(plt, "close", figures.append)
    runs = [
        (f"trial {i}: gamma 0.95, lr 1.05e-04, rollout 256", _record(25.0 + 0.01 * i))
        for i in range(12)
    ]
    path = tmp_path / "curves.png"
    plot_learning_curves({"ALDM": runs[:1], "naive": runs[:1], "other": runs[:1]}, path)
    plot_learning_curves({"ALDM": runs, "naive": runs, "other": runs}, path)
    assert path.stat().st_size > 0
    sparse, fig = figures
    renderer = fig.canvas.get_renderer()
    width = fig.axes[0].get_window_extent(renderer).width
    assert width >= 0.75 * sparse.axes[0].get_window_extent(sparse.canvas.get_renderer()).width
    left, right = fig.axes[0], fig.axes[1]  # top row: column 0, column 1
    legend = left.get_legend().get_window_extent(renderer)
    assert legend.x0 >= left.get_window_extent(renderer).x1
    assert legend.x1 <= right.get_tightbbox(renderer).x0 + 1.0
    assert right.get_legend().get_window_extent(renderer).x1 <= fig.bbox.x1 + 1.0
    lines = [ln for ln in left.get_lines() if ln.get_label().startswith("trial ")]
    by_label = {ln.get_label(): ln for ln in lines}

    def name(i: int) -> str:
        return runs[i][0]

    assert by_label[name(10)].get_color() == by_label[name(0)].get_color()
    assert by_label[name(0)].get_marker() == RUN_MARKERS[0]
    assert by_label[name(10)].get_marker() == RUN_MARKERS[1]
    real_close(fig)
    real_close(sparse)
