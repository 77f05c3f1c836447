"""Writing results: plain JSON and CSV, each set of files written whole or not at all.

A full disk (or quota) while writing is :class:`NoSpaceLeft`, naming the file; the files
written whole before are left as they were, and only a special file in the way (a
device, a FIFO) is refused rather than replaced (:class:`NotAFileToReplace`).
"""

from __future__ import annotations

import contextlib
import csv
import errno
import io
import json
import math
import os
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path

from baslip.errors import InputError, RunError
from baslip.gait.fixedpoint import FixedPointResult
from baslip.problem.text import file_kind

RESULT_FILES = ("result.json", "multipliers.csv")


#: The errors of a full disk, or of a full quota.
FULL = (errno.ENOSPC, errno.EDQUOT)


class NoSpaceLeft(RunError):
    """The disk (or the quota) filled while writing a file; the message names the file."""


class NotAFileToReplace(InputError):
    """An output path names a device, a FIFO, a socket or a folder: it is never replaced."""


@contextlib.contextmanager
def writing(path: Path) -> Iterator[None]:
    """Turn a full disk while writing ``path`` into :class:`NoSpaceLeft` naming it."""
    try:
        yield
    except OSError as err:
        if err.errno in FULL:
            raise NoSpaceLeft(f"no space left on device: {path}") from None
        raise


def check_replaceable(path: Path) -> None:
    """Raise :class:`NotAFileToReplace` if ``path`` exists and is no regular file (after
    links): writing a file there would replace a device node or a FIFO."""
    try:
        kind = file_kind(os.stat(path).st_mode)
    except OSError:  # nothing there (or nothing reachable): a file is created
        return
    if kind is not None:
        raise NotAFileToReplace("", f"{path} is {kind}, not a file; baslip writes no file in its place")


def write_files_atomically(files: Mapping[Path, str | bytes]) -> None:
    """Write every file (text, or bytes such as a PNG) to a temporary sibling first, then
    rename them all into place.

    Readers never see a half-written file, and a failure while writing (a full disk:
    :class:`NoSpaceLeft`) leaves the old files (if any) untouched. A path that is a
    device, a FIFO or a folder is refused before anything is written
    (:class:`NotAFileToReplace`). Files get the usual permissions (0666 less the umask).
    """
    for path in files:
        check_replaceable(path)
    umask = os.umask(0)
    os.umask(umask)
    temporaries: dict[Path, str] = {}
    try:
        for path, text in files.items():
            with writing(path):
                path.parent.mkdir(parents=True, exist_ok=True)
                fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
                temporaries[path] = tmp
                with os.fdopen(fd, "wb" if isinstance(text, bytes) else "w") as handle:
                    handle.write(text)
            os.chmod(tmp, 0o666 & ~umask)
        for path, tmp in temporaries.items():
            os.replace(tmp, path)
    finally:
        for tmp in temporaries.values():
            if os.path.exists(tmp):
                os.unlink(tmp)


def finite_or_none(value):
    """JSON has no NaN or infinity: map them to null, recursively."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list):
        return [finite_or_none(v) for v in value]
    return value


def json_text(record) -> str:
    """A record as strict JSON (non-finite numbers become null), indented, one trailing newline."""
    return json.dumps(finite_or_none(record), indent=2, allow_nan=False) + "\n"


def multipliers_csv(result: FixedPointResult) -> str:
    """One row per eigenvalue of dr/dX: re, im, abs, label ('' if non-trivial)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["re", "im", "abs", "label"])
    for m in result.stability.multipliers if result.stability else ():
        writer.writerow([repr(m.value.real), repr(m.value.imag), repr(abs(m.value)), m.label or ""])
    return buffer.getvalue()


def write_result(result: FixedPointResult, out_dir: Path, provenance: dict | None = None) -> list[Path]:
    """Write ``result.json`` (with ``provenance``, if given, as its last key) and
    ``multipliers.csv`` into ``out_dir``; return their paths."""
    record = result.to_json_dict()
    if provenance is not None:
        record["provenance"] = provenance
    files = {
        out_dir / "result.json": json_text(record),
        out_dir / "multipliers.csv": multipliers_csv(result),
    }
    write_files_atomically(files)
    return list(files)
