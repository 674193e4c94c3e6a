"""SB3 callbacks that interrupt a training the way a signal would (needs
stable-baselines3: import it from tests that skip without it)."""

from __future__ import annotations

from stable_baselines3.common.callbacks import BaseCallback


class InterruptAt(BaseCallback):
    """Raise KeyboardInterrupt (as Ctrl-C would) once ``steps`` steps are done."""

    def __init__(self, steps: int) -> None:
        super().__init__()
        self.steps = steps

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.steps:
            raise KeyboardInterrupt
        return True


class SignalInKernelAt(InterruptAt):
    """A signal handler's KeyboardInterrupt raised inside a C call (a numba kernel
    boxing its result) surfaces as ``SystemError`` with the interrupt as context."""

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.steps:
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt:
                raise SystemError("<CPUDispatcher> returned a result with an exception set")  # noqa: B904
        return True


class RaiseAt(InterruptAt):
    """Raise ``exc`` once ``steps`` steps are done."""

    def __init__(self, steps: int, exc: BaseException) -> None:
        super().__init__(steps)
        self.exc = exc

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.steps:
            raise self.exc
        return True
