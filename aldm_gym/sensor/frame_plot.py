"""Pictures of line-sensor frames and detections, in the style of the paper's Fig. 7–8.

Axes follow the paper: horizontal "lateral distance [m]", vertical "longitudinal
distance [m]". The horizontal axis is the ISO 8855 y axis drawn inverted, so that the
driver's left is on the left of the picture. matplotlib is imported only here, and
only when a function is called.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

_LINE_STYLE = {
    "ego_left": ("tab:blue", "-", 2.2),
    "ego_right": ("tab:orange", "-", 2.2),
    "left_adjacent": ("tab:purple", "--", 1.6),
    "right_adjacent": ("tab:olive", "--", 1.6),
}

POINT_COLOURS = {"left": "0.3", "right": "tab:brown"}
"""Colours of the sensor points of the left and the right side's line objects (neither
the trajectory's green nor the red that stands for the naive detector elsewhere)."""


def point_handles(sensor: bool = True) -> dict[str, Any]:
    """Legend entries of the two sides' sensor points and (``sensor``) of the sensor's
    own mark, by label."""
    from matplotlib.lines import Line2D

    handles = {
        f"points, {side} objects": Line2D(
            [], [], ls="", marker="+", color=colour, label=f"points, {side} objects"
        )
        for side, colour in POINT_COLOURS.items()
    }
    if sensor:
        handles["sensor"] = Line2D([], [], ls="", marker="x", color="black", label="sensor")
    return handles


HALF_WIDTH = (15.0, 30.0)
"""Lateral half-width of a frame panel [m]: at least the first, wider to show the
drawn lines in a bend (2 m beyond them), at most the second."""


def _half_width(detection: LaneDetection | None) -> float:
    """The panel's lateral half-width [m] for the lines of ``detection``
    (:data:`HALF_WIDTH`); points alone do not widen it (a bridge's or a far road's
    markings would squeeze the lanes into a few pixels)."""
    lo, hi = HALF_WIDTH
    if detection is None:
        return lo
    ys = [np.abs(detection.line(n)[:, 1]) for n in LINE_NAMES if len(detection.line(n))]
    if len(detection.trajectory):
        ys.append(np.abs(detection.trajectory[:, 1]))
    if not ys:
        return lo
    return float(np.clip(np.ceil(max(float(np.max(y)) for y in ys) + 2.0), lo, hi))


def draw_frame(
    ax: Axes,
    frame: SensorFrame,
    detection: LaneDetection | None = None,
    *,
    title: str | None = None,
    label_objects: bool = True,
    x_max: float | None = None,
    legend: bool = True,
) -> None:
    """Draw every point of a frame, labelled by side and line index, and a detection on top.

    :param ax: matplotlib axes to draw into.
    :param frame: the sensor frame.
    :param detection: lines and trajectory to overlay (optional).
    :param title: axes title.
    :param label_objects: write ``left,n`` / ``right,n`` (CarMaker's side and index) at each
        object's first point, as in the paper's Fig. 7.
    :param x_max: longitudinal extent to show [m] (default: the sensor range).
    :param legend: draw a legend in the axes (:func:`plot_frames` draws one for the
        figure instead, below the panels, off the data).
    """
    for side, lo, hi, colour in (
        ("left", 0, frame.n_left, POINT_COLOURS["left"]),
        ("right", frame.n_left, frame.n_lines, POINT_COLOURS["right"]),
    ):
        for n in range(lo, hi):
            pts = frame.line_points(n)
            ax.plot(pts[:, 1], pts[:, 0], "+", color=colour, ms=4, mew=0.8)
            if label_objects:
                ax.annotate(
                    f"{side},{n - lo}",
                    (pts[0, 1], pts[0, 0]),
                    fontsize=6.5,
                    color=colour,
                    xytext=(2, 0),
                    textcoords="offset points",
                )
    if detection is not None:
        for name in LINE_NAMES:
            line = detection.line(name)
            if len(line) == 0:
                continue
            colour, style, width = _LINE_STYLE[name]
            ax.plot(line[:, 1], line[:, 0], style, color=colour, lw=width, label=name)
            pts13 = detection.resample(13).line(name)
            if len(pts13):
                ax.plot(pts13[:, 1], pts13[:, 0], "o", color=colour, ms=3.5, mfc="none")
        if len(detection.trajectory):
            traj = detection.trajectory
            ax.plot(traj[:, 1], traj[:, 0], ":", color="tab:green", lw=2.5, label="trajectory")
        if legend:
            ax.legend(loc="upper left", fontsize=8.5, framealpha=0.85)
    ax.plot([0.0], [0.0], "kx", ms=8)
    ax.set_xlabel("lateral distance y [m] (left on the left)", fontsize=10)
    ax.set_ylabel("longitudinal distance x [m]", fontsize=10)
    ax.tick_params(labelsize=9)
    ax.set_ylim(0.0, x_max if x_max is not None else frame.range)
    half = _half_width(detection)
    ax.set_xlim(half, -half)
    ax.grid(alpha=0.3)
    if title:
        ax.set_title(title, fontsize=11)


def plot_frames(
    panels: Mapping[str, tuple[SensorFrame, LaneDetection | None]],
    path: str | Path | None = None,
    *,
    suptitle: str | None = None,
    x_max: float | None = None,
) -> Figure:
    """Side-by-side panels, one per ``title -> (frame, detection)``; saved as PNG if ``path``.

    :return: the matplotlib figure (closed after saving when ``path`` is given).
    """
    import matplotlib

    if path is not None:
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    n = len(panels)
    if n == 0:
        raise InputError("plot_frames needs at least one panel")
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 7.4), squeeze=False)
    for ax, (title, (frame, det)) in zip(axes[0], panels.items(), strict=True):
        draw_frame(ax, frame, det, title=title, x_max=x_max, legend=False)
    half = max(ax.get_xlim()[0] for ax in axes[0])  # one lateral range for all panels
    for ax in axes[0]:
        ax.set_xlim(half, -half)
    # One legend for the figure, below the panels: every line kind any panel drew.
    handles: dict[str, Any] = {}
    for ax in axes[0]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    order = [*LINE_NAMES, "trajectory"]
    labels = sorted(handles, key=lambda k: order.index(k) if k in order else len(order))
    if labels:
        points = point_handles()
        handles.update(points)
        labels += list(points)
        fig.legend(
            [handles[k] for k in labels],
            labels,
            loc="lower center",
            ncol=len(labels) if n > 2 else (len(labels) + 1) // 2,
            fontsize=9.5,
            frameon=False,
            handlelength=1.8,
            columnspacing=1.2,
        )
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    bottom = 0.0 if not labels else 0.05 if n > 2 else 0.09
    fig.tight_layout(rect=(0.0, bottom, 1.0, 1.0))
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=130)
        plt.close(fig)
    return fig


DETECTOR_STYLE = {
    "naive": ("naive", "tab:red"),
    "aldm": ("ALDM", "tab:blue"),
    "aldm_tracking": ("ALDM tracking", "tab:cyan"),
    "aldm_filter": ("ALDM filter", "tab:purple"),
    "ground_truth": ("ground truth", "0.45"),
}
"""Legend name and colour of each detector in the comparison figures."""


def percent(share: float) -> str:
    """A share in [0, 1] as a bar label in per cent (the axis says [%]): ``"0"``,
    ``"<1"`` (above zero but under 1 %), ``"14"``, ``"100"``."""
    if share == 0.0:
        return "0"
    if share < 0.01:
        return "<1"
    return f"{100.0 * share:.0f}"


def plot_detector_bars(rows: Sequence[Mapping[str, Any]], path: str | Path) -> None:
    """Per marking model and detector (rows of
    :func:`~aldm_gym.sensor.open_loop.compare_detectors`): the share of frames with both
    ego lines correct [%] (left) and the F1 of the four lines at the strict threshold,
    with the loose one (1.5 m) as a light bar behind (right); a PNG.

    Every bar carries its value (:func:`percent`), so a bar of zero height reads "0" in
    the bar's colour, not as a missing bar, and a sliver above zero reads "<1".
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = sorted({r["marking_model"] for r in rows}, reverse=True)
    keys = list(dict.fromkeys((r["detector"], r.get("mode", "")) for r in rows))
    keys.sort(key=lambda k: list(DETECTOR_STYLE).index(k[0]) if k[0] in DETECTOR_STYLE else 99)

    def value(model: str, key: tuple[str, str], column: str) -> float:
        return next(
            (
                float(r[column])
                for r in rows
                if r["marking_model"] == model and (r["detector"], r.get("mode", "")) == key
            ),
            0.0,
        )

    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.2))
    width = 0.8 / len(keys)
    for panel, (ax, column, label) in enumerate(
        zip(
            axes,
            ("both_correct", "strict_f1"),
            ("frames with both ego lines correct [%]", "F1 of the four lines [%]"),
            strict=True,
        )
    ):
        for i, key in enumerate(keys):
            name, colour = DETECTOR_STYLE.get(key[0], (key[0], None))
            if key[1] == "paper":
                name, colour = f"{name} (paper mode)", "tab:purple"
            x = np.arange(len(models)) + i * width
            if panel == 1:
                loose = [value(m, key, "loose_f1") for m in models]
                ax.bar(x, 100.0 * np.nan_to_num(loose), width, color=colour, alpha=0.3)
            vals = [value(m, key, column) for m in models]
            bars = ax.bar(x, 100.0 * np.nan_to_num(vals), width, label=name, color=colour)
            texts = ax.bar_label(bars, [percent(v) for v in vals], padding=2, fontsize=8)
            for text, v in zip(texts, vals, strict=True):
                if v == 0.0:
                    text.set_color(colour or "black")
                    text.set_fontweight("bold")
        ax.set_xticks(np.arange(len(models)) + 0.4 - width / 2, models, fontsize=11)
        ax.set_ylabel(label)
        ax.set_ylim(0, 112)
        ax.set_yticks(range(0, 101, 20))
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_title("strict: every point within 0.3 m, preview >= 60 m", fontsize=9)
    axes[1].set_title("dark: strict; light: 75 % within 1.5 m (OpenLane)", fontsize=9)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, ncol=len(keys), loc="upper center", frameon=False)
    fig.supxlabel(
        "marking model (per_dash: every dash its own object; editor: one object per line)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.93))
    fig.savefig(path, dpi=130)
    plt.close(fig)


def save_table_figure(rows: list[dict[str, Any]], columns: list[str], path: str | Path) -> None:
    """Render a small results table as a PNG (for reports)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    cells = [[_fmt(r[c]) for c in columns] for r in rows]
    fig, ax = plt.subplots(figsize=(1.2 * len(columns), 0.4 * (len(rows) + 1)))
    ax.axis("off")
    ax.table(cellText=cells, colLabels=columns, loc="center").auto_set_font_size(True)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _fmt(v: Any) -> str:
    if isinstance(v, float | np.floating):
        return f"{v:.3g}"
    return str(v)


def draw_occluders(ax: Axes, boxes: np.ndarray, reach: float) -> None:
    """Vehicles and their shadows in a frame's axes (drawn under the points).

    :param boxes: ``(V, 4, 2)`` corners (x, y) of the vehicles in the sensor frame [m].
    :param reach: how far to draw a shadow [m] (every vehicle is taller than the
        sensor's default 1.3 m mount, so its shadow reaches the end of the range).
    """
    from matplotlib.patches import Polygon

    for corners in boxes:
        if not np.all(corners[:, 0] > 0.5):
            continue  # beside or behind the sensor: no shadow ahead
        angles = np.arctan2(corners[:, 1], corners[:, 0])
        lo, hi = corners[int(np.argmin(angles))], corners[int(np.argmax(angles))]
        far_lo = lo / lo[0] * reach
        far_hi = hi / hi[0] * reach
        shadow = np.array([lo, hi, far_hi, far_lo])
        ax.add_patch(
            Polygon(shadow[:, ::-1], closed=True, color="0.85", zorder=0, lw=0, label="shadow")
        )
    for corners in boxes:
        ax.add_patch(
            Polygon(corners[:, ::-1], closed=True, color="0.35", zorder=1, lw=0, label="vehicle")
        )


def plot_conditions_frame(scene: Mapping[str, Any], path: str | Path, *, title: str = "") -> None:
    """One sensor frame with vehicles, shadows and clutter, under each detector's lines.

    :param scene: :func:`~aldm_gym.agents.closed_loop.conditions_scene`'s result.
    :param path: the PNG written.
    :param title: the figure's title.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    frame = scene["frame"]
    names = {
        "naive": "naive",
        "aldm": "ALDM (single frame)",
        "aldm_tracking": "ALDM tracking",
        "ground_truth": "ground truth",
    }
    panels = {names[k]: (frame, det) for k, det in scene["detections"].items() if k in names}
    fig = plot_frames(panels, None, suptitle=title or None, x_max=frame.range)
    clutter = [
        frame.line_points(n)
        for n in range(frame.n_lines)
        if frame.line_marking[n] < 0 and float(np.max(np.abs(frame.line_points(n)[:, 2]))) < 0.5
    ]
    for ax in fig.axes:
        draw_occluders(ax, scene["boxes"], frame.range)
        for i, pts in enumerate(clutter):
            ax.plot(
                pts[:, 1],
                pts[:, 0],
                "x",
                color="black",
                ms=3.5,
                mew=0.9,
                label="clutter (not a marking)" if i == 0 else None,
            )
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    # One legend below the panels: the lines any panel drew, then the scene's parts.
    lines: dict[str, Any] = {}
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            if label in (*LINE_NAMES, "trajectory"):
                lines.setdefault(label, handle)
    handles = [
        *lines.values(),
        Patch(color="0.35", label="vehicle"),
        Patch(color="0.85", label="its shadow"),
        *point_handles(sensor=False).values(),
        Line2D([], [], ls="", marker="x", color="black", label="clutter (not a marking)"),
    ]
    for legend in list(fig.legends):
        legend.remove()
    fig.legend(handles=handles, loc="lower center", fontsize=9.5, ncol=5, frameon=False)
    fig.tight_layout(rect=(0.0, 0.08, 1.0, 1.0))
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)
