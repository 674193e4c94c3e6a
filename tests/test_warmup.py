"""The warm-up (``python -m aldm_gym.warmup``): two processes, and a helper that fails
is not fatal (the serial pass compiles what it left)."""

from __future__ import annotations

import sys
from typing import Any

import pytest

from aldm_gym import warmup


def test_parallel_warm_up_survives_a_failing_helper(monkeypatch: pytest.MonkeyPatch) -> None:
    """A helper process that exits with an error leaves the serial pass to do the work."""
    launched: list[list[str]] = []
    real_popen = warmup.subprocess.Popen

    def failing_popen(args: list[str], **kwargs: Any) -> Any:
        launched.append(args)
        return real_popen([sys.executable, "-c", "raise SystemExit(3)"], **kwargs)

    monkeypatch.setattr(warmup.subprocess, "Popen", failing_popen)
    took = warmup.warm_up(parallel=True)
    assert took > 0.0
    assert len(launched) == 1 and "_the_rest" in launched[0][-1]


def test_serial_flag_runs_without_a_helper(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--serial`` compiles in this process only; the default lets the CPU count decide."""
    seen: list[bool | None] = []
    monkeypatch.setattr(warmup, "warm_up", lambda parallel=None: seen.append(parallel) or 1.0)
    for argv, expected in ((["--serial"], False), ([], None)):
        monkeypatch.setattr(sys, "argv", ["aldm_gym.warmup", *argv])
        warmup.main()
        assert seen[-1] is expected
    assert "kernels ready in 1 s" in capsys.readouterr().out


def test_the_warm_up_runs_the_compiled_traffic_engine() -> None:
    """The warm-up's envs step the traffic in the compiled engine on every CPU, so its
    kernels are in the cache before a test worker or a progress bar needs them."""
    assert warmup._env_steps(warmup._HELPER_ENVS[:1]) == 10  # one env step, 10 simulation steps
    assert warmup._env_steps(warmup._FINAL_ENVS[:1]) == 10


def test_store_flag_builds_only_when_the_shipped_kernels_do_not_match(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--store`` compiles the shipped kernels when they are missing or stale, and says
    so without compiling when they are current."""
    import aldm_gym._numba as numba_guards

    built: list[bool | None] = []
    monkeypatch.setattr(warmup, "build_store", lambda parallel=None: built.append(parallel) or 2.0)
    monkeypatch.setattr(sys, "argv", ["aldm_gym.warmup", "--store", "--serial"])
    for status, builds in (("current", 0), ("stale", 1), ("missing", 2)):
        monkeypatch.setattr(numba_guards, "store_status", lambda status=status: status)
        warmup.main()
        assert len(built) == builds
    assert built == [False, False]
    out = capsys.readouterr().out
    assert "the shipped kernels are current" in out and out.count("kernels ready in 2 s") == 2
