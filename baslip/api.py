"""The Python entry point: load a problem, solve it, get a verified result back.

>>> from baslip import load_problem, solve_problem
>>> result = solve_problem(load_problem("problems/downward.yaml"))
>>> result.status, result.residual, result.spectral_radius
"""

from __future__ import annotations

from .fixedpoint import FixedPointResult, FixedPointSolver
from .problem import Problem
from .shooting import FixedPointSpec, ShootingOptions


def shooting_options(problem: Problem) -> ShootingOptions:
    """The NLP settings a problem asks for."""
    s = problem.solver
    return ShootingOptions(
        nodes=s.nodes,
        substeps=s.substeps,
        ipopt={"max_iter": s.max_iter, "tol": s.tol, "acceptable_tol": max(s.tol, 1e-8), "print_level": s.print_level},
    )


def fixed_point_spec(problem: Problem) -> FixedPointSpec:
    """What the NLP solves for a problem."""
    return FixedPointSpec(
        params=problem.params,
        fixed=dict(problem.fix),
        guess=problem.full_guess(),
        bounds=dict(problem.bounds),
        objective=problem.objective,
        strides=problem.strides,
    )


def solve_problem(problem: Problem, solver: FixedPointSolver | None = None) -> FixedPointResult:
    """Solve and verify ``problem``; pass a built ``solver`` to reuse it across problems."""
    solver = solver or FixedPointSolver(shooting_options(problem))
    return solver.solve(fixed_point_spec(problem), name=problem.name)
