"""Run a study of a problem file: claim its folder, dispatch to its kind, record the result.

Each kind of study (sweep, random, basin, adaptive, optimal, controllers, atlas, families) lives in its own
module, with its tasks, its worker and its run together; :data:`KINDS` maps the class of
a ``study:`` section to it. A study writes into its folder ``results/<name>/``:

* its tables (``points.csv``, ``basin.csv`` and ``trajectories.csv``, ``strides.csv`` or
  ``controllers.csv``): one row per finished task, appended as it finishes;
* ``result.json``: counts, wall time and the study's own numbers;
* PNG figures.

Rerunning a finished study does no new solves; an interrupted one resumes, giving the
same answers as an uninterrupted run. The folder is held by one run at a time
(:mod:`baslip.files.lock`). ``result.json`` is written first, with ``complete: false`` and the
``provenance`` of the run; a rerun whose problem differs from the one recorded there is
refused (:class:`StaleFolder`) unless it is asked to start afresh, or unless the kind says
that the new problem only adds tasks to the recorded one (a controllers study given more
re-solved starts): then the rows stay and the run computes the added tasks.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from baslip.engine.codegen import recording_code
from baslip.errors import InputError, ProblemKindError
from baslip.files.atomic import json_text, write_files_atomically
from baslip.files.provenance import changed_entries, provenance
from baslip.files.rows import regular_text
from baslip.files.runs import clear_run, hold_for
from baslip.problem.reader import Problem
from baslip.problem.study import Adaptive, Atlas, Basin, Controllers, Families, Optimal, RandomSample, Sweep
from baslip.studies.adaptive import run_adaptive_study
from baslip.studies.atlas import run_atlas
from baslip.studies.basin import check_basin, run_basin
from baslip.studies.common import StudyFailed
from baslip.studies.controllers import adds_starts, run_controllers
from baslip.studies.families import run_families
from baslip.studies.optimal import run_optimal
from baslip.studies.processes import WorkerDied
from baslip.studies.runner import LANES, Workers
from baslip.studies.sources import StudyInputError
from baslip.studies.sweep import check_random, run_random, run_sweep

__all__ = ["KINDS", "StaleFolder", "StudyFailed", "StudyInputError", "StudyKind", "check_study_inputs", "outcome",
           "run_study"]


class StaleFolder(InputError):
    """The output folder holds results of another problem (or of unknown origin)."""


@dataclass(frozen=True)
class StudyKind:
    """How one kind of study runs: its function, its check of what it reads, its files.

    ``run(problem, study, out_dir, sources, quiet, lanes, workers)`` returns the kind's
    part of ``result.json``; ``check(problem, study, sources)`` raises an
    :class:`~baslip.errors.InputError` before anything runs; ``data_files`` are the
    tables it writes (``--fresh`` removes them); ``grows(old, new)`` tells whether a
    resolved study section ``new`` keeps every task (and row) of ``old`` and only adds
    tasks, so that a folder of ``old`` may be resumed under ``new``.
    """

    run: Callable[..., dict]
    data_files: tuple[str, ...]
    check: Callable[..., None] | None = None
    grows: Callable[[dict, dict], bool] | None = None


#: The tables of an atlas, and of a families study (an atlas of one cell).
ATLAS_FILES = ("cells.csv", "atlas.csv", "atlas_boundary.csv", "atlas_best.csv")
#: Every kind of study, by the class of its ``study:`` section.
KINDS: dict[type, StudyKind] = {
    Sweep: StudyKind(run_sweep, ("points.csv",)),
    RandomSample: StudyKind(run_random, ("points.csv",), check_random),
    Basin: StudyKind(run_basin, ("basin.csv", "trajectories.csv"), check_basin),
    Adaptive: StudyKind(run_adaptive_study, ("strides.csv",)),
    Optimal: StudyKind(run_optimal, ("points.csv",)),
    Controllers: StudyKind(run_controllers, ("controllers.csv",), grows=adds_starts),
    Atlas: StudyKind(run_atlas, ATLAS_FILES),
    Families: StudyKind(run_families, ATLAS_FILES),
}
#: Files any study writes besides its figures; ``--fresh`` removes them before starting.
DATA_FILES = tuple(sorted({name for kind in KINDS.values() for name in kind.data_files}))


def check_study_inputs(problem: Problem, sources: Path) -> None:
    """Raise :class:`~baslip.studies.sources.StudyInputError` if a study it depends on (in
    the folder ``sources``) has not been run (to the end), is being run, cannot be read,
    or gives points this problem would refuse."""
    if problem.study is None:
        return
    kind = KINDS[type(problem.study)]
    if kind.check is not None:
        kind.check(problem, problem.study, sources)


def run_study(problem: Problem, out_dir: Path, quiet: bool = False, fresh: bool = False,
              jobs: int | None = None, scheduler: str | None = None, lanes: int | None = None,
              sources: Path | None = None, kept: bool = True) -> dict:
    """Run (or resume) the study of ``problem``; return its summary (also in result.json).

    The runs a study reads (its source, region or boundary) are looked up in ``sources``,
    by default the folder that holds ``out_dir``.

    ``fresh`` discards what the folder holds first; without it, results of another
    problem there raise :class:`StaleFolder`. ``lanes`` splits a new run's tasks into
    that many warm-started lanes (default :data:`~baslip.studies.runner.LANES`); a resumed
    run keeps its recorded count, and asking for another raises :class:`StaleFolder`.
    Raises :class:`baslip.files.lock.FolderBusy` if another process is writing into ``out_dir``,
    and :class:`~baslip.studies.processes.WorkerDied` (a ``RunError``) if a worker process
    ended before finishing its tasks; what was done is written first, for a rerun to resume.
    ``kept=False`` says that ``out_dir`` is a temporary folder, removed after the run: such
    a failure then says that nothing was kept.
    """
    study = problem.study
    if study is None:
        raise ProblemKindError("study", f"problem {problem.name!r} holds no study")
    with hold_for(problem, out_dir, fresh), recording_code() as code:
        record, earlier = _claim(problem, out_dir, fresh, lanes)
        start = time.perf_counter()
        summary = KINDS[type(study)].run(problem, study, out_dir, sources or out_dir.parent, quiet,
                                         record["lanes"], Workers(jobs, scheduler))
        record = _what_ran(record, earlier, code)
        summary = {"name": problem.name, "kind": study.kind, **summary,
                   "wall_time_s": time.perf_counter() - start, "provenance": record}
        write_files_atomically({out_dir / "result.json": json_text(summary)})
    if "worker_failure" in summary:  # not a result: the run failed, though what it did is kept
        done = summary["done_before_this_run"] + summary["done_in_this_run"]
        fate = "kept, and a rerun resumes from them"
        if not kept:
            fate = "not kept: the run had no `out` folder, so nothing was written (give one to keep them for a rerun)"
        raise WorkerDied(f"{summary['worker_failure']}; {done} of {summary['tasks']} tasks were done, {fate}")
    return summary


def _what_ran(record: dict, earlier: dict | None, code: dict[str, str]) -> dict:
    """The run's provenance ``record`` with the code its libraries ran on (in this process
    and in its workers), and, for a resumed run of the same problem (``earlier``: the
    folder's result.json as it was), the earlier run's versions and code where they
    differ from this one's, ahead of the ``earlier_runs`` that :func:`_claim` carried over."""
    record = {**record, "code": dict(sorted(code.items()))}
    if earlier is None:
        return record
    before = earlier["provenance"]
    extended = before.get("problem_hash") != record["problem_hash"]  # already listed by _claim
    # A run stopped before its end never recorded its code (its claim's is empty): null
    # says "not known", where {} would claim that it loaded nothing.
    code_before = before.get("code") or None
    if not extended and (before.get("versions") != record["versions"] or code_before != record["code"]):
        record["earlier_runs"] = [{"versions": before.get("versions"), "code": code_before},
                                  *record.get("earlier_runs", [])]
    return record


def _carried_runs(earlier: dict, record: dict) -> list[dict]:
    """The ``earlier_runs`` that a resumed run's provenance ``record`` carries over from
    the folder's result.json ``earlier``, led by the run it held where this run extends
    that one (its versions, code, problem hash, study section and wall time)."""
    before = earlier["provenance"]
    runs = list(before.get("earlier_runs", []))
    if before.get("problem_hash") != record["problem_hash"]:
        runs.insert(0, {"versions": before.get("versions"), "code": before.get("code"),
                        "problem_hash": before.get("problem_hash"), "study": before.get("problem", {}).get("study"),
                        "wall_time_s": earlier.get("wall_time_s")})
    return runs


def _claim(problem: Problem, out_dir: Path, fresh: bool, lanes: int | None = None) -> tuple[dict, dict | None]:
    """Check that ``out_dir`` holds nothing but earlier results of this same problem (or of
    one that it extends, :func:`_extends`), run in the same number of lanes (or clear it
    if ``fresh``); record this run's provenance in result.json (its ``code`` is empty
    until the run has loaded its libraries). Return the record and, for a resumed run,
    the folder's result.json as it was."""
    record = {**provenance(problem, {}), "lanes": lanes or LANES}
    earlier = None
    data = [out_dir / name for name in DATA_FILES if (out_dir / name).exists()]
    recorded = _recorded(out_dir)
    old = recorded.get("provenance") if isinstance(recorded.get("provenance"), dict) else None
    if fresh:
        clear_run(out_dir)
    elif data:
        if old is None:
            raise StaleFolder("", f"{out_dir} holds results with no provenance record (from an older baslip?); "
                              "rerun with --fresh to discard them, or choose another --out")
        if old.get("problem_hash") != record["problem_hash"] and not _extends(problem, old, record):
            changed = _changed(old.get("problem", {}), record["problem"])
            raise StaleFolder("", f"{out_dir} holds results of a different problem (changed: {', '.join(changed[:4]) or 'unknown'}); "
                              "rerun with --fresh to discard them, or choose another --out")
        if lanes is not None and lanes != old.get("lanes", LANES):
            raise StaleFolder("", f"{out_dir} holds a run in {old.get('lanes', LANES)} lanes, not {lanes}; rerun with "
                              "--fresh to start again in the new count, or leave out --lanes to resume")
        record["lanes"] = old.get("lanes", LANES)
        earlier = recorded
        if carried := _carried_runs(earlier, record):  # kept if this run is killed
            record["earlier_runs"] = carried
    assert problem.study is not None
    write_files_atomically({out_dir / "result.json": json_text(
        {"name": problem.name, "kind": problem.study.kind, "complete": False, "provenance": record})})
    return record, earlier


def _extends(problem: Problem, old: dict, record: dict) -> bool:
    """Whether this run's problem (its provenance ``record``) only adds tasks to the
    recorded run ``old``: they differ in the study section alone, and its kind says so."""
    grows = KINDS[type(problem.study)].grows
    before, now = old.get("problem", {}), record["problem"]
    return (grows is not None and all(n.startswith("study.") for n in _changed(before, now))
            and isinstance(before.get("study"), dict) and grows(before["study"], now["study"]))


def _changed(old: dict, new: dict) -> list[str]:
    """Dotted names of the entries that differ between two resolved problems, leaving out
    those that change no number (the problem hash leaves them out too)."""
    return [n for n in changed_entries(old, new) if n not in ("name", "solver.print_level")]


def _recorded(out_dir: Path) -> dict:
    """The folder's result.json as it is ({} if it is missing or unreadable)."""
    try:
        record = json.loads(regular_text(out_dir / "result.json"))
    except (OSError, ValueError):
        return {}
    return record if isinstance(record, dict) else {}


def outcome(summary: dict) -> str | None:
    """Why a study's run is not a success (None if it is): it stopped short, or it
    solved nothing at all."""
    if not summary.get("complete", True):
        return f"stopped short: {summary['done_before_this_run'] + summary['done_in_this_run']} of {summary['tasks']} tasks done; rerun to resume"
    if summary["kind"] in ("sweep", "random", "optimal") and summary["solved"] == 0:
        return f"no fixed point was found at any of the {summary['points']} points"
    if summary["kind"] == "basin" and summary["stable_points"] == 0:
        return f"the source study {summary['source']!r} has no stable fixed point to simulate"
    if summary["kind"] == "controllers" and summary["done_before_this_run"] + summary["done_in_this_run"] == 0:
        return "no controller run was made"
    if summary["kind"] == "atlas" and summary.get("charts", 0) == 0:
        return "no chart was made: no seed of any cell solved"
    if summary["kind"] == "adaptive" and summary["adaptive_strides"] == 0:
        return f"no adaptive stride was taken: {summary['adaptive_failure']}"
    return None


