"""Specification of :mod:`baslip.gait.ipopt_threads`: IPOPT's BLAS runs on one thread, so
that a solve's iterates do not depend on how many cores the machine has."""

import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baslip import load_problem
from baslip.gait import shooting
from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.gait.ipopt_threads import loaded_openblas

ROOT = Path(__file__).resolve().parents[1]
#: A body_angle_scan point where the exact-Hessian NLP struggles from the guess: inertia
#: corrections up to 1e16, then 300 iterations without converging. On the 2-core machine
#: its last iterate on 2 threads was 1.4 rad/s away from the one on 1 thread in theta_h_dot.
STRUGGLING_THETA_H = -2.356194490192


@pytest.fixture(scope="module")
def scan():
    problem = load_problem(ROOT / "problems" / "body_angle_scan.yaml")
    return solver_for(problem), fixed_point_spec(problem)


def openblas_or_skip() -> list:
    libraries = loaded_openblas()
    if not libraries:
        pytest.skip("this CasADi's IPOPT links no OpenBLAS of its own")
    return libraries


def test_a_solve_runs_ipopt_blas_on_one_thread_whatever_was_set_before(scan):
    solver, spec = scan
    solver.nlp.solve(spec, rmap=solver.residual_map)  # the plugin and its BLAS are loaded
    libraries = openblas_or_skip()
    for library in libraries:
        library.openblas_set_num_threads(2)
    assert solver.nlp.solve(spec, rmap=solver.residual_map).return_status == "Solve_Succeeded"
    assert [library.openblas_get_num_threads() for library in libraries] == [1] * len(libraries)


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="OpenBLAS runs one thread on one core anyway")
def test_a_struggling_solve_ends_where_it_ends_on_one_thread(scan, monkeypatch):
    solver, spec = scan
    spec = replace(spec, fixed={**spec.fixed, "theta_h": STRUGGLING_THETA_H})
    nlp = solver.nlp_for(1, exact=True)
    nlp.solve(spec, rmap=solver.residual_map, ipopt={"max_iter": 1})
    libraries = openblas_or_skip()
    for library in libraries:
        library.openblas_set_num_threads(2)
    pinned = nlp.solve(spec, rmap=solver.residual_map)
    # The reference: one thread set by hand, the module's pin switched off.
    monkeypatch.setattr(shooting, "pin_ipopt_threads", lambda: [])
    for library in libraries:
        library.openblas_set_num_threads(1)
    by_hand = nlp.solve(spec, rmap=solver.residual_map)
    assert pinned.return_status == by_hand.return_status == "Maximum_Iterations_Exceeded"
    np.testing.assert_array_equal(pinned.w, by_hand.w)
