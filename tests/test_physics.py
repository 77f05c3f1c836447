"""The engine's physics is the BA-SLIP description's, in the engine's arguments.

* The stance flow derived from the description's Lagrangian by automatic differentiation
  is the hand-ordered derivation of :mod:`baslip.model.dynamics` to the bit, under both
  hip laws, at states across the design box.
* The guards, resets and clearances are the description's transitions and falls, found
  by their names, with the touchdown angle taken from the law's controls.
* Symbolic callers get the flow and guards as operations of their own graph (no call),
  numeric callers get numbers.
"""

import math

import casadi as ca
import numpy as np
import pytest

from baslip.engine.physics import CLEARANCE_FALLS, Physics
from baslip.model import dynamics
from baslip.model.dynamics import FLIGHT, PARAMS, STANCE, Params
from baslip.model.hiplaw import HIP_LAWS


def _samples(law, count, seed=61):
    """(x, u, p) at ``count`` stance states, controls and bodies drawn across the box."""
    rng = np.random.default_rng(seed)
    base = Params().vector()
    for _ in range(count):
        x = rng.uniform([0.05, 0.3, 0.2, -3.0, -8.0, -20.0], [0.25, 2.8, 3.0, 3.0, 8.0, 20.0])
        u = np.array([law.defaults[n] for n in law.controls.names]) * rng.uniform(0.2, 3.0, law.controls.size)
        yield x, u, base * rng.uniform(0.5, 2.0, PARAMS.size)


@pytest.mark.parametrize("law", HIP_LAWS.values(), ids=HIP_LAWS)
def test_the_described_stance_flow_is_the_engines_own_derivation_to_the_bit(law):
    physics = Physics.of(law)
    for x, u, p in _samples(law, 500):
        described = np.asarray(physics.stance_rate(x, u, p)).ravel()
        derived = np.asarray(dynamics.stance_dynamics(ca.DM(x), law.torque(ca.DM(x), ca.DM(u), ca.DM(p)), ca.DM(p))).ravel()
        assert np.array_equal(described, derived), (x, u, p)


@pytest.mark.parametrize("law", HIP_LAWS.values(), ids=HIP_LAWS)
def test_the_guards_and_resets_are_the_descriptions_transitions(law):
    physics = Physics.of(law)
    theta_td = law.controls.index("theta_td")
    for x, u, p in _samples(law, 50):
        xf = np.asarray(dynamics.liftoff_map(x, p)).ravel()
        assert float(physics.guard("bottom", x, u, p)) == STANCE.get(x, "rhodot")
        assert float(physics.guard("liftoff", x, u, p)) == pytest.approx(STANCE.get(x, "rho") - PARAMS.get(p, "rho0"))
        assert float(physics.guard("touchdown", xf, u, p)) == float(dynamics.touchdown_guard(xf, u[theta_td], p))
        assert np.array_equal(np.asarray(physics.reset("liftoff", x, u, p)).ravel(), xf)
        touchdown = np.asarray(physics.reset("touchdown", xf, u, p)).ravel()
        assert np.array_equal(touchdown, np.asarray(dynamics.touchdown_map(xf, u[theta_td], p)).ravel())


def test_the_clearances_are_the_descriptions_stance_falls_in_the_engines_order():
    law = HIP_LAWS["pd"]
    physics = Physics.of(law)
    assert CLEARANCE_FALLS == ("CoM touches the ground", "hip touches the ground", "leg collapses")
    for x, u, p in _samples(law, 50):
        com, hip, leg = np.asarray(physics.clearances(x, u, p)).ravel()
        q = ca.DM(x[:3])
        assert com == float(dynamics.stance_com_position(q, ca.DM(p))[1])
        assert hip == float(dynamics.stance_hip_position(q)[1])
        assert leg == pytest.approx(STANCE.get(x, "rho") - 0.05 * PARAMS.get(p, "rho0"))


def test_symbolic_callers_get_the_flow_and_guards_inlined():
    law = HIP_LAWS["vpp"]
    physics = Physics.of(law)
    x, u, p = STANCE.sym("x", ca.MX), law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
    for expression in (physics.stance_rate(x, u, p), physics.guard("touchdown", FLIGHT.sym("xf", ca.MX), u, p)):
        assert not expression.is_output()  # an output of a call node would be
    height = physics.guard("touchdown", np.array([0.0, 0.3, math.pi / 2, 1.0, -1.0, 0.0]), np.array([0.0, 0.2]),
                           Params().vector())
    assert isinstance(height, ca.DM)


@pytest.mark.parametrize("law", HIP_LAWS.values(), ids=HIP_LAWS)
def test_flight_is_the_descriptions_closed_form_flow_the_engines_ballistic_flight_to_the_bit(law):
    physics = Physics.of(law)
    for x, u, p in _samples(law, 50):
        xf = np.asarray(dynamics.liftoff_map(x, p)).ravel()
        for t in (0.0, 0.013, 0.4):
            ours = np.asarray(physics.flight(xf, t, u, p)).ravel()
            assert np.array_equal(ours, np.asarray(dynamics.ballistic_flight(ca.DM(xf), t, ca.DM(p))).ravel())
