"""What every study kind shares: its resumable table, its run counts and its status counts."""

from __future__ import annotations

from pathlib import Path

from baslip.diagnostics import logger
from baslip.errors import RunError
from baslip.status import Status
from baslip.studies.runner import ResumableCsv, RunReport

_log = logger(__name__)


class StudyFailed(RunError):
    """A study could not start: e.g. its starting fixed point did not converge."""


def study_table(path: Path, columns: list[str], keys: list[str], quiet: bool) -> ResumableCsv:
    """The study's resumable CSV, saying what was repaired in it."""
    table = ResumableCsv(path, columns, keys)
    if not quiet:
        for note in table.notes:
            _log.warning(f"note: {note}")
    return table


def run_info(report: RunReport) -> dict:
    """The run's counts for result.json, with ``worker_failure`` when a worker process
    ended before finishing its tasks."""
    failure = {"worker_failure": report.worker_failure} if report.worker_failure else {}
    return {
        "tasks": report.total,
        "done_before_this_run": report.skipped,
        "done_in_this_run": report.ran,
        "complete": report.complete,
        **failure,
    }


def status_counts(rows: list[dict]) -> dict:
    """How many points were solved, not verified, failed, and stable."""
    statuses = [r["status"] for r in rows]
    return {
        "points": len(rows),
        "solved": statuses.count(Status.CONVERGED),
        "not_verified": statuses.count(Status.NOT_VERIFIED),
        "failed": statuses.count(Status.FAILED),
        "stable": sum(1 for r in rows if r["status"] == Status.CONVERGED and r["stable"] is True),
    }
