"""Specification of baslip.model.dynamics: the Lagrangian-derived stance equations and the maps.

The stance equations are derived by CasADi from L = T - V; here they are checked against
the thesis's printed forms (eq. 3.27 for M, eq. 3.28 for f with "rhodot_1" read as
rhodot * theta1_dot) and against the invariants of the maps.
"""

import numpy as np
import pytest

from baslip.model.dynamics import CONFIGURATION, STANCE, Params, build_model, stance_equations

MODEL = build_model()
RNG = np.random.default_rng(7)


def random_stance_states(n):
    q = np.column_stack([RNG.uniform(0.1, 0.2, n), RNG.uniform(-0.6, 0.6, n), RNG.uniform(-3, 3, n)])
    qdot = RNG.uniform(-3, 3, (n, 3))
    return np.hstack([q, qdot])


def thesis_mass_matrix(q, p: Params):
    """Eq. 3.27 (printed divided by m)."""
    rho, _, th2 = q
    d, r = p.d, p.I / p.m
    s, c = np.sin(th2), np.cos(th2)
    return p.m * np.array(
        [
            [1, d * s, d * s],
            [d * s, rho**2 - 2 * d * rho * c + d**2 + r, d**2 - d * rho * c + r],
            [d * s, d**2 - d * rho * c + r, d**2 + r],
        ]
    )


def thesis_rhs(x, tau, p: Params):
    """Eq. 3.28 (divided by m) with the typo "rhodot_1" read as rhodot * theta1_dot."""
    rho, th1, th2, rd, t1d, t2d = x
    d, g, k, m = p.d, p.g, p.k, p.m
    return m * np.array(
        [
            rho * t1d**2 - g * np.cos(th1) - k / m * (rho - p.rho0) - d * np.cos(th2) * (t1d + t2d) ** 2,
            -2 * rd * t1d * (rho - d * np.cos(th2)) + g * rho * np.sin(th1)
            - t1d * t2d * 2 * d * rho * np.sin(th2) - t2d**2 * d * rho * np.sin(th2) - g * d * np.sin(th1 + th2),
            tau / m + rd * t1d * 2 * d * np.cos(th2) + t1d**2 * d * rho * np.sin(th2) - g * d * np.sin(th1 + th2),
        ]
    )


def test_the_stance_state_is_the_configuration_then_the_rate_of_each_entry():
    """The equations split a stance state by CONFIGURATION's size: q first, then qdot in
    the same order."""
    n = CONFIGURATION.size
    assert STANCE.size == 2 * n and STANCE.names[:n] == CONFIGURATION.names
    for coordinate, rate in zip(CONFIGURATION.names, STANCE.names[n:]):
        assert rate.startswith(coordinate) and rate.endswith("dot")


@pytest.mark.parametrize("params", [Params(), Params(m=2.5, I=0.01, d=0.07, k=3000.0)])
def test_mass_matrix_equals_thesis_eq_3_27(params):
    for x in random_stance_states(20):
        M = np.asarray(MODEL.mass_matrix(x[:3], params.vector()))
        np.testing.assert_allclose(M, thesis_mass_matrix(x[:3], params), rtol=1e-13, atol=1e-15)


def test_rhs_equals_thesis_eq_3_28_with_typo_corrected():
    p = Params(m=1.7, I=0.004, d=0.05)
    for x in random_stance_states(20):
        tau = RNG.uniform(-2, 2)
        _, rhs = stance_equations(x[:3], x[3:], tau, p.vector())
        np.testing.assert_allclose(np.asarray(rhs).ravel(), thesis_rhs(x, tau, p), rtol=1e-12, atol=1e-12)


def test_stance_energy_rate_is_hip_power():
    """dE/dt = tau * theta2_dot: the torque does work only through theta2."""
    p = Params().vector()
    eps = 1e-6
    for x in random_stance_states(10):
        tau = RNG.uniform(-1, 1)
        xdot = np.asarray(MODEL.stance_dynamics(x, tau, p)).ravel()
        rate = (float(MODEL.stance_energy(x + eps * xdot, p)) - float(MODEL.stance_energy(x - eps * xdot, p))) / (2 * eps)
        assert rate == pytest.approx(tau * x[5], rel=1e-6, abs=1e-8)


def test_touchdown_and_liftoff_maps_are_inverse_at_rest_length():
    p = Params().vector()
    for x in random_stance_states(10):
        x[0] = Params().rho0
        xf = MODEL.liftoff_map(x, p)
        back = np.asarray(MODEL.touchdown_map(xf, x[1], p)).ravel()
        np.testing.assert_allclose(back, x, atol=1e-12)


def test_touchdown_conserves_energy_and_puts_foot_on_ground():
    params = Params()
    p = params.vector()
    theta_td, theta_h = 0.12, -1.5
    z_touchdown = params.d * np.sin(theta_h) + params.rho0 * np.cos(theta_td)  # foot at z = 0
    xf = np.array([0.0, z_touchdown, theta_h, 0.6, -1.2, 0.3])
    x = np.asarray(MODEL.touchdown_map(xf, theta_td, p)).ravel()
    assert float(MODEL.stance_energy(x, p)) == pytest.approx(float(MODEL.flight_energy(xf, p)), rel=1e-14)
    assert x[0] == Params().rho0 and x[1] == theta_td
    assert x[1] + x[2] - np.pi / 2 == pytest.approx(xf[2], abs=1e-15)  # theta_h unchanged


def test_foot_height_guard_is_zero_at_the_stance_foot():
    """The touchdown guard of the CoM state of any stance pose at rest length is zero."""
    p = Params().vector()
    for x in random_stance_states(5):
        x[0] = Params().rho0
        xf = MODEL.liftoff_map(x, p)
        assert float(MODEL.touchdown_guard(xf, x[1], p)) == pytest.approx(0.0, abs=1e-15)
