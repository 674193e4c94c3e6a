"""What every training does, written once in :mod:`aldm_gym.training.backend`: checked
with a backend that trains nothing, and through both real backends where cheap."""

from __future__ import annotations

import json
import os
import signal
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import pytest

from aldm_gym.errors import CheckpointError, OutputLocked, ResumeError, TrainingWarning
from aldm_gym.training.backend import Backend, CheckpointRef, train_with
from aldm_gym.training.lock import output_lock
from aldm_gym.training.settings import env_config
from aldm_gym.training.signals import StopRequest


class CountingBackend(Backend[CheckpointRef]):
    """Trains nothing: counts steps, keeps checkpoints in a list, records its calls.

    :cvar faults: checkpoint steps -> why it cannot be used.
    :cvar unrestorable: checkpoint steps whose restore fails.
    :cvar during_learn: called with the backend at each step of :meth:`learn`.
    """

    name: ClassVar[str] = "sb3"
    stops_at_once: ClassVar[bool] = False
    faults: ClassVar[dict[int, str]] = {}
    unrestorable: ClassVar[set[int]] = set()
    during_learn: ClassVar[Callable[[CountingBackend], None] | None] = None
    saved_steps: ClassVar[list[int]] = []

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self.steps = 0
        self.calls: list[str] = []

    @staticmethod
    def require() -> None:
        pass

    def checkpoints(self) -> list[CheckpointRef]:
        return [CheckpointRef(s, self.out / f"c{s}") for s in sorted(self.saved_steps)[::-1]]

    def checkpoint_fault(self, checkpoint: CheckpointRef) -> str | None:
        return self.faults.get(checkpoint.steps)

    def restore(self, checkpoint: CheckpointRef) -> str:
        if checkpoint.steps in self.unrestorable:
            raise CheckpointError(f"{checkpoint.path}: does not restore")
        self.calls.append(f"restore {checkpoint.steps}")
        self.steps = checkpoint.steps
        return "continued"

    def build(self) -> None:
        self.calls.append("build")

    def learn(self, stop: StopRequest) -> None:
        while self.steps < self.record.run.timesteps and not stop.requested:
            self.steps += 1
            if self.during_learn is not None:
                type(self).during_learn(self)  # type: ignore[misc]

    def save_checkpoint(self) -> CheckpointRef | None:
        self.calls.append("save_checkpoint")
        self.saved_steps.append(self.steps)
        return CheckpointRef(self.steps, self.out / f"c{self.steps}")

    def save_final(self) -> Path:
        self.calls.append("save_final")
        return self.out / "final"

    def close(self, interrupted: bool) -> None:
        self.calls.append(f"close {interrupted}")

    @classmethod
    def load_policy(cls, path: Path) -> tuple[Any, Any]:
        raise NotImplementedError


@pytest.fixture()
def counting(monkeypatch: pytest.MonkeyPatch) -> type[CountingBackend]:
    """:class:`CountingBackend` with fresh class state."""
    for name, value in (("faults", {}), ("unrestorable", set()), ("saved_steps", [])):
        monkeypatch.setattr(CountingBackend, name, value)
    monkeypatch.setattr(CountingBackend, "during_learn", None)
    return CountingBackend


def _train(backend: type[CountingBackend], out: Path, **kwargs: Any) -> CountingBackend:
    given = {"timesteps": kwargs.pop("timesteps", 10), "seed": None}
    return train_with(
        backend, out, given=given, config=env_config(), params=None, progress=False, **kwargs
    )


def test_a_training_writes_its_record_and_saves_the_final_model(
    counting: type[CountingBackend], tmp_path: Path
) -> None:
    backend = _train(counting, tmp_path, resume=False)
    assert backend.calls == ["build", "save_final", "close False"] and backend.steps == 10
    meta = json.loads((tmp_path / "training.json").read_text())
    assert (meta["backend"], meta["timesteps"], meta["env_config"]["detector"]) == (
        "sb3",
        10,
        "aldm",
    )
    with pytest.raises(FileExistsError, match="already holds a training"):
        _train(counting, tmp_path, resume=False)


def test_a_resume_falls_back_to_the_newest_checkpoint_that_restores(
    counting: type[CountingBackend], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "training.json").write_text(json.dumps({"env_config": {}, "ppo": {}}))
    counting.saved_steps.extend([2, 4, 6])
    counting.faults[6] = "c6: truncated"
    counting.unrestorable.add(4)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with caplog.at_level("INFO", logger="aldm_gym"):
            backend = _train(counting, tmp_path, resume=True, timesteps=None)
    assert [str(w.message) for w in caught if w.category is TrainingWarning] == [
        "skipping checkpoint 6: c6: truncated",
        f"skipping checkpoint 4: {tmp_path / 'c4'}: does not restore",
    ]
    assert backend.calls[0] == "restore 2" and backend.steps == 49_152  # the default budget
    assert "at 2 steps; restored: env config, PPO hyperparameters" in caplog.text
    counting.unrestorable.update({2, 6})
    counting.faults.clear()
    with pytest.warns(TrainingWarning), caplog.at_level("INFO", logger="aldm_gym"):
        assert _train(counting, tmp_path, resume=True).calls[0] == "build"
    assert "no intact checkpoint: starting again from step 0" in caplog.text


@pytest.mark.parametrize("at_once", [False, True])
def test_a_signal_stops_at_a_safe_point_and_saves_a_checkpoint(
    counting: type[CountingBackend],
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
    at_once: bool,
) -> None:
    monkeypatch.setattr(counting, "stops_at_once", at_once)

    def sigterm_at_3(backend: CountingBackend) -> None:
        if backend.steps == 3:
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(counting, "during_learn", sigterm_at_3)
    with pytest.raises(KeyboardInterrupt), caplog.at_level("INFO", logger="aldm_gym"):
        _train(counting, tmp_path, resume=False)
    assert counting.saved_steps == [3]
    word = "interrupted" if at_once else "stopped"
    assert f"{word} after 0 s; saved {tmp_path / 'c3'} (3 steps); continue with --resume" in (
        caplog.text
    )


def test_a_second_signal_mid_chunk_saves_nothing(
    counting: type[CountingBackend],
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def two_sigterms(backend: CountingBackend) -> None:
        if backend.steps == 3:
            os.kill(os.getpid(), signal.SIGTERM)
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(counting, "during_learn", two_sigterms)
    with pytest.raises(KeyboardInterrupt), caplog.at_level("INFO", logger="aldm_gym"):
        _train(counting, tmp_path, resume=False)
    assert counting.saved_steps == []
    assert "interrupted after 0 s; nothing saved yet; continue with --resume" in caplog.text


def _backend_train(name: str) -> Callable[..., Any]:
    """Either backend's training function, skipping without its extra."""
    if name == "sb3":
        pytest.importorskip("stable_baselines3")
        from aldm_gym.training.sb3.backend import train

        return train
    pytest.importorskip("ray.rllib")
    from aldm_gym.training.rllib.backend import train_rllib

    return train_rllib


@pytest.mark.parametrize("name", ["sb3", "rllib"])
def test_both_backends_hold_the_lock_and_refuse_what_they_cannot_resume(
    name: str, tmp_path: Path
) -> None:
    train = _backend_train(name)
    with output_lock(tmp_path), pytest.raises(OutputLocked, match="another training"):
        train(tmp_path, progress=False)
    with pytest.raises(FileNotFoundError, match="nothing to resume"):
        train(tmp_path, resume=True, progress=False)
    other = {"sb3": "rllib", "rllib": "sb3"}[name]
    record = {"backend": other, "env_config": {}, "ppo": {}}
    (tmp_path / "training.json").write_text(json.dumps(record))
    with pytest.raises(ResumeError, match=f"resume it with --backend {other}"):
        train(tmp_path, resume=True, progress=False)
    with pytest.raises(FileExistsError, match="already holds a training"):
        train(tmp_path, progress=False)
