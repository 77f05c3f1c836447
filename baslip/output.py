"""Writing results: plain JSON and CSV, each file written whole or not at all."""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile
from pathlib import Path

from .fixedpoint import FixedPointResult


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file and a rename, so readers never see
    a half-written file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def multipliers_csv(result: FixedPointResult) -> str:
    """One row per eigenvalue of dr/dX: re, im, abs, label ('' if non-trivial)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["re", "im", "abs", "label"])
    for m in result.stability.multipliers if result.stability else ():
        writer.writerow([repr(m.value.real), repr(m.value.imag), repr(abs(m.value)), m.label or ""])
    return buffer.getvalue()


def write_result(result: FixedPointResult, out_dir: Path) -> list[Path]:
    """Write ``result.json`` and ``multipliers.csv`` into ``out_dir``; return their paths."""
    files = {
        out_dir / "result.json": json.dumps(result.to_json_dict(), indent=2) + "\n",
        out_dir / "multipliers.csv": multipliers_csv(result),
    }
    for path, text in files.items():
        write_atomic(path, text)
    return list(files)
