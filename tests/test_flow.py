"""Specification of baslip.engine.dop853: fixed-step DOP853 steps, chains and Newton-located events.

Checked on the harmonic oscillator x'' = -w^2 x, whose flow and event times are known in
closed form.
"""

import math

import casadi as ca
import numpy as np
import pytest

from baslip.engine import dop853 as flow

OMEGA = 2.0


def oscillator():
    x, theta = ca.SX.sym("x", 2), ca.SX.sym("theta")
    return ca.Function("oscillator", [x, theta], [ca.vertcat(x[1], -theta**2 * x[0])])


def velocity_guard():
    x, theta = ca.SX.sym("x", 2), ca.SX.sym("theta")
    return ca.Function("velocity", [x, theta], [x[1]])


def final_error(steps: int) -> tuple[float, float]:
    """(|error| of x(T) after ``steps`` steps over T = 2, summed error estimate)."""
    chained = flow.chain(flow.step_function(oscillator()), steps)
    nodes, estimates = chained([1.0, 0.0], 2.0 / steps, OMEGA)
    return abs(float(nodes[0, -1]) - math.cos(2.0 * OMEGA)), float(ca.sum2(estimates))


def test_dop853_is_of_order_eight():
    coarse, _ = final_error(10)
    fine, _ = final_error(20)
    assert coarse / fine > 2**8 * 0.6


@pytest.mark.parametrize("steps", [10, 20, 40])
def test_error_estimate_bounds_the_actual_error(steps):
    actual, estimate = final_error(steps)
    assert actual <= estimate


def test_chain_repeats_the_step():
    step = flow.step_function(oscillator())
    x = np.array([1.0, 0.0])
    for _ in range(5):
        x = np.asarray(step(x, 0.1, OMEGA)[0]).ravel()
    nodes = flow.chain(step, 5)([1.0, 0.0], 0.1, OMEGA)[0]
    assert np.array_equal(np.asarray(nodes)[:, -1], x)


def test_event_step_lands_on_the_guard_with_ift_derivatives():
    """x = cos(w t): the velocity vanishes at t = pi / w, and dt/dw = -pi / w^2."""
    step = flow.step_function(oscillator())
    event = flow.event_step(step, oscillator(), velocity_guard(), iterations=4)
    x0, theta = ca.MX.sym("x0", 2), ca.MX.sym("theta")
    # 19 steps of the grid, then the step that ends on the event.
    h = 0.05 * math.pi / OMEGA
    x19 = flow.chain(step, 19)(x0, h, theta)[0][:, -1]
    s = event(x19, h * 1.02, theta)[0]
    t_event = ca.Function("t_event", [x0, theta], [19 * h + s, ca.jacobian(s, theta)])
    t, dt_dw = (float(v) for v in t_event([1.0, 0.0], OMEGA))
    assert t == pytest.approx(math.pi / OMEGA, abs=1e-12)
    assert dt_dw == pytest.approx(-math.pi / OMEGA**2, abs=1e-9)
