"""Specification of baslip.analysis.feedback: stride-to-stride controllers.

* Deadbeat feedback puts every closed-loop multiplier at 0 where dr/du has rank 4.
* The closed-loop multipliers of u = u* + K (X - X*) are the eigenvalues of A + B K, and
  agree with the Jacobian of the closed-loop map measured by finite differences of the
  stride itself (not from A and B).
* LQR solves the discrete Riccati equation and stabilises the upright gait linearly,
  where dr/du has rank 3 and deadbeat is impossible.
* A structural multiplier at 1 that no control reaches is left out of the design: the
  transverse LQR stabilises the rest and leaves that direction alone, where the plain
  Riccati iteration has no stabilising solution; where the plain design settles, it is
  the one kept.
* The per-stride re-solve keeps a perturbed runner hopping and reports what it leaves.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from baslip import Params, ReturnMap
from baslip.analysis.feedback import (
    CONTROL_SCALE,
    LinearFeedback,
    ResolvedControl,
    closed_loop_multipliers,
    control_rank,
    deadbeat_gain,
    lqr_gain,
    lqr_gain_for_gait,
    run_closed_loop,
    transverse_lqr_gain,
)
from baslip.gait.polish import eps

ROOT = Path(__file__).resolve().parents[1]
Q = np.diag(1 / np.array([0.01, 0.1, 0.1, 1.0]) ** 2)
R = np.diag(1 / CONTROL_SCALE**2)
NO_BOUNDS = (np.full(5, -np.inf), np.full(5, np.inf))


def gait(name):
    record = json.loads((ROOT / "results" / name / "result.json").read_text())
    return np.array(list(record["apex"].values())), np.array(list(record["control"].values()))


@pytest.fixture(scope="module")
def linearised(tight_map):
    out = {}
    for name in ("downward", "upward"):
        X, u = gait(name)
        out[name] = (X, u, *tight_map.jacobians(X, u, Params()))
    return out


def test_deadbeat_puts_the_multipliers_at_zero_where_dr_du_has_rank_4(linearised):
    X, u, A, B = linearised["downward"]
    assert control_rank(B) == 4
    assert np.max(np.abs(closed_loop_multipliers(A, B, deadbeat_gain(A, B)))) < 1e-6


def test_deadbeat_is_refused_where_dr_du_has_rank_3(linearised):
    X, u, A, B = linearised["upward"]
    assert control_rank(B) == 3
    with pytest.raises(ValueError, match="rank 4"):
        deadbeat_gain(A, B)


def test_lqr_solves_the_riccati_equation_and_stabilises_the_upright_gait(linearised):
    X, u, A, B = linearised["upward"]
    assert np.max(np.abs(np.linalg.eigvals(A))) > 10  # open loop: unstable
    K = lqr_gain(A, B, Q, R)
    # K is the LQR gain of the P that solves the discrete algebraic Riccati equation.
    P = Q.copy()
    for _ in range(20000):
        P = Q + A.T @ P @ A - A.T @ P @ B @ np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    assert np.allclose(K, -np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A), rtol=1e-6, atol=1e-8)
    assert np.max(np.abs(closed_loop_multipliers(A, B, K))) < 1


@pytest.mark.parametrize("name", ["downward", "upward"])
def test_closed_loop_multipliers_match_the_measured_closed_loop_map(tight_map, linearised, name):
    """Central differences of X -> r(X, u* + K (X - X*)), with strides of the map itself."""
    X, u, A, B = linearised[name]
    K = lqr_gain(A, B, Q, R)
    h = 1e-6
    J = np.zeros((4, 4))
    for j in range(4):
        step = np.zeros(4)
        step[j] = h
        plus = tight_map(X + step, u + K @ step, Params())
        minus = tight_map(X - step, u - K @ step, Params())
        J[:, j] = (plus - minus) / (2 * h)
    measured = np.sort_complex(np.linalg.eigvals(J))
    predicted = np.sort_complex(closed_loop_multipliers(A, B, K))
    assert np.allclose(measured, predicted, atol=1e-5)


def test_lqr_feedback_recovers_the_upright_gait_from_a_perturbation(tight_map, linearised):
    X, u, A, B = linearised["upward"]
    controller = LinearFeedback(X, u, lqr_gain(A, B, Q, R), *NO_BOUNDS)
    run = run_closed_loop(tight_map, Params(), controller, X + np.array([1e-4, 1e-4, 1e-4, 1e-3]), X, 200)
    assert run.outcome == "converged" and run.strides_to_converge < 100


SHIPPED = np.array([1e-3, 1e-2, 1e-2, 0.0])  # the adaptive study's perturbation
RANDOM = np.random.default_rng(11).choice([-1.0, 1.0], size=4) * np.abs(SHIPPED)  # same size, random signs


@pytest.mark.parametrize("criterion", ["thesis", "tracking"])
@pytest.mark.parametrize("offset", [SHIPPED, RANDOM], ids=["shipped", "random"])
def test_the_per_stride_re_solve_keeps_a_perturbed_upright_runner_hopping(tight_map, criterion, offset):
    """The open-loop gait, perturbed like this, falls within a few strides; re-solving u at
    every apex keeps it up. With dr/du of rank 3 the re-solve cannot zero its residual: it
    reports what it leaves (about 1e-4 here)."""
    X, u = gait("upward")
    X0 = X + offset
    from baslip.analysis.feedback import ConstantControl

    assert run_closed_loop(tight_map, Params(), ConstantControl(u), X0, X, 40).outcome == "fell"
    controller = ResolvedControl(tight_map, Params(), X, u, criterion, fixed=(3,))
    run = run_closed_loop(tight_map, Params(), controller, X0, X, 40)
    assert run.outcome != "fell" and len(run.controls) == 40
    assert 0 < np.max(run.residuals) < 1e-2
    if criterion == "tracking":
        assert eps(run.apexes[-1], X) < 2e-3  # brought back near the gait


def test_runs_in_lockstep_end_as_the_same_runs_one_by_one(tight_map, linearised):
    """The batched closed loop (every live run's stride in one call) against the scalar
    loop, start by start: the same outcome after the same number of strides."""
    from baslip.analysis.feedback import run_closed_loop_many

    X, u, A, B = linearised["upward"]
    controller = LinearFeedback(X, u, lqr_gain(A, B, Q, R), *NO_BOUNDS)
    starts = X + np.random.default_rng(5).uniform(-1, 1, (12, 4)) * np.array([1e-3, 1e-2, 1e-2, 5e-2]) * 0.5
    together = run_closed_loop_many(tight_map, Params(), controller, starts, X, 60)
    for start, batched in zip(starts, together):
        alone = run_closed_loop(tight_map, Params(), controller, start, X, 60)
        assert (batched.outcome, batched.strides_run) == (alone.outcome, len(alone.controls))
    assert {r.outcome for r in together} >= {"converged", "fell"}  # the box is large enough to tell


def test_a_run_that_repeats_away_from_the_gait_has_settled_on_its_family(linearised):
    """At a VPP gait a structural multiplier 1 leaves a direction of neighbouring gaits;
    under the constant law a start on that direction repeats at once."""
    from baslip import ReturnMap, Tolerances
    from baslip.analysis.feedback import ConstantControl
    from baslip.gait.from_problem import solve_problem
    from baslip.problem.reader import load_problem

    gait = solve_problem(load_problem(ROOT / "problems" / "vpp_human.yaml"))
    rmap = ReturnMap(Tolerances(1e-12, 1e-12), law=gait.law)
    values, vectors = np.linalg.eig(rmap.jacobians(gait.X, gait.u, gait.params)[0])
    family = np.real(vectors[:, np.argmin(np.abs(values - 1.0))])
    start = gait.X + 1e-5 * family / np.linalg.norm(family)
    run = run_closed_loop(rmap, gait.params, ConstantControl(gait.u), start, gait.X, 50, 1e-6, settle=True)
    assert run.outcome == "settled" and eps(run.apexes[-1], gait.X) > 1e-6


def _system_with_a_unit_multiplier_no_control_reaches():
    """A 4-state system, unstable (multipliers 1.6 and 1.3), with a multiplier at exactly 1
    along v = (1, 1, 0, 0) / sqrt(2) that B does not reach, written in a rotated basis."""
    rotation = np.linalg.qr(np.array([[1.0, 2, 0, 1], [1, -1, 1, 0], [0, 1, 3, 1], [2, 0, 1, -1]]))[0]
    modal = np.array([[1.0, 0, 0, 0], [0, 1.6, 0.3, 0], [0, 0, 1.3, 0], [0, 0, 0.2, 0.5]])
    reach = np.array([[0.0, 0], [1, 0], [0.5, 1], [0, 1]])  # nothing along the first (neutral) mode
    return rotation @ modal @ rotation.T, rotation @ reach, rotation[:, 0]


def test_the_plain_riccati_iteration_refuses_a_unit_multiplier_no_control_reaches():
    A, B, _ = _system_with_a_unit_multiplier_no_control_reaches()
    with pytest.raises(ValueError, match="does not settle"):
        lqr_gain(A, B, np.eye(4), np.eye(2))


def test_the_transverse_lqr_stabilises_the_rest_and_leaves_the_neutral_direction_alone():
    A, B, neutral_direction = _system_with_a_unit_multiplier_no_control_reaches()
    K = transverse_lqr_gain(A, B, np.eye(4), np.eye(2), neutral=1)
    assert np.allclose(K @ neutral_direction, 0.0, atol=1e-12)
    multipliers = np.sort(np.abs(np.linalg.eigvals(A + B @ K)))
    assert multipliers[-1] == pytest.approx(1.0, abs=1e-12)  # the neutral one, untouched
    assert multipliers[-2] < 1.0  # the unstable 1.6 and 1.3 are brought inside
    assert np.allclose(lqr_gain_for_gait(A, B, np.eye(4), np.eye(2), neutral=1), K)
    with pytest.raises(ValueError):
        lqr_gain_for_gait(A, B, np.eye(4), np.eye(2), neutral=0)


def test_where_the_plain_design_settles_it_is_the_gain_kept():
    X, u = gait("downward")
    A, B = ReturnMap().jacobians(X, u, Params())
    assert np.array_equal(lqr_gain_for_gait(A, B, Q, R, neutral=1), lqr_gain(A, B, Q, R))
