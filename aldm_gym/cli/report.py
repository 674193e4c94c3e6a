"""Command-line reports: plain-text tables and CSV files."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def format_table(
    rows: Sequence[dict[str, Any]],
    columns: Sequence[str],
    headers: dict[str, str] | None = None,
) -> str:
    """Right-aligned text table of ``rows`` (dicts) in ``columns`` order; floats to 3
    decimals; ``headers`` renames columns in the header line."""

    def fmt(v: Any) -> str:
        return f"{v:.3f}" if isinstance(v, float) else str(v)

    names = [(headers or {}).get(c, c) for c in columns]
    cells = [[fmt(r[c]) for c in columns] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(names)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(names, widths, strict=True))]
    lines += ["  ".join(v.rjust(w) for v, w in zip(row, widths, strict=True)) for row in cells]
    return "\n".join(lines)


def write_csv(path: Path, rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> None:
    """Write ``rows`` (dicts) as CSV with a header of ``columns``."""
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(columns))
        writer.writeheader()
        writer.writerows(rows)
