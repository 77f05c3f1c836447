"""Files that baslip wrote, read back: CSV rows (numbers as floats, ``true``/``false`` as
bools; status, reason and empty cells as strings) and small text files.

Each is read only if it is a regular file: a directory, a FIFO (which would block the
read forever) or a device in its place is refused with a ValueError naming what it is.
A CSV file that is damaged (not UTF-8, without its header, or with a damaged row, see
:func:`row_damage`: one whose cell count differs from its header's, or a converged
gait's whose apex state is not a finite number, as after a change by hand) is refused
with :class:`DamagedTable`, naming the file and the line.
"""

from __future__ import annotations

import csv
import itertools
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import IO

from baslip.errors import InputError
from baslip.model.dynamics import APEX
from baslip.problem.text import file_kind
from baslip.status import Status


class DamagedTable(InputError):
    """A CSV file of a run that cannot be read back as baslip wrote it: ``where`` names
    the file, ``why`` says what is wrong (with the line)."""

    def __init__(self, where: str, why: str):
        super().__init__("", f"{where}: {why}")
        self.where, self.why = where, why


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


def ends_a_line(path: Path) -> bool:
    """Whether the non-empty file ``path`` ends with a newline (else its last line was
    cut short, by a kill or a full disk)."""
    with open(path, "rb") as handle:
        handle.seek(-1, os.SEEK_END)
        return handle.read(1) == b"\n"


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of the CSV file ``path`` as dicts of strings, after checking that it is a
    regular file and that it is whole (:class:`DamagedTable` naming it if not)."""
    check_regular(path)
    with open(path, encoding="utf-8", newline="") as handle:
        return _whole_rows(handle, str(path))


def read_points(path: Path) -> list[dict]:
    """Rows of a points.csv as dicts of floats (status and empty cells kept as strings)."""
    return [_converted(row) for row in read_rows(path)]


def points_from(handle: IO[str], where: str) -> list[dict]:
    """Rows of CSV text as dicts of floats (status and empty cells kept as strings);
    ``where`` names the file in the message of :class:`DamagedTable`."""
    return [_converted(row) for row in _whole_rows(handle, where)]


def check_rows(handle: IO[str], where: str) -> None:
    """Raise :class:`DamagedTable` naming ``where`` if the CSV text in ``handle`` is
    damaged (see :func:`row_damage`)."""
    _whole_rows(handle, where)


def check_header(path: Path) -> None:
    """Raise :class:`DamagedTable` naming ``path`` unless it is a regular file that starts
    with a header (reading only its first line: cheap, for a folder's every table)."""
    try:
        check_regular(path)
    except ValueError as err:
        raise DamagedTable(str(path), str(err)) from None
    with open(path, encoding="utf-8", newline="") as handle:
        _whole_rows(itertools.islice(handle, 1), str(path))


def _whole_rows(handle: Iterable[str], where: str) -> list[dict[str, str]]:
    """The rows under the header of the CSV lines ``handle``, as dicts of strings, all
    checked (:class:`DamagedTable` naming ``where`` and the line if one is damaged)."""
    try:
        lines = csv.reader(handle)
        header = next(lines, None)
        if header is None:
            return []
        if any(_number(cell) or not cell for cell in header):
            raise DamagedTable(where, "its first line is no header (it has numbers or empty cells)")
        rows = []
        for number, cells in enumerate(lines, start=2):
            if not cells:  # a blank line, skipped as csv.DictReader does
                continue
            damage = row_damage(cells, header)
            if damage is not None:
                raise DamagedTable(where, f"line {number}: {damage}")
            rows.append(dict(zip(header, cells)))
        return rows
    except UnicodeDecodeError:
        raise DamagedTable(where, "it is not UTF-8 text") from None
    except csv.Error as err:
        raise DamagedTable(where, f"it is not CSV ({err})") from None


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
    return _number(text) and math.isfinite(float(text))


def _number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _converted(row: dict[str, str]) -> dict:
    return {k: _number_or_text(v) for k, v in row.items()}


def _number_or_text(text: str):
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)
    except ValueError:
        return text
