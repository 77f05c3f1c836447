"""The Python verbs: run whatever a problem holds, and get a result object back.

>>> import baslip
>>> gait = baslip.run("problems/downward.yaml")             # a verified gait
>>> grid = baslip.run("problems/grid_downward.yaml", out="runs/grid")   # a study, written
>>> grid.to_dataframe(), grid.plot(), grid.summary()

The command line (``baslip solve``) is a thin layer over :func:`run`: the same checks,
the same files, the same exit status for the same outcome.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

from baslip.diagnostics import logger, progress_hidden, show_on_stderr
from baslip.engine.arguments import shown, whole_number
from baslip.engine.codegen import recording_code
from baslip.errors import ArgumentError, InputError, ProblemKindError, RunError
from baslip.files.atomic import write_result
from baslip.files.lock import hold, unwritable
from baslip.files.provenance import provenance
from baslip.files.runs import check_folder, clear_run, hold_for
from baslip.gait.fixedpoint import FixedPointResult
from baslip.gait.from_problem import solve_problem, solver_for
from baslip.problem.model_file import ModelProblem, load_any_problem
from baslip.problem.reader import Problem, check_problem, load_problem
from baslip.problem.study import Families
from baslip.problem.text import path_argument
from baslip.results import RunResults, open_results, read_into_memory
from baslip.studies.modelruns import ModelRun, run_model_problem

_log = logger(__name__)


class OutputUnwritable(InputError):
    """The output folder cannot be created or written to."""


class NothingToSchedule(InputError):
    """A scheduler was asked for, but the problem holds no study to spread over it."""


def run(problem: Problem | ModelProblem | str | Path, out: str | Path | None = None, *, jobs: int | None = None,
        lanes: int | None = None, scheduler: str | None = None, fresh: bool = False, progress: bool = True,
        sources: str | Path | None = None) -> FixedPointResult | RunResults | ModelRun:
    """Run what ``problem`` holds: its gait, its study (of any kind), or its continuation.

    Parameters
    ----------
    problem : Problem, ModelProblem, str or Path
        A problem, or the path of a problem file; one of a described model
        (``model: file.py:Name``) runs as :func:`run_model` runs it.
    out : str or Path, optional
        The folder to write the run's files into: exactly those ``baslip solve --out``
        writes, resuming what is there. Without it nothing is written and nothing is
        resumed.
    jobs : int, optional
        Worker processes for a study, or for a continuation's curves (default one per
        core); answers do not depend on it.
    lanes : int, optional
        A new study's warm-started lanes (default 2); recorded, and the answers follow it.
    scheduler : str, optional
        A Dask scheduler's address, or ``"local"``, to run a study's lanes on.
    fresh : bool
        Discard what ``out`` holds first.
    progress : bool
        Show progress on stderr.
    sources : str or Path, optional
        The folder holding the runs a study reads (a basin study's source sweep, a random
        sample's region or boundary); by default the folder that holds ``out``, else
        ``results``.

    Returns
    -------
    FixedPointResult or RunResults
        The verified gait (or why there is none) for a gait problem; the study's or the
        continuation's results otherwise, with ``summary()``, ``to_dataframe()``,
        ``plot()`` and a short ``repr``.

    Raises
    ------
    InputError
        Bad input, checked before anything is solved or written: the problem, an option,
        a run it reads, or an output folder that is busy or holds another problem's run.
    RunError
        A run that could not start, e.g. a study or branch whose start did not converge,
        or a study whose worker process ended before finishing its tasks (what was done is
        kept in ``out``, for a rerun to resume; without ``out`` nothing is kept).
    """
    _check_options(out=out, jobs=jobs, lanes=lanes, scheduler=scheduler, fresh=fresh, progress=progress,
                   sources=sources)
    if not isinstance(problem, (Problem, ModelProblem)):
        problem = load_any_problem(path_argument(problem, "problem"))
    if isinstance(problem, ModelProblem):
        if scheduler is not None:
            raise ArgumentError("scheduler", f"{problem.name} is a described model's problem, which runs in this process")
        return run_model(problem, out, progress=progress, fresh=fresh)
    if progress:
        show_on_stderr()
    # A Problem built in Python is checked as a file would be (Problem(...) checks nothing).
    problem = check_problem(problem)
    folder = None if out is None else Path(path_argument(out, "out"))
    where = Path(path_argument(sources, "sources")) if sources is not None else (
        folder.parent if folder is not None else Path("results"))
    check_run(problem, folder, where, scheduler, fresh)
    if folder is None and problem.study is None and problem.continuation is None:
        return solve_problem(problem, progress=progress)  # a gait written nowhere needs no folder at all
    with progress_hidden(not progress), _place(folder, problem.name) as target:
        result = _run_into(problem, target, where, jobs=jobs, lanes=lanes, scheduler=scheduler, fresh=fresh,
                           quiet=not progress, kept=folder is not None)
        if folder is not None:
            return result
        return read_into_memory(target, where)


def run_model(problem: ModelProblem | str | Path, out: str | Path | None = None, *, progress: bool = True,
              fresh: bool = False) -> ModelRun:
    """Run a described model's problem: its gait, and the branch or atlas it asks for.

    Parameters
    ----------
    problem : ModelProblem, str or Path
        A problem (:func:`baslip.problem.model_file.parse_model_problem`), or the path of
        a problem file whose ``model`` names a description (``file.py:Name``, ``slip``).
    out : str or Path, optional
        The folder to write ``result.json`` and the branch's or atlas's CSV and figure
        into, all at once; nothing is written without it.
    progress : bool
        Show progress on stderr.
    fresh : bool
        Discard what ``out`` holds first.

    Returns
    -------
    ModelRun
        The verified gait, the branch or chart centres (each with its verification), and
        ``summary()``.

    Raises
    ------
    InputError
        A bad problem (naming its key, ``model.<part>`` for a description that cannot run)
        or an output folder that cannot be written.
    RunError
        No verified gait was found (:class:`baslip.gait.modelsolver.NoFixedPoint`).
    """
    if not isinstance(problem, ModelProblem):
        loaded = load_any_problem(path_argument(problem, "problem"))
        if not isinstance(loaded, ModelProblem):
            raise ProblemKindError("problem", f"{loaded.name} is a BA-SLIP problem: run it with baslip.run")
        problem = loaded
    if progress:
        show_on_stderr()
    folder = None if out is None else Path(path_argument(out, "out"))
    existed = folder is not None and folder.exists()
    if folder is not None:
        _check_writable(folder)
        if fresh:
            with hold(folder):
                clear_run(folder)
    try:
        with progress_hidden(not progress):
            return run_model_problem(problem, folder)
    except RunError:
        if folder is not None and not existed and not any(folder.iterdir()):
            folder.rmdir()  # made only to check it could be written: a failure leaves nothing
        raise


def families(problem: Problem | str | Path, out: str | Path | None = None, *, study: Families | None = None,
             jobs: int | None = None, progress: bool = True) -> RunResults:
    """Which gaits exist at ``problem``'s cell (what it fixes), and the most stable one.

    Parameters
    ----------
    problem : Problem, str or Path
        A gait problem (no study, no continuation), or one whose study is a families
        study, or the path of its file. With no guess its seeds start from the body alone.
    out : str or Path, optional
        The folder to write the run's files into (as :func:`run`).
    study : Families, optional
        The budget (seeds, charts, descents); by default the problem's own families
        study, else :class:`~baslip.problem.study.Families` at its defaults.
    jobs : int, optional
        Worker processes (as :func:`run`).
    progress : bool
        Show progress on stderr.

    Returns
    -------
    RunResults
        Its ``record["answer"]``: the pieces found (charts, least spectral radius, stable
        share), the best gaits polished and verified, how wide the search was, and where
        no gait was found, why (:mod:`baslip.studies.families`).

    Raises
    ------
    InputError
        As :func:`run`; also a problem holding another study or a continuation.
    """
    if not isinstance(problem, Problem):
        problem = load_problem(path_argument(problem, "problem"))
    if study is not None and not isinstance(study, Families):
        raise ArgumentError("study", f"expected a Families study, got {type(study).__name__}")
    held = problem.study
    if problem.continuation is not None or (held is not None and not isinstance(held, Families)):
        raise ProblemKindError("study", f"problem {problem.name!r} holds a {'continuation' if held is None else held.kind}"
                               "; families asks at a gait problem's cell (leave its study and continuation out)")
    result = run(replace(problem, study=study or held or Families()), out, jobs=jobs, progress=progress)
    assert isinstance(result, RunResults)
    return result


#: The most worker processes or lanes a run takes (as ``--jobs`` and ``--lanes``).
MAX_WORKERS = 1024


def _check_options(*, out, jobs, lanes, scheduler, fresh, progress, sources) -> None:
    """Refuse :func:`run`'s options of the wrong type or range, naming the option, before
    anything is read or written."""
    for name, value in (("jobs", jobs), ("lanes", lanes)):
        if value is not None:
            whole_number(value, name, 1, MAX_WORKERS)
    for name, value in (("out", out), ("sources", sources)):
        if value is not None:
            path_argument(value, name)
    if scheduler is not None and not isinstance(scheduler, str):
        raise ArgumentError("scheduler", f"expected an address as text, got {type(scheduler).__name__}")
    for name, value in (("fresh", fresh), ("progress", progress)):
        if not isinstance(value, bool):
            raise ArgumentError(name, f"expected True or False, got {shown(value)}")


def check_run(problem: Problem, out: Path | None, sources: Path, scheduler: str | None = None,
              fresh: bool = False) -> None:
    """Every check of a run beyond its problem (which was checked whole when it was read):
    the runs a study reads, the scheduler, and the output folder (writable, and holding no
    run of another kind or problem unless ``fresh``).

    Parameters
    ----------
    problem : Problem
        The problem, read and checked.
    out : Path or None
        The output folder; None for a run that writes nothing.
    sources : Path
        The folder that holds the finished runs a study reads (its sweep, region, ...).
    scheduler : str or None
        A Dask scheduler's address (``tcp://...`` or ``local``), or None for worker processes.
    fresh : bool
        Whether results already in ``out`` are to be discarded rather than resumed.

    Raises
    ------
    InputError
        The first check that fails, naming its key or option.
    """
    if problem.study is not None:
        # Here, not at the top: a single gait's run then never loads the studies' modules
        # and their figures' matplotlib (a third of a warm run's start-up).
        from baslip.studies.registry import check_study_inputs

        check_study_inputs(problem, sources)
    if scheduler is not None:
        if problem.study is None:
            raise NothingToSchedule("--scheduler", f"{problem.name} has no study to run on a cluster")
        from baslip.studies.runner import check_scheduler  # here: a gait's run loads no worker machinery

        check_scheduler(scheduler)
    if out is not None:
        check_folder(problem, out, fresh)
        _check_writable(out)


def _check_writable(folder: Path) -> None:
    reason = unwritable(folder)
    if reason is not None:
        raise OutputUnwritable("", f"output folder {folder}: {reason}")


@contextlib.contextmanager
def _place(folder: Path | None, name: str) -> Iterator[Path]:
    """``folder``, or a temporary folder removed afterwards when there is none."""
    if folder is not None:
        yield folder
        return
    with tempfile.TemporaryDirectory(prefix="baslip-run-") as scratch:
        yield Path(scratch) / name


def _run_into(problem: Problem, out: Path, sources: Path, *, jobs, lanes, scheduler, fresh: bool,
              quiet: bool, kept: bool = True) -> FixedPointResult | RunResults:
    # The studies' modules are imported where a run needs them, as in check_run.
    if problem.study is not None:
        from baslip.studies.registry import run_study

        run_study(problem, out, quiet, fresh, jobs, scheduler, lanes, sources=sources, kept=kept)
        return open_results(out)
    if fresh:
        with hold(out):
            clear_run(out)
    if problem.continuation is not None:
        from baslip.studies.branch import run_continuation

        run_continuation(problem, out, quiet, jobs)
        return open_results(out)
    return solve_and_write(problem, out, quiet)


def solve_and_write(problem: Problem, out: Path, quiet: bool = True) -> FixedPointResult:
    """Solve the gait of ``problem`` and write ``result.json`` and ``multipliers.csv`` to
    ``out``, replacing an earlier result only once the new files are complete.

    Parameters
    ----------
    problem : Problem
        A single-gait problem (no study or continuation).
    out : Path
        The output folder.
    quiet : bool
        Whether to say nothing on stderr (else what is being loaded and solved).

    Returns
    -------
    FixedPointResult
        The verified gait, or the failure, as written.
    """
    with hold_for(problem, out), recording_code() as code:
        if not quiet:
            s = problem.solver
            orbit = "" if problem.strides == 1 else f", {problem.strides}-stride orbits"
            _log.info(f"{problem.name}: loading the compiled model and NLP ({s.nodes} nodes x {s.substeps} RK4 "
                      f"steps per stance phase{orbit}; the first run on a machine compiles them)...")
        solver = solver_for(problem, few_calls=True)  # one gait: see FixedPointSolver
        solver.nlp_for(problem.strides)
        if not quiet:
            _log.info(f"{problem.name}: solving ({problem.objective}) and verifying...")
        result = solve_problem(problem, solver)
        write_result(result, out, provenance(problem, code))
    return result
