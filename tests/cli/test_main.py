"""The ``aldm-gym`` entry points: version, ``python -m``, subcommand errors."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from aldm_gym import __version__
from aldm_gym.cli import main


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"aldm-gym {__version__}"


def test_unknown_argument_shows_the_subcommands_usage(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["plot", "--bogus"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "usage: aldm-gym plot" in err and "unrecognized arguments: --bogus" in err


def test_subcommand_help_shows_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["plot", "--help"])
    assert "(default: 0)" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["compare", "plot", "train", "evaluate"])
def test_help_has_no_empty_defaults(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Arguments without a default of their own do not read "(default: None)"."""
    argv = [command, "--help"]
    with pytest.raises(SystemExit):
        main(argv)
    out = capsys.readouterr().out
    assert "--out" in out
    for empty in ("(default: None)", "(default: False)", "(default: [])"):
        assert empty not in out
    # no help names its default a second time ("(default -1) (default: -1)")
    for chunk in re.split(r"\n  -", out):
        assert chunk.count("default") <= 1, chunk


def test_python_dash_m() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "aldm_gym", "--version"], capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == f"aldm-gym {__version__}"
