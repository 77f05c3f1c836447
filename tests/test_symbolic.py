"""A model description made symbolic: each part checked, and a bad description refused
with an error naming the part (issue: bad model descriptions get clear errors)."""

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from baslip.model.catalogue.slip import SLIP, stance_lagrangian
from baslip.model.description import Mode, ModelError, Section, Transition
from baslip.model.symbolic import model_functions


def with_transition(index, **changes):
    transitions = list(SLIP.transitions)
    transitions[index] = replace(transitions[index], **changes)
    return replace(SLIP, transitions=tuple(transitions))


def test_the_slip_builds_and_names_its_vectors():
    f = model_functions(SLIP)
    assert f.theta_names == ("m", "k", "l0", "g", "theta_td")
    assert f.section_states == ("y", "z", "ydot", "zdot")
    assert list(f.lift([0.9, 5.0])) == [0.0, 0.9, 5.0, 0.0]
    assert list(f.project(np.array([3.0, 0.9, 5.0, -1.0]))) == [0.9, 5.0]


def test_the_derived_stance_equations_are_the_point_mass_on_a_spring():
    """rho'' = rho theta'^2 - g cos(theta) - k/m (rho - l0); theta'' = (g sin(theta) - 2 rho' theta') / rho."""
    f = model_functions(SLIP)
    m, k, l0, g = 80.0, 2e4, 1.0, 9.81
    x = np.array([0.93, 0.2, -0.7, -4.9])
    rates = np.array(f.rhs["stance"](x, [m, k, l0, g, 0.3])).ravel()
    rho, theta, rhodot, thetadot = x
    assert rates[:2] == pytest.approx([rhodot, thetadot], abs=0)
    assert rates[2] == pytest.approx(rho * thetadot**2 - g * np.cos(theta) - k / m * (rho - l0), rel=1e-14)
    assert rates[3] == pytest.approx((g * np.sin(theta) - 2 * rhodot * thetadot) / rho, rel=1e-14)


def test_a_reset_of_the_wrong_size_is_named():
    wrong = with_transition(1, reset=lambda s, p, u: [s.rho, s.theta, s.rhodot])
    with pytest.raises(ModelError, match=r"model\.transitions\.liftoff\.reset: gives 3 values; mode 'flight'"):
        model_functions(wrong)


def test_a_reset_that_leaves_out_a_state_is_named():
    wrong = with_transition(1, reset=lambda s, p, u: {"y": 0, "z": s.rho, "ydot": 0})
    with pytest.raises(ModelError, match=r"liftoff\.reset: leaves out \['zdot'\]"):
        model_functions(wrong)


def test_a_guard_that_cannot_depend_on_the_motion_is_refused():
    wrong = with_transition(0, guard=lambda s, p, u: p.l0 - 1.5)
    with pytest.raises(ModelError, match=r"touchdown\.guard: does not depend on the mode's state, so it never fires"):
        model_functions(wrong)


def test_a_section_coordinate_that_is_not_a_state_is_named():
    wrong = replace(SLIP, section=replace(SLIP.section, coordinates=("z", "xdot")))
    with pytest.raises(ModelError, match=r"model\.section\.coordinates: 'xdot' is not a state of mode 'flight'"):
        model_functions(wrong)


def test_a_section_must_account_for_every_state_once():
    wrong = replace(SLIP, section=Section("flight", lambda s, p, u: s.zdot, -1, ("z",), ("y",), {"zdot": 0.0}))
    with pytest.raises(ModelError, match=r"left out: \['ydot'\]"):
        model_functions(wrong)


def test_a_lagrangian_without_a_rate_is_named():
    def no_spin(s, p, u):
        return p.m / 2 * s.rhodot**2 - p.k / 2 * (s.rho - p.l0) ** 2 + 0 * s.theta

    stance = Mode("stance", ("rho", "theta"), ("rhodot", "theta_dot"), lagrangian=no_spin)
    wrong = replace(SLIP, modes=(SLIP.modes[0], stance))
    with pytest.raises(ModelError, match=r"modes\.stance\.lagrangian: .* rate 'theta_dot'"):
        model_functions(wrong)


def test_a_name_the_parameters_do_not_have_is_named_with_the_part():
    def typo(s, p, u):
        return stance_lagrangian(s, p, u) + p.mass

    wrong = replace(SLIP, modes=(SLIP.modes[0], replace(SLIP.modes[1], lagrangian=typo)))
    with pytest.raises(ModelError, match=r"stance\.lagrangian: AttributeError: p \(the parameters\) has no 'mass'"):
        model_functions(wrong)


def test_a_direction_other_than_plus_or_minus_one_is_refused():
    with pytest.raises(ModelError, match=r"touchdown\.direction: must be \+1"):
        model_functions(with_transition(0, direction=0))


def test_an_order_outside_the_section_mode_is_refused():
    with pytest.raises(ModelError, match=r"model\.order: must start and end in the section's mode"):
        model_functions(replace(SLIP, order=("stance", "flight", "stance")))


def test_a_missing_transition_is_named():
    lone = replace(SLIP, transitions=(SLIP.transitions[0],))
    with pytest.raises(ModelError, match=r"no transition from 'stance' to 'flight'"):
        model_functions(lone)


def test_an_unknown_law_is_named():
    with pytest.raises(ModelError, match=r"law: 'pd' is not a law of slip"):
        model_functions(SLIP, "pd")


def test_forces_on_a_coordinate_the_mode_lacks_are_named():
    stance = replace(SLIP.modes[1], forces=lambda s, p, u: {"phi": 1.0})
    with pytest.raises(ModelError, match=r"stance\.forces: gives a force on 'phi'"):
        model_functions(replace(SLIP, modes=(SLIP.modes[0], stance)))


def test_a_transition_between_modes_of_other_states_needs_a_reset():
    wrong = with_transition(1, reset=None)
    with pytest.raises(ModelError, match=r"liftoff\.reset: is needed"):
        model_functions(wrong)


def test_the_guard_of_a_transition_is_a_casadi_function_of_the_state():
    f = model_functions(SLIP)
    touchdown = f.guards[0]
    assert isinstance(touchdown, ca.Function)
    assert float(touchdown([0, 1.0, 5, -1], [80, 2e4, 1.0, 9.81, 0.0])) == pytest.approx(0.0, abs=1e-15)
    assert isinstance(Transition("a", "b", lambda s, p, u: s.z, -1).label, str)


def with_flight_flow(flow):
    modes = tuple(replace(m, flow=flow) if m.name == "flight" else m for m in SLIP.modes)
    return replace(SLIP, modes=modes)


def ballistic(s, p, u, t):
    return {"y": s.y + s.ydot * t, "z": s.z + s.zdot * t - p.g * t**2 / 2, "ydot": s.ydot, "zdot": s.zdot - p.g * t}


def test_a_closed_form_flow_that_solves_the_equations_is_kept_as_a_function_of_time():
    f = model_functions(with_flight_flow(ballistic))
    x = np.array([0.0, 1.0, 5.0, 2.0])
    theta = f.theta({"m": 80.0, "k": 2e4, "l0": 1.0, "g": 9.81, "theta_td": 0.3})
    moved = np.array(f.flows["flight"](x, theta, 0.25)).ravel()
    assert moved == pytest.approx([1.25, 1.0 + 0.5 - 9.81 * 0.25**2 / 2, 5.0, 2.0 - 9.81 * 0.25], rel=1e-15)
    assert "stance" not in f.flows


def test_a_closed_form_flow_that_does_not_solve_the_equations_is_named():
    wrong = with_flight_flow(lambda s, p, u, t: {**ballistic(s, p, u, t), "z": s.z + s.zdot * t - p.g * t**2})
    # Its rate is off by g t: nothing at t = 0, 0.139 m/s a tenth of the body's time on.
    with pytest.raises(ModelError, match=r"model\.modes\.flight\.flow: does not solve the mode's equations of motion: "
                                         r"its rate differs from them by 0\.139 at t = 0\.0142 s"):
        model_functions(wrong)


def test_a_closed_form_flow_that_leaves_its_state_is_named():
    wrong = with_flight_flow(lambda s, p, u, t: {**ballistic(s, p, u, t), "y": s.y + s.ydot * t + 0.1})
    with pytest.raises(ModelError, match=r"model\.modes\.flight\.flow: does not start at its state: at t = 0 it moves it by 0\.1"):
        model_functions(wrong)


def test_a_closed_form_flow_of_the_wrong_states_is_named():
    wrong = with_flight_flow(lambda s, p, u, t: {"y": s.y, "z": s.z})
    with pytest.raises(ModelError, match=r"model\.modes\.flight\.flow: leaves out \['ydot', 'zdot'\]"):
        model_functions(wrong)
