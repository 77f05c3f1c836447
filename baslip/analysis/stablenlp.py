"""The most stable gait near a start by the stability NLP: the cross-check of the descent
(:mod:`baslip.analysis.descent`) and of the atlas (:mod:`baslip.analysis.atlas`).

The stability NLP (:mod:`baslip.gait.monodromy`) bounds every multiplier of the shot
stride by a Schur form inside the stride NLP and minimises the bound. It is accurate only
where its RK4 intervals are (h * rate <= :data:`baslip.gait.monodromy.STEP_RATE_LIMIT`),
so its starts are drawn where that holds; its answer is polished and verified on the
compiled map like any other solve, and the verified radius is the one reported.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baslip.analysis.descent import OptimalGait
from baslip.gait.draws import random_start
from baslip.gait.fixedpoint import FixedPointSolver
from baslip.gait.monodromy import accurate_control_bounds
from baslip.gait.shooting import FixedPointSpec


def draw_spec(spec: FixedPointSpec, steps: int) -> FixedPointSpec:
    """``spec`` with the drawn controls' bounds narrowed to where ``steps`` RK4 steps per
    stance phase are accurate (:func:`baslip.gait.monodromy.accurate_control_bounds`)."""
    narrowed = dict(spec.bounds)
    for name, (lo, hi) in accurate_control_bounds(spec.law, spec.params, steps).items():
        own_lo, own_hi = spec.bounds_of(name)
        narrowed[name] = (max(own_lo, lo), min(own_hi, hi))
    return replace(spec, bounds=narrowed)


def stable_nlp_from(solver: FixedPointSolver, spec: FixedPointSpec, rng: np.random.Generator,
                    name: str = "problem") -> OptimalGait:
    """Draw the law's gains (Kp and Kd, or r_vpp) where the stability NLP is accurate,
    solve the gait with them held, and run the stability NLP from that gait (gains free
    again); the end is verified.

    Parameters
    ----------
    solver
        Builds and runs both NLPs and verifies their answers.
    spec
        The problem at one grid point (its objective is replaced).
    rng
        The start's own random stream.
    name
        The problem's name, for the results.
    """
    steps = solver.options.nodes * solver.options.substeps
    held = random_start(draw_spec(spec, steps), rng)
    start = solver.solve(replace(spec, fixed={**spec.fixed, **held}, objective="nearest_guess"), name=name)
    if not start.converged:
        return OptimalGait(held, start, note=f"no starting fixed point: {start.message}")
    end = solver.solve(replace(spec, objective="least_spectral_radius"), name=name, w0=start.nlp_w)
    report = end.solver
    bound = "" if report.spectral_bound is None else f", its bound {report.spectral_bound:.4g}"
    return OptimalGait(held, start, end=end, note=f"stability NLP: {report.return_status} after "
                       f"{report.iterations} iterations{bound}")
