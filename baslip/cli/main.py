"""The ``baslip`` command (also ``python -m baslip``).

    baslip solve PROBLEM.yaml [--out DIR] [--jobs N] [--lanes N] [--quiet | --verbose] [--fresh]
    baslip trajectory PROBLEM.yaml [--strides N] [--samples N] [--out FILE.csv]
    baslip animate PROBLEM.yaml ... [--out DIR]
    baslip report [--results DIR]
    baslip problems [--copy DIR]
    baslip --version

``solve`` is ``python -m baslip.solve``: a gait, a study or a continuation, by what the
problem file holds. Exit codes are those of ``solve`` (0 done, 1 a solver failure or a run
that stopped short, 2 bad input).
"""

from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path

from baslip.cli.common import (
    EXIT_BAD_INPUT,
    EXIT_NOT_CONVERGED,
    EXIT_OK,
    OneLineParser,
    place_refusal,
    whole_number,
)
from baslip.version import __version__

COMMANDS = {
    "solve": "find and verify a gait, or run the problem's study or continuation",
    "trajectory": "solve a gait and write its continuous motion (positions, velocities, torque, forces) as CSV",
    "animate": "solve gaits and write animated GIFs of them",
    "report": "write results/REPORT.md from the studies' results",
    "problems": "list the shipped problem files, or copy them into a folder",
}

#: Most characters of a shipped problem's description in ``baslip problems``.
DESCRIPTION_WIDTH = 90


def _parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="baslip",
        description="Periodic running gaits of the BA-SLIP runner, their stability and bifurcations.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Commands:\n" + "\n".join(f"  {name:<11} {text}" for name, text in COMMANDS.items())
        + "\n\n'baslip COMMAND --help' tells more; 'baslip solve --help' covers studies and continuation.",
    )
    parser.add_argument("--version", action="version", version=f"baslip {__version__}")
    parser.add_argument("command", choices=COMMANDS, metavar="COMMAND", help="one of: " + ", ".join(COMMANDS))
    parser.add_argument("arguments", nargs=argparse.REMAINDER, help="the command's own arguments")
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except BrokenPipeError:  # e.g. `baslip problems | head`: the reader has gone
        sys.stderr.close()
        return EXIT_OK


def _main(argv: list[str] | None) -> int:
    args = _parser().parse_args(argv)
    rest = args.arguments
    if args.command == "solve":
        from baslip.cli.solve import main as solve

        return solve(rest, prog="baslip solve")
    if args.command == "trajectory":
        return trajectory(rest)
    if args.command == "animate":
        from baslip.cli.animate import main as animate

        return animate(rest, prog="baslip animate")
    if args.command == "report":
        from baslip.cli.report import main as report

        return report(rest, prog="baslip report")
    return problems(rest)


def problems(argv: list[str]) -> int:
    """List the shipped problems with their first comment line, or copy them."""
    from baslip.problem.shipped import copy_problems, describe, problems_dir, shipped_problems

    parser = OneLineParser(prog="baslip problems", description=COMMANDS["problems"])
    parser.add_argument("--copy", type=Path, metavar="DIR", help="copy every shipped problem into DIR (existing files are kept)")
    args = parser.parse_args(argv)
    if args.copy is not None:
        refusal = place_refusal("--copy", args.copy)
        if refusal is not None:
            print(refusal, file=sys.stderr)
            return EXIT_BAD_INPUT
        copied = copy_problems(args.copy)
        print(f"copied {len(copied)} problem files into {args.copy}/ ({len(shipped_problems()) - len(copied)} already there)")
        return EXIT_OK
    print(f"shipped problems ({problems_dir()}):")
    paths = shipped_problems()
    width = max(len(path.stem) for path in paths)  # the names' column fits the longest
    for path in paths:
        # Cut at a word, and say so, rather than mid-word.
        print(f"  {path.stem:<{width}} {textwrap.shorten(describe(path), DESCRIPTION_WIDTH, placeholder=' …')}")
    return EXIT_OK


def trajectory(argv: list[str]) -> int:
    """Solve a single-gait problem and write its motion as CSV."""
    from baslip.engine.returnmap import RunnerFell
    from baslip.engine.trajectory import checked_sampling
    from baslip.errors import ArgumentError
    from baslip.files.atomic import NoSpaceLeft, NotAFileToReplace, write_files_atomically
    from baslip.gait.from_problem import solve_start
    from baslip.problem.reader import ProblemError, load_problem

    parser = OneLineParser(prog="baslip trajectory", description=COMMANDS["trajectory"])
    parser.add_argument("problem", type=Path, help="a single-gait problem file (no study or continuation)")
    parser.add_argument("--strides", type=whole_number(1, 1000), default=2, metavar="N", help="strides to sample (default 2)")
    parser.add_argument("--samples", type=whole_number(2, 100000), default=100, metavar="N",
                        help="samples per flight phase; stance gets twice as many (default 100)")
    parser.add_argument("--out", type=Path, metavar="FILE", help="CSV file (default: <name>_trajectory.csv)")
    args = parser.parse_args(argv)
    try:  # before the solve: a motion of too many samples would run on for hours
        checked_sampling(args.strides, args.samples)
    except ArgumentError as err:
        print(f"error: --{err.key}: {err.message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        problem = load_problem(args.problem)
    except ProblemError as err:
        print(f"error: {args.problem}: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if problem.study is not None or problem.continuation is not None:
        print(f"error: {args.problem}: a trajectory needs a single gait, not a study or continuation", file=sys.stderr)
        return EXIT_BAD_INPUT
    out = args.out or Path(f"{problem.name}_trajectory.csv")
    refusal = place_refusal("--out", out, file=True)
    if refusal is not None:
        print(refusal, file=sys.stderr)
        return EXIT_BAD_INPUT
    result = solve_start(problem)
    if not result.converged:
        print(f"error: {problem.name}: no verified gait: {result.status} ({result.message})", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    try:
        motion = result.trajectory(args.strides, args.samples)
    except RunnerFell as err:
        print(f"error: {problem.name}: the runner falls ({err.fall.value})", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    try:
        write_files_atomically({out: motion.csv_text()})
    except NotAFileToReplace as err:  # put there since the check above
        print(f"error: --out {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except NoSpaceLeft as err:
        print(f"error: {problem.name}: {err}", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    print(f"wrote {out}: {motion!r}")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
