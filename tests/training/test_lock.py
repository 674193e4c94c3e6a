"""One writer per output folder: a second one is refused naming the holder; the lock of
a killed training is taken over with a warning."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from _cli import usage_error

from aldm_gym.errors import OutputLocked, TrainingWarning
from aldm_gym.training.lock import output_lock
from aldm_gym.training.outputs import LOCK_FILE

_HOLD_LOCK = """
import sys, time
from aldm_gym.training.lock import output_lock
with output_lock(sys.argv[1]):
    print("locked", flush=True)
    time.sleep(60)
"""


def test_a_second_writer_is_refused_naming_the_holder(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", _HOLD_LOCK, str(tmp_path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        with pytest.raises(OutputLocked, match=f"pid {holder.pid}"):
            with output_lock(tmp_path):
                pass
        line = usage_error(["train", "--out", str(tmp_path), "--no-progress"], capsys)
        assert f"argument --out: {tmp_path} is being written by another training " in line
        assert f"(pid {holder.pid}," in line
        argv = ["train", "--resume", "--out", str(tmp_path), "--no-progress"]
        assert f"(pid {holder.pid}," in usage_error(argv, capsys)
    finally:
        holder.kill()
        holder.wait()
    # Killed while holding it: the kernel released the lock; the next writer takes it
    # over and says whose it was.
    with pytest.warns(TrainingWarning, match=f"took over the lock of pid {holder.pid}"):
        with output_lock(tmp_path):
            assert (tmp_path / LOCK_FILE).read_text().strip() == str(os.getpid())
    assert (tmp_path / LOCK_FILE).read_text() == ""  # released cleanly: no warning next
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with output_lock(tmp_path):
            pass
