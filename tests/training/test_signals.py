"""SIGINT/SIGTERM during a training: a stop request at a safe point, or an interrupt."""

from __future__ import annotations

import os
import signal

import pytest

from aldm_gym.training.signals import raised_by_interrupt, signals_deferred, stop_on_signal


class SignalInKernel:
    """A signal handler's KeyboardInterrupt raised inside a C call (a numba kernel
    boxing its result) surfaces as ``SystemError`` with the interrupt as context."""

    def raise_it(self) -> None:
        """Raise the ``SystemError`` such a call raises."""
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("<CPUDispatcher> returned a result with an exception set")  # noqa: B904


def test_an_interrupt_wrapped_by_a_c_call_is_an_interruption() -> None:
    try:
        SignalInKernel().raise_it()
    except SystemError as exc:
        assert raised_by_interrupt(exc)
    assert raised_by_interrupt(KeyboardInterrupt())
    assert not raised_by_interrupt(SystemError("a real fault"))
    try:
        try:
            raise ValueError("x")
        except ValueError:
            raise SystemError("y")  # noqa: B904
    except SystemError as exc:
        assert not raised_by_interrupt(exc)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_the_first_signal_requests_a_stop_and_the_second_interrupts(sig: int) -> None:
    before = signal.getsignal(sig)
    with stop_on_signal(at_once=False) as stop:
        os.kill(os.getpid(), sig)
        assert stop.requested
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), sig)
    assert signal.getsignal(sig) is before


def test_a_trainer_that_can_stop_anywhere_is_interrupted_at_once() -> None:
    with pytest.raises(KeyboardInterrupt), stop_on_signal(at_once=True):
        os.kill(os.getpid(), signal.SIGTERM)


def test_deferred_signals_arrive_after_the_block() -> None:
    with stop_on_signal(at_once=False) as stop:
        with signals_deferred():
            os.kill(os.getpid(), signal.SIGTERM)
            assert not stop.requested
        assert stop.requested


def test_a_second_signal_ends_an_insisting_deferral_at_once() -> None:
    # the build of a training holds the first signal (an interrupted import would
    # leave a broken module) and gives way to a second one
    reached = []
    with pytest.raises(KeyboardInterrupt), stop_on_signal(at_once=True):
        with signals_deferred(insist=True):
            os.kill(os.getpid(), signal.SIGTERM)
            reached.append("held")
            os.kill(os.getpid(), signal.SIGINT)
            reached.append("not reached")
    assert reached == ["held"]


def test_an_interrupt_outside_a_safe_point_exits_130(monkeypatch: pytest.MonkeyPatch) -> None:
    from aldm_gym import cli

    def interrupted(args: object) -> int:
        raise KeyboardInterrupt

    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    parser._subparsers._group_actions[0].choices["plot"].set_defaults(func=interrupted)  # type: ignore[union-attr]
    assert cli.main(["plot"]) == 130
