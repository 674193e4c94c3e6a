"""The open-loop comparison: the same frames on both marking models, both ALDM modes."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from aldm_gym.errors import ConfigError
from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor import LineSensor
from aldm_gym.sensor.open_loop import COLUMNS, FRAME_DETECTORS, compare_detectors


class RecordingSensor(LineSensor):
    """A line sensor that records each pose, marking model and noise draw it measures."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.seen: list[tuple[str, tuple[float, ...], float]] = []

    def measure(self, road: Any, pose: Any, *args: Any, rng: Any = None, **kwargs: Any) -> Any:
        draw = float(np.random.default_rng(rng.bit_generator.state["state"]["state"]).random())
        self.seen.append((road.marking_model, tuple(pose), draw))
        return super().measure(road, pose, *args, rng=rng, **kwargs)


def test_both_marking_models_see_the_same_poses_and_noise() -> None:
    sensor = RecordingSensor({"lateral_noise": 0.05})
    roads = [HighwayRoad({"seed": 3, "length": 3000.0})]
    rows = compare_detectors(roads, frames_per_road=6, sensor=sensor, seed=2)
    per_dash = [(p, d) for m, p, d in sensor.seen if m == "per_dash"]
    editor = [(p, d) for m, p, d in sensor.seen if m == "editor"]
    assert len(per_dash) == len(editor) == 6
    assert per_dash == editor
    assert len({p for p, _ in per_dash}) == 6  # six different poses
    assert {(r["marking_model"], r["detector"], r["mode"]) for r in rows} == {
        (m, d, mode) for m in ("per_dash", "editor") for d, mode, _ in FRAME_DETECTORS
    }
    assert all(list(r) == list(COLUMNS) for r in rows)


def test_ground_truth_bounds_the_detectors_on_noisy_frames() -> None:
    roads = [HighwayRoad({"seed": 4, "length": 3000.0})]
    sensor = LineSensor({"lateral_noise": 0.1, "dropout": 0.2})
    rows = compare_detectors(roads, frames_per_road=20, sensor=sensor, seed=0)
    for model in ("per_dash", "editor"):
        mine = [r for r in rows if r["marking_model"] == model]
        gt = next(r for r in mine if r["detector"] == "ground_truth")
        assert gt["strict_f1"] == 1.0 and gt["strict_fp"] == gt["strict_fn"] == 0
        for r in mine:
            assert r["strict_f1"] <= gt["strict_f1"] and r["loose_f1"] <= gt["loose_f1"]
            assert r["mean_preview_m"] <= gt["mean_preview_m"]
        modes = {r["mode"] for r in mine if r["detector"] == "aldm"}
        assert modes == {"robust", "paper"}


def test_detectors_by_name() -> None:
    rows = compare_detectors([HighwayRoad({"seed": 1, "length": 2000.0})], ["naive", "aldm"], 3)
    assert {(r["detector"], r["mode"]) for r in rows} == {("naive", ""), ("aldm", "robust")}
    assert {r["marking_model"] for r in rows} == {"per_dash", "editor"}


@pytest.mark.parametrize(
    ("detectors", "message"),
    [
        ([("aldm", "", {}), ("aldm", "", {"mode": "paper"})], "mode label ''"),
        ([("aldm", "robust", {"mode": "paper"})], "is not the mode it runs, 'paper'"),
        ([("aldm", "robust", {}), "aldm"], r"given twice .*\('aldm', 'robust'\)"),
        ([("naive", "")], r"a name or \(detector, mode, params\)"),
        ([("naive", "paper", {})], "is not the mode it runs, ''"),
    ],
)
def test_bad_detector_rows_are_named(detectors: list, message: str) -> None:
    road = [HighwayRoad({"seed": 1, "length": 2000.0})]
    with pytest.raises(ConfigError, match=message):
        compare_detectors(road, detectors, 2)


def test_no_marking_model_is_an_error() -> None:
    with pytest.raises(ConfigError, match="marking_models is empty"):
        compare_detectors([HighwayRoad({"seed": 1})], ["naive"], 2, marking_models=[])
