"""What every command shares: exit statuses, and usage errors on one line."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import NoReturn

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2


class OneLineParser(argparse.ArgumentParser):
    """Usage errors as one line on stderr and exit code 2, like every other bad input."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"error: {message} (see --help)\n")


def whole_number(lo: int, hi: int):
    """An argparse ``type``: a whole number in [``lo``, ``hi``], else a one-line refusal."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text[:20]!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"expected {lo} to {hi}, got {value}")
        return value

    return parse


def place_refusal(option: str, place: Path, *, file: bool = False, existing: bool = False) -> str | None:
    """The one-line refusal of an output place given to ``option``, or None if it can be
    written: a ``file`` in an existing folder (where no device, FIFO or socket is in its
    place), else a folder (one that must exist when
    ``existing``, else created if need be). Checked before a command does any work."""
    from baslip.files.atomic import NotAFileToReplace, check_replaceable
    from baslip.files.lock import unwritable  # not at import: `baslip --help` stays light

    if file:
        try:
            check_replaceable(place)  # a device or a FIFO is never replaced by a file
        except NotAFileToReplace as err:
            return f"error: {option} {err}"
        wrong, what, folder = place.is_dir() or not place.parent.is_dir(), "not a file in an existing folder", place.parent
    else:
        wrong = not place.is_dir() if existing else place.exists() and not place.is_dir()
        what, folder = "not a folder", place
    reason = what if wrong else unwritable(folder)
    return None if reason is None else f"error: {option} {place}: {reason}"
