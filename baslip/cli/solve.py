"""Command line: ``python -m baslip.solve PROBLEM.yaml [--out DIR] [--fresh]``.

Exit codes:

* 0: a verified fixed point; or a study or continuation that ran to the end (a point with
  no fixed point is data, listed with its reason);
* 1: the solver failed or the answer did not verify; a study that solved nothing or
  stopped short (Ctrl-C, a killed worker); a branch whose start did not converge;
* 2: bad input, a busy output folder, or a folder holding results of another problem
  (one line on stderr naming the key or folder; nothing is written).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from baslip.cli.common import EXIT_BAD_INPUT, EXIT_NOT_CONVERGED, EXIT_OK, OneLineParser, whole_number
from baslip.diagnostics import progress_hidden, show_on_stderr
from baslip.errors import InputError, RunError
from baslip.gait.describe import summary_text as summary
from baslip.problem.model_file import ModelProblem, load_any_problem
from baslip.problem.reader import ProblemError
from baslip.results import run_summary_text
from baslip.status import VERIFY_EPS


def _parser(prog: str = "python -m baslip.solve") -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog=prog,
        description=(
            "Find a periodic running gait (a fixed point of the apex return map) of the "
            "BA-SLIP runner described by a YAML problem file, verify it by an independent "
            f"re-simulation (eps <= {VERIFY_EPS:g}) and report its stability."
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=(
            "A plain problem writes DIR/result.json and DIR/multipliers.csv.\n"
            "A problem with a study: section (kind sweep, random, basin, adaptive, optimal,\n"
            "controllers, atlas or families) runs it on worker processes, resumably, and writes its CSV files,\n"
            "result.json and figures; rerunning finishes an interrupted study.\n"
            "A problem with a continuation: section traces a branch of fixed points in one\n"
            "parameter (branch.csv, diagram.png) and, with second/second_range/follow, the\n"
            "bifurcation curves in two parameters (curve.csv, curve.png).\n"
            "docs/guides/problem-files.md has every key; problems/ has examples of each.\n\n"
            "Exit status: 0 verified fixed point or completed study/branch; 1 solver failure,\n"
            "not verified, a study that solved nothing or stopped short, or a curve not found;\n"
            "2 bad input or a busy or stale output folder."
        ),
    )
    parser.add_argument("problem", type=Path, help="YAML problem file (see docs/guides/problem-files.md)")
    parser.add_argument("--out", type=Path, metavar="DIR", help="output folder (default: results/<name>/)")
    talk = parser.add_mutually_exclusive_group()
    talk.add_argument("--quiet", action="store_true", help="print nothing but errors")
    talk.add_argument("--verbose", action="store_true",
                      help="also print IPOPT's iterations (of a single solve, or of a branch's start)")
    parser.add_argument("--jobs", type=whole_number(1, 1024), metavar="N",
                        help="worker processes for a study, or for a continuation's curves (default: one per core, at "
                             "most one per lane; the answers do not depend on it); with --scheduler local, the "
                             "LocalCluster's workers")
    parser.add_argument("--lanes", type=whole_number(1, 1024), metavar="N",
                        help="split a new study into N lanes of warm-started tasks (default 2), so that up to N "
                             "workers run at once; recorded in result.json and kept when the run resumes. "
                             "The answers depend on N (not on --jobs): each lane warm-starts from its own "
                             "previous point. One-quantity sweeps always walk two lanes from their start")
    parser.add_argument("--format", choices=("png", "svg", "pdf"), default="png",
                        help="format of the figures a study or continuation writes (default png)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run a study's lanes on a Dask cluster: a scheduler address such as "
                             "tcp://host:8786, or 'local' for a LocalCluster (needs pip install 'baslip[dask]')")
    parser.add_argument(
        "--fresh", action="store_true",
        help="discard what DIR holds from an earlier run instead of resuming it (without "
             "this, a folder holding another kind of run, another problem's gait or "
             "branch, or a changed study's results is refused)",
    )
    return parser


def main(argv: list[str] | None = None, prog: str = "python -m baslip.solve") -> int:
    show_on_stderr()  # diagnostics (progress, notes) go through logging; show them
    args = _parser(prog).parse_args(argv)
    try:
        problem = load_any_problem(args.problem)
    except ProblemError as err:
        print(f"error: {args.problem}: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if isinstance(problem, ModelProblem):
        return _run_model(problem, args)
    if args.verbose:  # print_level is not part of the problem's hash: results stay comparable
        problem = problem.replace(solver=replace(problem.solver, print_level=5))
    out_dir = args.out if args.out is not None else Path("results") / problem.name
    # The run's modules (engine, solver, studies) are imported only once the problem is read.
    from baslip.api import check_run

    try:
        check_run(problem, out_dir, out_dir.parent, args.scheduler, args.fresh)
    except InputError as err:
        print(refusal(err, args.problem), file=sys.stderr)
        return EXIT_BAD_INPUT
    if problem.study is None and problem.continuation is None:
        return _run(problem, args, out_dir)  # a gait draws no figures: no matplotlib to load
    import matplotlib

    with matplotlib.rc_context({"savefig.format": args.format}):  # for this run's figures only
        return _run(problem, args, out_dir)


def refusal(err: InputError, problem_path: Path) -> str:
    """The one line for refused input: an entry of the problem file is named after the
    file; an option (``--scheduler: ...``) or a folder speaks for itself."""
    if err.key and not err.key.startswith("-"):
        return f"error: {problem_path}: {err}"
    return f"error: {err}"


def _run(problem, args, out_dir: Path) -> int:
    """Run the problem: a gait, a study or a continuation (inputs already checked); with
    ``--quiet`` no progress at all (compiles, IPOPT tries, the study's)."""
    with progress_hidden(args.quiet):
        return _run_shown(problem, args, out_dir)


def _run_shown(problem, args, out_dir: Path) -> int:
    try:
        if problem.study is not None:
            return _run_study(problem, out_dir, args.quiet, args.fresh, args.jobs, args.scheduler,
                              args.lanes)
        if args.fresh:
            clear_folder(out_dir)
        if problem.continuation is not None:
            return _run_continuation(problem, out_dir, args.quiet, args.jobs)
        return _solve_and_write(problem, out_dir, args.quiet)
    except InputError as err:  # found only once running: a busy or stale folder, a lost scheduler
        print(refusal(err, args.problem), file=sys.stderr)
        return EXIT_BAD_INPUT
    except RunError as err:  # valid input, but the run could not start
        print(f"error: {problem.name}: {err}", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    except KeyboardInterrupt:
        print(f"{problem.name}: interrupted", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    except Exception as err:  # a bug, not a result (or a full disk): say so in one line, write nothing
        print(failure_line(problem.name, err, out_dir), file=sys.stderr)
        return EXIT_NOT_CONVERGED


def failure_line(name: str, err: Exception, out_dir: Path) -> str:
    """The one line for an exception no layer turned into a refusal or a failure: a full
    disk met outside baslip's own writers (a figure's) names the file; anything else is a
    bug."""
    from baslip.files.atomic import FULL

    if isinstance(err, OSError) and err.errno in FULL:
        return f"error: {name}: no space left on device: {err.filename or out_dir}"
    return f"error: {name}: internal error: {type(err).__name__}: {err}".splitlines()[0]


def clear_folder(out_dir: Path) -> None:
    """Discard the run the folder holds, for ``--fresh`` (holding the folder meanwhile)."""
    from baslip.files.lock import hold
    from baslip.files.runs import clear_run

    with hold(out_dir):
        clear_run(out_dir)


def _run_study(problem, out_dir: Path, quiet: bool, fresh: bool, jobs: int | None,
               scheduler: str | None, lanes: int | None = None) -> int:
    from baslip.studies.registry import outcome, run_study

    summary = run_study(problem, out_dir, quiet, fresh, jobs, scheduler, lanes)
    failure = outcome(summary)
    if not quiet:
        print(run_summary_text(summary))
        print(f"  wrote {out_dir}/ (result.json, CSV files and figures), {summary['wall_time_s']:.1f} s")
    if failure is not None:
        print(f"error: {problem.name}: {failure}", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    return EXIT_OK


def _run_continuation(problem, out_dir: Path, quiet: bool, jobs: int | None = None) -> int:
    from baslip.studies.branch import run_continuation

    summary = run_continuation(problem, out_dir, quiet, jobs)
    if not quiet:
        print(run_summary_text(summary))
        from baslip.viz.figures import figure_file

        files = f"branch.csv, result.json, {figure_file('diagram')}"
        files += f", curve.csv, {figure_file('curve')}" if "curves" in summary else ""
        print(f"  wrote {out_dir}/ ({files}), {summary['wall_time_s']:.1f} s")
    missing = _missing_curves(summary.get("curves"))
    if missing:
        print(f"error: {problem.name}: no {' or '.join(missing)} curve was traced (see result.json)", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    return EXIT_OK


def _run_model(problem: ModelProblem, args) -> int:
    """A described model's problem: its gait, and its branch or atlas, written into the
    output folder whole or not at all."""
    if args.scheduler is not None:
        print(f"error: --scheduler: {problem.name} is a described model's problem, which runs in this process",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    out_dir = args.out if args.out is not None else Path("results") / problem.name
    from baslip.api import run_model

    try:
        with progress_hidden(args.quiet):
            run = run_model(problem, out_dir, progress=not args.quiet, fresh=args.fresh)
    except InputError as err:
        print(refusal(err, args.problem), file=sys.stderr)
        return EXIT_BAD_INPUT
    except RunError as err:
        print(f"error: {problem.name}: {err}", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    except KeyboardInterrupt:
        print(f"{problem.name}: interrupted", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    except Exception as err:  # a bug, not a result: one line, and nothing written
        print(failure_line(problem.name, err, out_dir), file=sys.stderr)
        return EXIT_NOT_CONVERGED
    if not args.quiet:
        print(run.summary())
        print(f"  wrote {', '.join(str(path) for path in run.files)}")
    return EXIT_OK


def _missing_curves(curves: dict | None) -> list[str]:
    """Curve types asked for that gave no curve (no such point on the branch, or failed)."""
    if curves is None:
        return []
    traced = {c["type"] for c in curves["curves"]}
    return [kind.replace("_", " ") for kind in curves["follow"] if kind not in traced]


def _solve_and_write(problem, out_dir: Path, quiet: bool) -> int:
    from baslip.api import solve_and_write
    from baslip.files.atomic import RESULT_FILES

    result = solve_and_write(problem, out_dir, quiet)
    if not quiet:
        print(summary(result))
        print(f"  wrote {', '.join(str(out_dir / name) for name in RESULT_FILES)}")
    return EXIT_OK if result.converged else EXIT_NOT_CONVERGED


if __name__ == "__main__":
    sys.exit(main())
