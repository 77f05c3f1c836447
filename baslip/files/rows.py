"""Files that baslip wrote, read back: CSV rows (numbers as floats, ``true``/``false`` as
bools; status, reason and empty cells as strings) and small text files.

Each is read only if it is a regular file: a directory, a FIFO (which would block the
read forever) or a device in its place is refused with a ValueError naming what it is,
as is a CSV row whose cell count differs from its header's.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import IO

from baslip.problem.text import file_kind

def check_regular(path: Path) -> None:
    """Raise ValueError unless ``path`` is a regular file (after symbolic links); the
    message says what it is instead. A missing path raises FileNotFoundError."""
    kind = file_kind(os.stat(path).st_mode)
    if kind is not None:
        raise ValueError(f"it is {kind}, not a file")


def regular_text(path: Path) -> str:
    """The UTF-8 text of the regular file ``path`` (see :func:`check_regular`)."""
    check_regular(path)
    return Path(path).read_text(encoding="utf-8")


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of the CSV file ``path`` as dicts of strings, after checking that it is a
    regular file and that every row has as many cells as its header."""
    check_regular(path)
    with open(path, encoding="utf-8", newline="") as handle:
        return _whole_rows(csv.reader(handle))


def read_points(path: Path) -> list[dict]:
    """Rows of a points.csv as dicts of floats (status and empty cells kept as strings)."""
    return [_converted(row) for row in read_rows(path)]


def points_from(handle: IO[str]) -> list[dict]:
    """Rows of CSV text as dicts of floats (status and empty cells kept as strings)."""
    return [_converted(row) for row in _whole_rows(csv.reader(handle))]


def _whole_rows(lines) -> list[dict[str, str]]:
    header = next(lines, None)
    if header is None:
        return []
    rows = []
    for number, cells in enumerate(lines, start=2):
        if not cells:  # a blank line, skipped as csv.DictReader does
            continue
        if len(cells) != len(header):
            raise ValueError(f"its line {number} has {len(cells)} cells, its header {len(header)}")
        rows.append(dict(zip(header, cells)))
    return rows


def _converted(row: dict[str, str]) -> dict:
    return {k: _number_or_text(v) for k, v in row.items()}


def _number_or_text(text: str):
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)
    except ValueError:
        return text
