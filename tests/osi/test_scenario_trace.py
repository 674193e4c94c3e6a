"""A scenario run written as an OSI trace (``aldm-gym scenario run --osi``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aldm_gym.cli import main
from aldm_gym.osi import ViewReader, read_messages
from tests._cli import usage_error
from tests.scenario._build import write


def test_scenario_run_writes_its_trace(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, target=(1, 60.0, 15.0), activate_at=0.0, stop=3.0)
    trace = tmp_path / "run.mcap"
    code = main(["scenario", "run", str(path), "--osi", str(trace)])
    assert code in (0, 1)
    assert f"wrote the OSI trace {trace}" in capsys.readouterr().out
    views = list(read_messages(trace))
    assert len(views) >= 30  # 3 s at 10 Hz, and the reset's frame
    reader = ViewReader()
    xs = []
    for index, view in views:
        gt = view.global_ground_truth
        assert len(gt.moving_object) == 2  # the ego and the target
        frame = reader.frame(view, index)
        assert frame.n_lines > 0
        xs.append(frame.origin[0])
    assert np.all(np.diff(xs) > 0)  # the ego drives along the road (+x)
    err = usage_error(["scenario", "run", str(path), "--osi", str(tmp_path / "x.txt")], capsys)
    assert ".mcap or .osi" in err
