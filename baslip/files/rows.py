"""Rows of baslip's CSV files read back: numbers as floats, ``true``/``false`` as bools.

Status, reason and empty cells stay strings.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import IO


def read_points(path: Path) -> list[dict]:
    """Rows of a points.csv as dicts of floats (status and empty cells kept as strings)."""
    with open(path, encoding="utf-8", newline="") as handle:
        return points_from(handle)


def points_from(handle: IO[str]) -> list[dict]:
    """Rows of CSV text as dicts of floats (status and empty cells kept as strings)."""
    return [{k: _number_or_text(v) for k, v in row.items()} for row in csv.DictReader(handle)]


def _number_or_text(text: str):
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)
    except ValueError:
        return text
