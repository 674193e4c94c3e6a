"""Regenerate the numbers and figures of the docs from seeded runs (``make figures``).

What it rewrites, each between ``<!-- generated:NAME -->`` and ``<!-- /generated:NAME -->``
markers, so that no number there can go stale unnoticed:

- README.md, ``headline``: the headline table, from ``aldm-gym compare --quick`` (the
  run of ``make demo``; ``tests/test_docs.py`` recomputes it and checks the README);
- docs/results.md, ``open-loop``, ``closed-loop``, ``targets``, ``targets-closed-loop``:
  the naive-vs-ALDM tables of section (a), from ``aldm-gym compare`` (5 roads × 400
  frames per marking model, 10 episodes per policy, 200 target scenes per road);
- docs/img: ``frame_per_dash.png``, ``frame_editor.png``, ``compare_frames.png``,
  ``compare_targets.png`` and ``offset.png`` of that run;
- docs/results.md, ``camera-open-loop``, ``camera-closed-loop`` and
  docs/img/frame_conditions.png: the camera-like sensor (``--sensor-preset camera``,
  15 % trucks, 20 episodes per policy);
- docs/results.md, ``sight-clearance``: a roadside that shortens the view in bends;
- docs/results.md, ``maps``: every shipped OpenDRIVE map (``--quick --xodr NAME``).

The other tables of docs/results.md (the tracker's failure classes, bridges against
their control map, training) come from longer or hand-built runs; each names its
command and date there and is not rewritten here.

Run: ``.venv/bin/python scripts/figures.py [--quick-only]`` (about 5 minutes on 2
cores; ``--quick-only``: the README's table alone, under a minute).
"""

from __future__ import annotations

import argparse
import csv
import re
import shutil
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
NAMES = {
    "naive": "naive",
    "aldm": "ALDM",
    "aldm_tracking": "ALDM tracking",
    "aldm_filter": "ALDM filter",
    "ground_truth": "ground truth",
}
"""Detector names as the docs print them."""

QUICK_ARGS = ["compare", "--quick", "--no-progress"]
"""The headline run: ``make demo``'s comparison."""

FULL_ARGS = ["compare", "--no-progress"]
"""The run of docs/results.md's section (a)."""

FIGURES = (
    "frame_per_dash.png",
    "frame_editor.png",
    "compare_frames.png",
    "compare_targets.png",
    "offset.png",
)
"""The figures of the full run copied to docs/img."""

CAMERA_ARGS = [
    *FULL_ARGS,
    *("--sensor-preset", "camera", "--trucks", "0.15", "--episodes", "20"),
    *("--roads", "3", "--frames", "200"),
]
"""The run under the camera-like sensor."""

SIGHT_ARGS = [*FULL_ARGS, "--sensor", "sight_clearance=2", "--episodes", "3", "--roads", "3"]
SIGHT_ARGS += ["--frames", "100"]
"""The run with a roadside 2 m beyond the outer markings."""

MAPS = ("motorway", "two_plus_one", "features", "bridges")
"""The shipped maps, each run with ``compare --quick --xodr NAME``."""

RESULTS_BLOCKS = (
    "open-loop",
    "closed-loop",
    "targets",
    "targets-closed-loop",
    "camera-open-loop",
    "camera-closed-loop",
    "sight-clearance",
    "maps",
)
"""The generated blocks of docs/results.md (:func:`results_blocks`)."""


def read_rows(path: Path) -> list[dict[str, Any]]:
    """A CSV of ``aldm-gym compare`` as rows, numbers as floats."""
    rows = []
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            out: dict[str, Any] = {}
            for key, value in row.items():
                try:
                    out[key] = float(value)
                except ValueError:
                    out[key] = value
            rows.append(out)
    return rows


def pct(value: float) -> str:
    """A share as a percentage: "0 %" and "100 %" exactly, one decimal otherwise
    ("99.6 %", "35.0 %"); "–" when undefined."""
    if value != value:
        return "–"
    if value in (0.0, 1.0):
        return f"{100.0 * value:.0f} %"
    return f"{100.0 * value:.1f} %"


def num(value: float, digits: int = 3) -> str:
    """A number with ``digits`` decimals (0 without a trailing fraction); "–" for NaN."""
    if value != value:
        return "–"
    return "0" if value == 0 else f"{value:.{digits}f}"


def _label(row: Mapping[str, Any]) -> str:
    """The detector as the tables print it, with the ALDM's mode where it has one."""
    name = NAMES.get(str(row["detector"]), str(row["detector"]))
    mode = row.get("mode") or ""
    return f"{name} ({mode})" if mode and mode != "robust" else name


def _find(rows: Sequence[Mapping[str, Any]], model: str, detector: str, mode: str = "") -> Any:
    return next(
        r
        for r in rows
        if r["marking_model"] == model
        and r["detector"] == detector
        and (r.get("mode") or "") == mode
    )


def headline_table(
    frames: Sequence[Mapping[str, Any]],
    targets: Sequence[Mapping[str, Any]],
    loop: Sequence[Mapping[str, Any]],
) -> str:
    """The README's table from the three CSVs of the quick comparison."""
    lines = [
        "| road model | detector | frames with both ego lines correct | F1 of the four lines "
        "| ACC target right (curve scenes) | closed loop: lane departures per km |",
        "|---|---|---|---|---|---|",
    ]
    model_names = {
        "per_dash": "`per_dash` (every dash an object)",
        "editor": "`editor` (a dashed line is one object)",
    }
    for model in ("per_dash", "editor"):
        for i, detector in enumerate(("naive", "aldm")):
            mode = "robust" if detector == "aldm" else ""
            f = _find(frames, model, detector, mode)
            t = _find(targets, model, detector, mode)
            c = _find(loop, model, detector, mode)
            dep = num(c["departures_per_km"], 1)
            if c["collisions"]:
                n = int(c["collisions"])
                dep += (
                    f" (and {n} collision{'s' if n > 1 else ''} in {int(c['episodes'])} episodes)"
                )
            name = model_names[model] if i == 0 else f"`{model}`"
            label = "naive (CarMaker default)" if detector == "naive" else "ALDM"
            lines.append(
                f"| {name} | {label} | {pct(f['both_correct'])} | {pct(f['strict_f1'])} "
                f"| {pct(t['accuracy'])} | {dep} |"
            )
    return "\n".join(lines)


def summary_table(
    runs: Mapping[str, Mapping[str, Sequence[Mapping[str, Any]]]], first: str = "map"
) -> str:
    """One table of several comparisons (``runs``: name -> their CSVs), a row per
    run, marking model and detector: the open loop's strict rule, F1 and preview and
    the closed loop's departures, both lines correct, collisions and successes."""
    lines = [
        f"| {first} | marking model | detector | open loop: both ego lines correct | F1 "
        "| preview [m] | closed loop: departures / km | both lines correct | collisions "
        "| success rate |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, csvs in runs.items():
        for c in csvs["compare"]:
            mode = c.get("mode") or ""
            frames = [
                r
                for r in csvs["compare_frames"]
                if (r["marking_model"], r["detector"], r.get("mode") or "")
                == (c["marking_model"], c["detector"], mode)
            ]
            # The tracking ALDM has no open-loop row (it needs a sequence of frames).
            nan = float("nan")
            f = frames[0] if frames else {"both_correct": nan, "strict_f1": nan}
            f.setdefault("mean_preview_m", nan)
            lines.append(
                f"| {name} | {c['marking_model']} | {_label(c)} | {pct(f['both_correct'])} "
                f"| {pct(f['strict_f1'])} | {num(f['mean_preview_m'], 1)} "
                f"| {num(c['departures_per_km'], 2)} | {pct(c['both_correct'])} "
                f"| {int(c['collisions'])} | {pct(c['success_rate'])} |"
            )
    return "\n".join(lines)


Column = tuple[str, Callable[[Mapping[str, Any]], str]]
"""A table column: its header and how a row's cell reads."""


def markdown_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[Column]) -> str:
    """A Markdown table of ``rows``: the first two columns (marking model, detector)
    left-aligned, the numbers right-aligned."""
    lines = [
        "| " + " | ".join(header for header, _ in columns) + " |",
        "|" + "---|" * 2 + "---:|" * (len(columns) - 2),
    ]
    lines += ["| " + " | ".join(cell(r) for _, cell in columns) + " |" for r in rows]
    return "\n".join(lines)


def _share(key: str) -> Callable[[Mapping[str, Any]], str]:
    return lambda r: pct(r[key])


def _number(key: str, digits: int = 3) -> Callable[[Mapping[str, Any]], str]:
    return lambda r: num(r[key], digits)


def _count(key: str) -> Callable[[Mapping[str, Any]], str]:
    return lambda r: str(int(r[key]))


MODEL_AND_DETECTOR: tuple[Column, ...] = (
    ("marking model", lambda r: str(r["marking_model"])),
    ("detector", _label),
)

OPEN_LOOP: tuple[Column, ...] = (
    *MODEL_AND_DETECTOR,
    ("both ego lines correct", _share("both_correct")),
    ("F1 strict", _share("strict_f1")),
    ("precision", _share("strict_precision")),
    ("recall", _share("strict_recall")),
    ("F1 at 1.5 m", _share("loose_f1")),
    ("error ≤ 40 m [m]", _number("near_mean_m")),
    ("error > 40 m [m]", _number("far_mean_m")),
    ("p95 error [m]", _number("p95_abs_error_m")),
    ("preview [m]", _number("mean_preview_m", 1)),
    ("adjacent lines correct", _share("adjacent_correct")),
)
"""docs/results.md's open-loop tables."""

CLOSED_LOOP: tuple[Column, ...] = (
    *MODEL_AND_DETECTOR,
    ("km", _number("km", 1)),
    ("departures / km", _number("departures_per_km", 2)),
    ("RMS offset [m]", _number("rms_offset_m")),
    ("max offset [m]", _number("max_offset_m")),
    ("both lines correct", _share("both_correct")),
    ("mean preview [m]", _number("mean_preview_m", 1)),
    ("collisions", _count("collisions")),
    ("lane changes ok", _count("lane_changes_ok")),
    ("failed", _count("lane_changes_failed")),
    ("mean speed [m/s]", _number("mean_speed", 2)),
    ("success rate", _share("success_rate")),
)
"""docs/results.md's closed-loop tables."""

TARGETS: tuple[Column, ...] = (
    *MODEL_AND_DETECTOR,
    ("correct", _share("accuracy")),
    ("missed", _share("missed_rate")),
    ("false", _share("false_rate")),
    ("ego-lane scenes", _share("ego_lane_accuracy")),
    ("adjacent", _share("adjacent_accuracy")),
    ("cut-ins", _share("cut_in_accuracy")),
)
"""docs/results.md's table of the hard target-selection scenes."""

TARGETS_CLOSED_LOOP: tuple[Column, ...] = (
    *MODEL_AND_DETECTOR,
    ("collisions", _count("collisions")),
    ("rear-end", _count("rear_end_collisions")),
    ("target correct", _share("target_accuracy")),
    ("missed", _share("missed_rate")),
    ("false", _share("false_rate")),
    ("phantom braking", _count("phantom_braking")),
    ("AEB", _count("aeb_activations")),
    ("min time gap [s]", _number("min_time_gap", 2)),
)
"""docs/results.md's table of the ACC in the closed loop."""


def replace_block(text: str, name: str, content: str) -> str:
    """``text`` with the block between ``<!-- generated:name -->`` and
    ``<!-- /generated:name -->`` replaced by ``content``.

    :raises ValueError: the markers are missing.
    """
    pattern = re.compile(
        rf"(<!-- generated:{re.escape(name)} -->\n).*?(\n<!-- /generated:{re.escape(name)} -->)",
        re.S,
    )
    if not pattern.search(text):
        raise ValueError(f"no <!-- generated:{name} --> block")
    return pattern.sub(lambda m: m.group(1) + content + m.group(2), text)


def block(text: str, name: str) -> str:
    """The content of block ``name`` of ``text`` (:func:`replace_block`)."""
    m = re.search(
        rf"<!-- generated:{re.escape(name)} -->\n(.*?)\n<!-- /generated:{re.escape(name)} -->",
        text,
        re.S,
    )
    if m is None:
        raise ValueError(f"no <!-- generated:{name} --> block")
    return m.group(1)


def run_compare(args: list[str], out: Path) -> dict[str, list[dict[str, Any]]]:
    """Run ``aldm-gym <args> --out out`` in this process; its CSVs as rows (the target
    scenes' CSV is empty on a map, where there are none)."""
    from aldm_gym.cli import main

    code = main([*args, "--out", str(out)])
    if code not in (0, None):
        raise SystemExit(code)
    names = ("compare_frames", "compare_targets", "compare")
    return {n: read_rows(out / f"{n}.csv") if (out / f"{n}.csv").exists() else [] for n in names}


def quick_headline(out: Path) -> str:
    """The README's headline table, computed by the quick comparison into ``out``."""
    csvs = run_compare(QUICK_ARGS, out)
    return headline_table(csvs["compare_frames"], csvs["compare_targets"], csvs["compare"])


def results_blocks(out: Path) -> tuple[dict[str, str], dict[Path, str]]:
    """The generated blocks of docs/results.md and the figures for docs/img, from the
    runs of the module docstring into ``out``: ``(blocks, {source file: image name})``."""
    full = run_compare(FULL_ARGS, out / "full")
    camera = run_compare(CAMERA_ARGS, out / "camera")
    sight = run_compare(SIGHT_ARGS, out / "sight")
    maps = {m: run_compare([*QUICK_ARGS, "--xodr", m], out / f"map_{m}") for m in MAPS}
    blocks = {
        "open-loop": markdown_table(full["compare_frames"], OPEN_LOOP),
        "closed-loop": markdown_table(full["compare"], CLOSED_LOOP),
        "targets": markdown_table(full["compare_targets"], TARGETS),
        "targets-closed-loop": markdown_table(full["compare"], TARGETS_CLOSED_LOOP),
        "camera-open-loop": markdown_table(camera["compare_frames"], OPEN_LOOP),
        "camera-closed-loop": markdown_table(camera["compare"], CLOSED_LOOP),
        "sight-clearance": summary_table({"sight_clearance 2 m": sight}, first="roadside"),
        "maps": summary_table({f"`{m}`": csvs for m, csvs in maps.items()}),
    }
    assert tuple(blocks) == RESULTS_BLOCKS
    figures = {out / "full" / f: f for f in FIGURES}
    figures[out / "camera" / "frame_conditions.png"] = "frame_conditions.png"
    return blocks, figures


def main(argv: list[str] | None = None) -> None:
    """Rewrite the generated blocks and figures (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick-only", action="store_true", help="the README only")
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "figures")
    args = parser.parse_args(argv)
    readme = ROOT / "README.md"
    readme.write_text(
        replace_block(readme.read_text(), "headline", quick_headline(args.out / "quick"))
    )
    print(f"rewrote {readme} (headline table)")
    if args.quick_only:
        return
    blocks, figures = results_blocks(args.out)
    results = ROOT / "docs" / "results.md"
    text = results.read_text()
    for name, content in blocks.items():
        text = replace_block(text, name, content)
    results.write_text(text)
    for source, name in figures.items():
        shutil.copy(source, ROOT / "docs" / "img" / name)
    print(f"rewrote {results} ({len(blocks)} tables) and docs/img: {', '.join(figures.values())}")


if __name__ == "__main__":
    main()
