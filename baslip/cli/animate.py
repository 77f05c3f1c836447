"""``baslip animate`` (also ``python -m baslip.animate``): GIFs of verified gaits.

    python -m baslip.animate problems/downward.yaml problems/upward.yaml --out results/animation

Each problem is solved (and verified) first; its gait is drawn for two strides in slow
motion by :mod:`baslip.viz.animation`.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from baslip.cli.common import OneLineParser
from baslip.diagnostics import show_on_stderr
from baslip.engine.codegen import FEW_CALLS
from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.engine.trajectory import stride_trajectory
from baslip.gait.from_problem import solve_start
from baslip.problem.reader import ProblemError, load_problem
from baslip.viz.animation import animate

#: What ``--help`` says the command does (plain text: help is no docstring).
DESCRIPTION = ("solve and verify each single-gait problem, then write an animated GIF of its gait: two strides "
               "in slow motion (also python -m baslip.animate)")


def main(argv: list[str] | None = None, prog: str = "python -m baslip.animate") -> int:
    """Solve each problem file given in ``argv`` and write its GIF; return the exit status."""
    show_on_stderr()  # diagnostics (progress, notes) go through logging; show them
    parser = OneLineParser(prog=prog, description=DESCRIPTION)
    parser.add_argument("problems", nargs="+", type=Path, help="single fixed-point problem files")
    parser.add_argument("--out", type=Path, default=Path("results/animation"), metavar="DIR",
                        help="folder for the GIFs, one <name>.gif per problem (default: results/animation)")
    args = parser.parse_args(argv)
    problems = []
    for path in args.problems:  # every file read before anything is written
        try:
            problems.append(load_problem(path))
        except ProblemError as err:
            print(f"error: {path}: {err}", file=sys.stderr)
            return 2
    args.out.mkdir(parents=True, exist_ok=True)
    for path, problem in zip(args.problems, problems):
        result = solve_start(problem)
        if not result.converged:
            print(f"error: {path}: no verified fixed point to animate ({result.message})", file=sys.stderr)
            return 1
        rmap = ReturnMap(Tolerances(1e-10, 1e-10), compile=FEW_CALLS, law=problem.hip_law)  # its own law; a few strides
        trajectory = stride_trajectory(rmap, result.X, result.u, problem.params)
        verdict = "stable" if result.stable else "unstable"
        title = (f"{problem.name}: theta_h = {np.degrees(result.apex['theta_h']):.1f} deg, "
                 f"ydot = {result.apex['ydot']:.2f} m/s, {verdict}")
        out = animate(trajectory, problem.params, title, args.out / f"{problem.name}.gif")
        print(f"wrote {out} ({out.stat().st_size // 1024} KB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
