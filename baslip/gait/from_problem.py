"""A problem file's gait: the NLP settings and the fixed-point spec it asks for, solved.

>>> from baslip import load_problem, solve_problem
>>> result = solve_problem(load_problem("problems/downward.yaml"))
>>> result.status, result.residual, result.spectral_radius
"""

from __future__ import annotations

from baslip.diagnostics import progress_hidden, show_on_stderr
from baslip.errors import ProblemKindError
from baslip.gait.anybody import started_from_body
from baslip.gait.fixedpoint import FixedPointResult, FixedPointSolver
from baslip.gait.shooting import FixedPointSpec, ShootingOptions, ipopt_options
from baslip.model.quantities import POSTURE_BOUNDS
from baslip.problem.reader import Problem


def shooting_options(problem: Problem) -> ShootingOptions:
    """The NLP settings a problem asks for."""
    s = problem.solver
    return ShootingOptions(nodes=s.nodes, substeps=s.substeps, ipopt=ipopt_options(s))


def fixed_point_spec(problem: Problem) -> FixedPointSpec:
    """What the NLP solves for a problem (its posture bounding theta_h unless its bounds do)."""
    posture = {"theta_h": POSTURE_BOUNDS[problem.posture]} if problem.posture in POSTURE_BOUNDS else {}
    return FixedPointSpec(
        params=problem.params,
        fixed=dict(problem.fix),
        guess=problem.full_guess(),
        bounds={**posture, **problem.bounds},
        objective=problem.objective,
        strides=problem.strides,
        law=problem.hip_law,
    )


def solver_for(problem: Problem, few_calls: bool = False) -> FixedPointSolver:
    """A solver built with the discretisation and IPOPT settings ``problem`` asks for;
    ``few_calls`` for one gait's solve (see :class:`~baslip.gait.fixedpoint.FixedPointSolver`)."""
    return FixedPointSolver(shooting_options(problem), law=problem.hip_law, few_calls=few_calls)


def solve_problem(problem: Problem, solver: FixedPointSolver | None = None, *, progress: bool = True) -> FixedPointResult:
    """Solve and verify the gait of ``problem``.

    Parameters
    ----------
    problem : Problem
        A problem with no ``study:`` and no ``continuation:`` section (run those with
        :func:`baslip.run`).
    solver : FixedPointSolver, optional
        A built solver, to reuse across problems; its own settings are then used, not
        the problem's ``solver:`` section. Without one, a solver of one gait is built
        (``few_calls``: libraries it would call a few times are not compiled).
    progress : bool
        Show progress on stderr (a compile's announcement and heartbeat, IPOPT's second
        try), as :func:`baslip.run` does; unless the application configured logging
        itself, whose handlers then decide.

    Returns
    -------
    FixedPointResult
        The verified gait, or a result whose status says why there is none.

    Raises
    ------
    ProblemKindError
        If ``problem`` holds a study or a continuation.
    """
    for section in ("study", "continuation"):
        if getattr(problem, section) is not None:
            raise ProblemKindError(section, f"problem {problem.name!r} holds a {section}, which solve_problem "
                                   "does not run; use baslip.run(problem) for it")
    if progress:
        show_on_stderr()
    with progress_hidden(not progress):
        return solve_start(problem, solver)


def solve_start(problem: Problem, solver: FixedPointSolver | None = None) -> FixedPointResult:
    """Solve and verify the problem's own fixed point, whatever else it holds: the gait a
    study or a branch starts from. A problem of one stride with no guess at all starts
    from the body alone (:func:`~baslip.gait.anybody.start_from_body`), or, where no path
    reaches it, from the default guess."""
    solver = solver or solver_for(problem, few_calls=True)
    spec = fixed_point_spec(problem)
    if not problem.guess and problem.strides == 1:
        spec = started_from_body(spec, solver, problem.posture)
    return solver.solve(spec, name=problem.name)
