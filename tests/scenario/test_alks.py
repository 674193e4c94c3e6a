"""The 15 concrete scenarios of the OSC-ALKS suite (UN R157 Annex 5, 4.1-4.6), end to end.

The suite is not shipped with the package: the tests read it from ``$OSC_ALKS_DIR``,
else from ``../shared/osc-alks`` beside the repository, and skip without it.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from aldm_gym.harness.criteria import run_scenario


def _suite() -> Path | None:
    for candidate in (
        os.environ.get("OSC_ALKS_DIR"),
        Path(__file__).resolve().parents[3] / "shared" / "osc-alks",
    ):
        if candidate and (Path(candidate) / "logical_scenarios").is_dir():
            return Path(candidate) / "logical_scenarios"
    return None


SUITE = _suite()
CONCRETE = sorted((SUITE / "concrete_scenarios").glob("*.xosc")) if SUITE else []
pytestmark = pytest.mark.skipif(
    SUITE is None, reason="the OSC-ALKS suite is not here (set OSC_ALKS_DIR)"
)

KNOWN_FAILURES = {
    # 4.2_3 (crossing pedestrian) passes with a small margin: the pedestrian starts
    # when its box (its width along the road) is 2.16 s ahead, the AEB stops the ego
    # about 0.2 m short of it (docs/results.md).
    # The cut-in leaves 0.26 s: the gap cannot be restored within 3 s (the suite calls
    # the collision unavoidable; the gap criterion is judged all the same).
    "alks_scenario_4_4_2_cut_in_unavoidable_collision_template.xosc": "time_gap",
}
"""Criteria the shipped function fails with ground-truth lanes (docs/scenarios.md)."""


def test_all_fifteen_are_here() -> None:
    assert len(CONCRETE) == 15


@pytest.mark.parametrize("path", CONCRETE, ids=lambda p: p.name[14:19])
def test_perception_through_the_aldm_is_as_good_as_ground_truth(path: Path) -> None:
    runs = {
        (det, mm): run_scenario(path, detector=det, marking_model=mm)
        for det in ("ground_truth", "aldm")
        for mm in ("per_dash", "editor")
    }
    truth = runs["ground_truth", "per_dash"]
    verdicts = {key: (r.passed, r.no_collision, r.in_lane, r.time_gap) for key, r in runs.items()}
    assert len(set(verdicts.values())) == 1, verdicts
    assert truth.finished or truth.collision
    failed = {c for c in ("no_collision", "in_lane", "time_gap") if not getattr(truth, c)}
    expected = {KNOWN_FAILURES[path.name]} if path.name in KNOWN_FAILURES else set()
    assert failed == expected


def test_naive_detection_on_per_dash_paint_fails_free_driving() -> None:
    path = next(p for p in CONCRETE if "4_1_1" in p.name)
    naive = run_scenario(path, detector="naive", marking_model="per_dash")
    editor = run_scenario(path, detector="naive", marking_model="editor")
    assert not naive.in_lane and naive.departures > 0
    assert editor.passed
