"""Running fuzz cases in a child process with a memory cap and a time limit.

A case is a dict: its ``label``, its ``argv`` for ``aldm-gym`` (run in process through
:func:`aldm_gym.cli.main`), and ``names``: the file names a refusal must mention (any
one). The child plays the cases in order under ``RLIMIT_AS`` (the address space it had
after the first case, plus :data:`MEMORY_CAP`) and a per-case alarm, and prints one
JSON line per case. Each outcome is classified:

* ``refused``: exit 2 with one ``error:`` line that names the file (a named error);
* ``played``: exit 0 or 1 (a verdict, or "not judged"), with no ``nan`` in what it
  printed;
* ``defect``: anything else: a traceback, a refusal that does not name the file, a
  NaN printed, ``MemoryError``, the time limit, a crash of the child.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import resource
import signal
import subprocess
import sys
import traceback
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

MEMORY_CAP = 2 << 30
"""Address space a case may add to the child's [bytes] (the review's 2 GB goal)."""

CASE_TIMEOUT = 120
"""Seconds a case may take before it is a defect."""

_NAN = re.compile(r"(?<![\w.])nan(?![\w])", re.IGNORECASE)
"""A NaN printed: garbage out (``inf`` is a fair "none": no vehicle ahead, no TTC)."""


class _Timeout(BaseException):
    """The case ran out of time (a BaseException: no ``except Exception`` eats it)."""


def _alarm(signum: int, frame: Any) -> None:
    raise _Timeout


def _address_space() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmPeak:"):
            return int(line.split()[1]) * 1024
    return 0


def classify(case: dict[str, Any]) -> dict[str, Any]:
    """Play one case in this process; its outcome."""
    from aldm_gym.cli import main

    out, err = io.StringIO(), io.StringIO()
    signal.alarm(CASE_TIMEOUT)
    try:
        with (
            contextlib.redirect_stdout(out),
            contextlib.redirect_stderr(err),
            warnings.catch_warnings(),
        ):
            warnings.simplefilter("ignore")
            try:
                code = main(case["argv"])
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 2
    except _Timeout:
        return {"outcome": "defect", "why": f"more than {CASE_TIMEOUT} s"}
    except MemoryError:
        return {"outcome": "defect", "why": f"more than {MEMORY_CAP >> 20} MiB"}
    except Exception as exc:  # a traceback: the finding this harness is for
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return {
            "outcome": "defect",
            "why": f"{type(exc).__name__}: {str(exc)[:300]} "
            f"(at {Path(where.filename).name}:{where.lineno})",
        }
    finally:
        signal.alarm(0)
    printed = out.getvalue()
    errors = [line for line in err.getvalue().splitlines() if "error:" in line]
    if code == 2:
        if len(errors) != 1:
            return {
                "outcome": "defect",
                "why": f"exit 2 without one error line: {err.getvalue()[-300:]!r}",
            }
        if not any(name in errors[0] for name in case["names"]):
            return {"outcome": "defect", "why": f"the error names no file: {errors[0][:300]}"}
        return {"outcome": "refused", "why": errors[0][:300]}
    if code in (0, 1):
        bad = _NAN.search(printed)
        if bad:
            line = next(x for x in printed.splitlines() if bad.group(0) in x)
            return {"outcome": "defect", "why": f"a NaN printed: {line[:200]}"}
        return {
            "outcome": "played",
            "why": printed.strip().splitlines()[0][:200] if printed.strip() else "",
        }
    return {"outcome": "defect", "why": f"exit {code}: {err.getvalue()[-300:]!r}"}


def _child(cases_file: str) -> None:
    """The child: play every case of ``cases_file``, one JSON line each on stdout."""
    signal.signal(signal.SIGALRM, _alarm)
    cases = json.loads(Path(cases_file).read_text())
    capped = False
    for case in cases:
        print(f"CASE {case['label']}", file=sys.stderr, flush=True)
        result = classify(case)
        print(json.dumps({"label": case["label"], **result}), flush=True)
        if not capped:  # after the first case every module is imported and warm
            limit = _address_space() + MEMORY_CAP
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
            capped = True


def run_cases(
    cases: Sequence[dict[str, Any]], folder: Path, timeout: float
) -> list[dict[str, Any]]:
    """Play ``cases`` in a child process; one outcome per case, in order. A crash of the
    child is a ``defect`` outcome of the case it died in (the rest are not played)."""
    cases_file = folder / "cases.json"
    cases_file.write_text(json.dumps(list(cases)))
    argv = [sys.executable, "-m", "tests.fuzz.harness", str(cases_file)]
    root = Path(__file__).resolve().parents[2]
    try:
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, cwd=root)
        stdout, stderr, code = proc.stdout, proc.stderr, proc.returncode
    except subprocess.TimeoutExpired as exc:
        stdout = exc.stdout.decode() if isinstance(exc.stdout, bytes) else exc.stdout or ""
        stderr = exc.stderr.decode() if isinstance(exc.stderr, bytes) else exc.stderr or ""
        code = f"timeout after {timeout} s"
    results = [json.loads(line) for line in stdout.splitlines() if line.startswith("{")]
    if len(results) < len(cases):
        last = [line[5:] for line in stderr.splitlines() if line.startswith("CASE ")]
        results.append(
            {
                "label": last[-1] if last else cases[0]["label"],
                "outcome": "defect",
                "why": f"the process died ({code}): {stderr[-600:]}",
            }
        )
    return results


if __name__ == "__main__":
    _child(sys.argv[1])
