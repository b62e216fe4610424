"""Result tables written as CSV (for machines) and Markdown (for people), atomically.

The one table writer of the package, its scripts and its benchmarks.
"""

from __future__ import annotations

import csv
import io
import math
import os
import statistics
from collections.abc import Mapping, Sequence

from nriqa.io.atomic import write_text_atomic


def _cell(value, digits: int) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        # NaN marks "not defined here" (a predictor without a map has no pixel PCC): a dash for
        # people; the CSV keeps NaN for machines.
        return "–" if math.isnan(value) else f"{value:.{digits}f}"
    return "" if value is None else str(value)


def write_csv(path: str | os.PathLike, rows: list[dict], columns: list[str] | None = None) -> None:
    """Write ``rows`` (dicts; missing keys left empty) with a header of ``columns`` (default: the first row's keys)."""
    if columns is None:
        columns = list(rows[0]) if rows else []
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(path, buf.getvalue())


def read_csv(path: str | os.PathLike, need: set[str], what: str) -> list[dict]:
    """The rows of the CSV file ``path`` as dicts of strings, checked to hold the columns ``need``.

    Raises:
        ValueError: the file cannot be read, or is empty or lacks a column; the one-line message names
            the file and ``what`` it should be (e.g. "an nriqa-evaluate images.csv").
    """
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except OSError as exc:
        raise ValueError(f"cannot read {path} ({exc.strerror}); give {what}") from None
    if not rows or not need <= set(rows[0]):
        raise ValueError(f"{path} is not {what} (need columns {', '.join(sorted(need))})")
    return rows


def markdown_table(rows: Sequence[Mapping | Sequence], columns: list[str], digits: int = 3) -> str:
    """A GitHub Markdown table of ``rows`` under the header ``columns``, ending in a newline.

    A row is a mapping (its values at ``columns``; missing ones left empty) or a sequence of cells
    in column order. Floats get ``digits`` decimals (NaN as "–"), booleans yes/no, strings stay.
    """
    lines = ["| " + " | ".join(columns) + " |", "|" + "|".join("---" for _ in columns) + "|"]
    for row in rows:
        cells = [row.get(c) for c in columns] if isinstance(row, Mapping) else list(row)
        lines.append("| " + " | ".join(_cell(v, digits) for v in cells) + " |")
    return "\n".join(lines) + "\n"


def mean_std_row(rows: list[dict], columns: list[str], label_column: str, digits: int = 3) -> dict:
    """A row of ``mean ± std`` (sample std; 0 for one row) strings over ``columns`` of ``rows``."""
    out = {label_column: "mean ± std"}
    for c in columns:
        values = [float(r[c]) for r in rows if r.get(c) is not None]
        if values:
            std = statistics.stdev(values) if len(values) > 1 else 0.0
            out[c] = f"{statistics.fmean(values):.{digits}f} ± {std:.{digits}f}"
    return out
