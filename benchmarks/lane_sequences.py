"""The lane detectors on drives along map lanes: single frame, filter, tracker.

For every map (the shipped ones and ``benchmarks/data/curvature_step.xodr``, whose
straights and R 100 m arcs meet with no transition curve), every lane chain a drive
starts on (:func:`aldm_gym.sensor.drives.drive_starts`), and every condition of
:data:`aldm_gym.sensor.drives.CONDITIONS` (ideal; 5 cm noise and 10 % dropout; 30 %
worn dashes; four moving vehicles, 30 % trucks; all together), the ego drives the
chain at 25 m/s with a frame every 0.1 s (per-dash paint, the line sensor's CarMaker
sampling) and each detector is scored per frame
(:func:`aldm_gym.sensor.drives.drive`). Prints one Markdown table: per map and
condition, the share of frames in which both ego lines were observed to the preview
(:class:`~aldm_gym.sensor.drives.SeenPaint`), and per detector the share of frames
with both ego lines correct, the longest run of wrong frames [s] (in brackets: the
longest within observed frames) and the share of ego lines missing.

Run: ``.venv/bin/python -m benchmarks.lane_sequences [--jobs 2] [--max-frames 600]
[--maps NAME,...] [--conditions NAME,...]`` (about three minutes on 2 cores). A ``--maps``
entry may also be the path of any OpenDRIVE file (``.xodr``): the benchmark then drives
your own map, named in the table by its file name.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from tqdm import tqdm

from aldm_gym.errors import AldmGymError
from aldm_gym.roads import SHIPPED_MAPS, OpenDriveRoad, shipped_map
from aldm_gym.sensor.drives import CONDITIONS, DETECTORS, DriveScore, drive, drive_starts

CURVATURE_STEP = Path(__file__).resolve().parent / "data" / "curvature_step.xodr"
"""Straight, R 100 m, straight, R 100 m, straight, with no transition curves."""

MAPS: dict[str, Path] = {
    **{name: shipped_map(name) for name in SHIPPED_MAPS},
    "curvature_step": CURVATURE_STEP,
}
"""The maps the benchmark drives on."""


def map_path(name: str) -> Path:
    """The file of a map of :data:`MAPS`, or ``name`` itself as the path of an
    OpenDRIVE file.

    :raises ValueError: ``name`` is neither.
    """
    if name in MAPS:
        return MAPS[name]
    path = Path(name)
    if path.suffix.lower() != ".xodr":
        raise ValueError(
            f"{name!r} is no map of the benchmark ({', '.join(MAPS)}) and no OpenDRIVE "
            "file (a path ending in .xodr)"
        )
    if not path.is_file():
        raise ValueError(f"{name}: no such file")
    return path


NO_DRIVE = (
    "no driving lane starts a lane chain of at least 400 m (the lanes of a ring have no start)"
)
"""Why a map has no drive (:func:`~aldm_gym.sensor.drives.drive_starts`)."""


def _label(name: str) -> str:
    return name if name in MAPS else Path(name).name


Task = tuple[str, str, tuple[str, int, int], int]
"""``(map, condition, drive start, max_frames)``: one drive."""


def _run(task: Task) -> tuple[str, str, dict]:
    name, condition, start, max_frames = task
    road = OpenDriveRoad.from_file(map_path(name), marking_model="per_dash")
    return name, condition, drive(road, start, CONDITIONS[condition], max_frames=max_frames)


def drive_tasks(maps: list[str], conditions: list[str], max_frames: int) -> list[Task]:
    """Every drive of ``maps`` (names of :data:`MAPS` or OpenDRIVE files' paths,
    :func:`map_path`) under ``conditions``.

    :raises ValueError: a map that is no map, cannot be read (a ``MapError``) or has
        no drive (:data:`NO_DRIVE`).
    """
    tasks: list[Task] = []
    for name in maps:
        road = OpenDriveRoad.from_file(map_path(name), marking_model="per_dash")
        starts = drive_starts(road)
        if not starts:
            raise ValueError(f"{_label(name)}: {NO_DRIVE}")
        for start in starts:
            tasks += [(name, c, start, max_frames) for c in conditions]
    return tasks


def _merged(
    tasks: list[Task], maps: list[str], conditions: list[str], jobs: int
) -> dict[tuple[str, str], dict[str, DriveScore]]:
    totals = {(m, c): {d: DriveScore() for d in DETECTORS} for m in maps for c in conditions}
    with ProcessPoolExecutor(jobs) as pool:
        for name, condition, scores in tqdm(
            pool.map(_run, tasks), total=len(tasks), desc="drives", unit="drive"
        ):
            for d, sc in scores.items():
                totals[name, condition][d].merge(sc)
    return totals


def table(
    maps: list[str], conditions: list[str], max_frames: int, jobs: int
) -> dict[tuple[str, str], dict[str, DriveScore]]:
    """Every drive (:func:`drive_tasks`), merged per map and condition."""
    return _merged(drive_tasks(maps, conditions, max_frames), maps, conditions, jobs)


def main(argv: list[str] | None = None) -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--max-frames", type=int, default=600, help="per drive (60 s)")
    parser.add_argument(
        "--maps",
        default=",".join(MAPS),
        help="names of the benchmark's maps or paths of OpenDRIVE files (.xodr), comma-separated",
    )
    parser.add_argument("--conditions", default=",".join(CONDITIONS))
    args = parser.parse_args(argv)
    maps = [m for m in args.maps.split(",") if m]
    conditions = [c for c in args.conditions.split(",") if c]
    bad = [c for c in conditions if c not in CONDITIONS]
    if bad:
        parser.error(f"unknown conditions {bad}; conditions: {list(CONDITIONS)}")
    try:
        tasks = drive_tasks(maps, conditions, args.max_frames)
    except (AldmGymError, ValueError) as e:
        parser.error(str(e))
    totals = _merged(tasks, maps, conditions, args.jobs)
    head = " | ".join(f"{d} both / longest wrong (observed) / missed" for d in DETECTORS)
    print(f"\n| map | condition | frames | observed | {head} |")
    print("|---|---|---:|---:|" + "---:|" * len(DETECTORS))
    for (name, condition), scores in totals.items():
        cells = " | ".join(
            f"{sc.share:.3f} / {sc.longest_wrong_s:.1f} s ({sc.longest_wrong_observed_s:.1f} s)"
            f" / {sc.missed_share:.3f}"
            for sc in scores.values()
        )
        first = scores[DETECTORS[0]]
        print(
            f"| {_label(name)} | {condition} | {first.frames} | {first.observed_share:.3f} "
            f"| {cells} |"
        )


if __name__ == "__main__":
    main()
