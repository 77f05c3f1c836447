"""What a results folder holds: one run, of one kind and one problem.

A folder holds the files of one run. A run of another kind (a sweep into a gait's folder)
or, for a gait or a continuation, of another problem is refused rather than mixed with
what is there; ``fresh`` clears the folder's run first. (A study of the same kind checks
its recorded problem itself, naming the entries that changed, and resumes an unchanged
one.)

The check is made again once the folder's lock is held (:func:`hold_for`): two runs
started at the same instant both pass the first check, made before either has written
anything, and the second to take the lock must then see the first's run.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from pathlib import Path

from baslip.errors import InputError
from baslip.files.lock import hold
from baslip.files.provenance import problem_hash
from baslip.files.rows import regular_text
from baslip.problem.reader import Problem

#: Every data file a run of any kind writes (figures aside); a fresh run removes them.
RUN_FILES = ("result.json", "multipliers.csv", "branch.csv", "curve.csv", "points.csv", "basin.csv",
             "trajectories.csv", "strides.csv", "controllers.csv", "cells.csv", "atlas.csv", "atlas_boundary.csv",
             "atlas_best.csv")


class FolderHoldsAnotherRun(InputError):
    """The output folder holds a run of another kind, or of another problem."""


def run_kind(problem: Problem) -> str:
    """``gait``, ``continuation``, or the study's kind (``sweep``, ``basin``, ...)."""
    if problem.study is not None:
        return problem.study.kind
    return "continuation" if problem.continuation is not None else "gait"


def recorded_run(folder: Path) -> tuple[str, str | None] | None:
    """(kind, problem hash) of the run whose ``result.json`` is in ``folder``, or None."""
    try:
        record = json.loads(regular_text(folder / "result.json"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict):
        return None
    kind = record.get("kind") or ("continuation" if "branches" in record else "gait")
    provenance = record.get("provenance")
    return str(kind), provenance.get("problem_hash") if isinstance(provenance, dict) else None


def check_folder(problem: Problem, folder: Path, fresh: bool) -> None:
    """Raise :class:`FolderHoldsAnotherRun` unless ``folder`` may take a run of ``problem``."""
    recorded = recorded_run(folder)
    if recorded is None or fresh:
        return
    kind, old_hash = recorded
    new = run_kind(problem)
    if kind != new:
        raise FolderHoldsAnotherRun("", f"output folder {folder} holds a {kind} run, not a {new} one; rerun with "
                                    "--fresh to replace it, or choose another --out")
    if new in ("gait", "continuation") and old_hash != problem_hash(problem):
        raise FolderHoldsAnotherRun("", f"output folder {folder} holds the {kind} of another problem; rerun with "
                                    "--fresh to replace it, or choose another --out")


@contextlib.contextmanager
def hold_for(problem: Problem, folder: Path, fresh: bool = False) -> Iterator[None]:
    """Hold ``folder`` for writing a run of ``problem`` (:func:`~baslip.files.lock.hold`),
    then check it (:func:`check_folder`): the lock first, so that the folder's kind is
    decided by whichever run holds it. Raises :class:`~baslip.files.lock.FolderBusy` or
    :class:`FolderHoldsAnotherRun`."""
    with hold(folder):
        check_folder(problem, folder, fresh)
        yield


def clear_run(folder: Path) -> None:
    """Remove the data files of the run in ``folder`` (and their saved solver states)."""
    for name in RUN_FILES:
        with contextlib.suppress(FileNotFoundError):
            (folder / name).unlink()
        for log in ("states", "charts"):  # saved solver states, an atlas's charts
            with contextlib.suppress(FileNotFoundError):
                (folder / f".{name}.{log}").unlink()
