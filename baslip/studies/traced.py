"""What branch runs and curve runs share: traced branches, their progress and their rows.

A ``continuation:`` problem traces branches (:mod:`baslip.studies.branch`) and may then
follow curves from their special points (:mod:`baslip.studies.curve`); both write points
with the same columns and show progress the same way.
"""

from __future__ import annotations

import csv
import io
import math
import sys
import time
from dataclasses import dataclass

from baslip.analysis.gaitsystem import FixedPointSystem, NearestGuessSystem
from baslip.diagnostics import IN_PLACE, logger
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import PD
from baslip.numerics.continuation import Branch
from baslip.studies.runner import format_value

_log = logger(__name__)


@dataclass(frozen=True)
class TracedBranch:
    """One traced branch: its fixed-point system, points, and where it came from."""

    number: int  # 0 for the branch from the problem's start, then in order of switching
    system: FixedPointSystem | NearestGuessSystem
    branch: Branch
    origin: dict | None = None  # the special point it was switched from

    @property
    def strides(self) -> int:
        return self.system.spec.strides


def progress_lines(describe, quiet: bool):
    """A progress callback (n, point) that shows ``describe(n, point)``: rewritten in
    place on a terminal, a plain line every 10 s in a log file, nothing when quiet."""
    started, shown = time.perf_counter(), [-math.inf]

    def progress(n, point):
        if quiet:
            return
        elapsed = time.perf_counter() - started
        if sys.stderr.isatty():
            _log.info(describe(n, point), extra=IN_PLACE)
        elif elapsed - shown[0] >= 10.0:
            shown[0] = elapsed
            _log.info(describe(n, point))

    return progress


def named_stop(system, branch) -> str:
    """The stop reason, with the grazing it comes from named when the last point grazes."""
    if branch.stop_reason in ("end of range", "maximum number of points") or not branch.points:
        return branch.stop_reason
    grazing = system.grazing(branch.points[-1].v)
    return f"{grazing}; then {branch.stop_reason}" if grazing else branch.stop_reason


def point_record(row: dict, controls: tuple[str, ...] = PD.controls.names) -> dict:
    """A row's apex, control (entries ``controls``, the hip law's) and multipliers, as
    result.json gives them for a point."""
    return {"apex": {n: row[n] for n in APEX.names}, "control": {n: row[n] for n in controls},
            "multipliers": [[row[f"mult{i}_re"], row[f"mult{i}_im"]] for i in range(1, 5)]}


def points_csv(rows: list[dict], leading: list[str], trailing: list[str],
               controls: tuple[str, ...] = PD.controls.names) -> str:
    """CSV of points: the ``leading`` columns, the apex, control (entries ``controls``, the
    hip law's) and energy (those not already leading, so a parameter that is one of them
    is not repeated), the four multipliers, then the ``trailing`` columns."""
    columns = list(leading)
    columns += [n for n in (*APEX.names, *controls, "energy") if n not in leading]
    columns += [f"mult{i}_{part}" for i in range(1, 5) for part in ("re", "im")]
    columns += trailing
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, columns, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: format_value(v) for k, v in row.items() if k in columns})
    return buffer.getvalue()
