"""Files that baslip wrote, read back: CSV rows (numbers as floats, ``true``/``false`` as
bools; status, reason and empty cells as strings) and small text files.

Each is read only if it is a regular file: a directory, a FIFO (which would block the
read forever) or a device in its place is refused with a ValueError naming what it is,
as is a damaged CSV row (:func:`row_damage`): one whose cell count differs from its
header's, or a converged gait's whose apex state is not a finite number (a file changed
by hand).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import IO

from baslip.model.dynamics import APEX
from baslip.problem.text import file_kind
from baslip.status import Status

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
        damage = row_damage(cells, header)
        if damage is not None:
            raise ValueError(f"its line {number}: {damage}")
        rows.append(dict(zip(header, cells)))
    return rows


def row_damage(cells: Sequence[str], header: Sequence[str]) -> str | None:
    """Why the CSV row ``cells`` under ``header`` cannot be trusted, or None if it can.

    A row is damaged if its cell count differs from the header's (torn, or cells added),
    or if it is a converged gait's (``status`` is ``converged``) and a cell of its apex
    state (z, theta_h, ydot, theta_h_dot, where the header has them) is not a finite
    number: baslip never writes such a row, so the file was changed by hand.
    """
    if len(cells) != len(header):
        return f"it has {len(cells)} cells, its header {len(header)}"
    row = dict(zip(header, cells))
    if row.get("status") != Status.CONVERGED:
        return None
    for name in APEX.names:
        if name in row and not _finite_number(row[name]):
            return f"its {name} is {row[name][:20]!r}, not a finite number"
    return None


def _finite_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _converted(row: dict[str, str]) -> dict:
    return {k: _number_or_text(v) for k, v in row.items()}


def _number_or_text(text: str):
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)
    except ValueError:
        return text
