"""Test helper: run ``aldm-gym`` expecting a usage error."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from aldm_gym.cli import main

NESTED = ("scenario", "osi")
"""Commands whose usage errors come from an action's parser (``aldm-gym scenario run``)."""


def usage_error(argv: Sequence[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``aldm-gym argv``; assert it exits with code 2 after the subcommand's usage
    and no traceback; return the one error line (``aldm-gym <cmd>: error: ...``)."""
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(list(argv))
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert lines[0].startswith("usage: aldm-gym"), err
    command = " ".join(argv[:2] if argv[0] in NESTED else argv[:1])
    assert lines[-1].startswith(f"aldm-gym {command}: error: "), err
    return lines[-1]
