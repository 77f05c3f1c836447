"""Hip laws (:mod:`baslip.model.hiplaw`): each names its controls, ends them with theta_td,
and gives a stance torque; the VPP law's ground force passes through its pivot.

The ground force is checked against Newton's law for the trunk, m (a_CoM + g), with the
CoM's acceleration from the Lagrangian stance dynamics: independent of the virtual-work
argument that :func:`ground_force` rests on.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.engine.trajectory import motion
from baslip.model.dynamics import PARAMS, STANCE, Params, stance_com_position, stance_dynamics
from baslip.model.hiplaw import HIP_LAWS, PD, VPP, ground_force, hip_law, touchdown_angle, virtual_pivot
from baslip.model.quantities import DEFAULT_BOUNDS, DEFAULT_GUESS, NOMINAL, UNITS

#: A VPP stride that is not a fixed point: an upright trunk, the pivot 2 cm above the CoM.
APEX_UPRIGHT = np.array([0.4, math.pi / 2, 0.5, 0.0])
PARAMS_THESIS = Params()


def test_every_law_ends_its_controls_with_the_touchdown_angle_and_documents_each_control():
    for name, law in HIP_LAWS.items():
        assert law.name == name and law.controls.names[-1] == "theta_td"
        for control in law.controls.names:
            assert control in UNITS and control in NOMINAL and control in DEFAULT_BOUNDS and control in DEFAULT_GUESS
    assert touchdown_angle(np.array([0.03, 0.2])) == 0.2
    assert hip_law("vpp") is VPP
    with pytest.raises(KeyError, match="hip_law 'spring' is not one of"):
        hip_law("spring")


def test_the_pd_torque_is_the_thesis_law():
    x = np.array([0.18, 0.1, 2.9, -0.3, 1.2, -0.7])
    u = np.array([2.0, 0.3, 3.0, 0.5, 0.1])
    tau = float(PD.torque(ca.DM(x), ca.DM(u), ca.DM(PARAMS_THESIS.vector())))
    assert tau == pytest.approx(-2.0 * (2.9 - 3.0) - 0.3 * (-0.7 - 0.5), rel=1e-14)
    assert PD.torque_free({"Kp": 0.0, "Kd": 0.0}) and not PD.torque_free({"Kp": 0.0})
    assert not VPP.torque_free({"r_vpp": 0.0})


def _newton_force(x, tau, p):
    """m (a_CoM + g e_z) [N] at stance state ``x`` under torque ``tau``, from the stance
    equations of motion."""
    xs, taus, ps = STANCE.sym("x"), ca.SX.sym("tau"), PARAMS.sym("p")
    q, qdot = xs[:3], xs[3:]
    velocity = ca.jtimes(stance_com_position(q, ps), q, qdot)
    rates = stance_dynamics(xs, taus, ps)
    acceleration = ca.jtimes(velocity, xs, rates)
    m, g = PARAMS.get(ps, "m"), PARAMS.get(ps, "g")
    force = ca.Function("newton", [xs, taus, ps], [m * (acceleration + ca.vertcat(0, g))])
    return np.asarray(force(x, tau, p)).ravel()


@pytest.mark.parametrize("law, u", [(PD, np.array([1.5, 0.2, 2.9, 0.0, 0.12])), (VPP, np.array([0.02, 0.12]))])
def test_the_ground_force_is_newtons_force_on_the_trunk(law, u):
    p = PARAMS_THESIS.vector()
    x = np.array([0.185, 0.05, math.pi - 0.02, -0.4, -2.0, 1.5])
    tau = float(law.torque(ca.DM(x), ca.DM(u), ca.DM(p)))
    G = np.asarray(ground_force(ca.DM(x), tau, ca.DM(p))).ravel()
    np.testing.assert_allclose(G, _newton_force(x, tau, p), rtol=1e-12, atol=1e-12 * np.linalg.norm(G))


@pytest.fixture(scope="module")
def vpp_map():
    return ReturnMap(Tolerances(1e-12, 1e-12), law=VPP)


def _stance_rows(table):
    return [i for i, phase in enumerate(table["phase"]) if phase in ("compression", "decompression")]


def test_the_vpp_force_passes_through_the_pivot_at_every_stance_sample(vpp_map):
    u, params = np.array([0.02, 0.12]), PARAMS_THESIS
    table = motion(vpp_map, APEX_UPRIGHT, u, params, strides=1, samples=60)
    p = params.vector()
    worst, loaded = 0.0, 0
    peak = max(math.hypot(table["grf_y"][i], table["grf_z"][i]) for i in _stance_rows(table))
    for i in _stance_rows(table):
        foot_y = table["hip_y"][i] + table["leg_length"][i] * math.sin(table["leg_angle"][i])
        force = np.array([table["grf_y"][i], table["grf_z"][i]])
        if np.linalg.norm(force) < 1e-6 * peak:  # touchdown and liftoff: no force, no line
            continue
        loaded += 1
        # The pivot from the sample's own CoM and trunk angle, not from the stance state.
        pivot = (np.array([table["y"][i], table["z"][i]]) + 0.02 * np.array([math.cos(table["theta_h"][i]),
                                                                               math.sin(table["theta_h"][i])]))
        offset = pivot - np.array([foot_y, 0.0])
        worst = max(worst, abs(offset[0] * force[1] - offset[1] * force[0]) / np.linalg.norm(force))
        q = np.array([table["leg_length"][i], table["leg_angle"][i], table["theta_h"][i] + math.pi / 2 - table["leg_angle"][i]])
        np.testing.assert_allclose(np.asarray(virtual_pivot(ca.DM(q), 0.02, ca.DM(p))).ravel(), offset, atol=1e-12)
    assert loaded >= len(_stance_rows(table)) - 2 >= 100 and worst <= 1e-9


def test_with_the_pivot_at_the_com_the_trunk_spin_is_unchanged_by_stance(vpp_map):
    spin = 1.3  # rad/s at the apex, kept through flight and, with the pivot at the CoM, stance
    table = motion(vpp_map, np.array([0.4, math.pi / 2, 0.5, spin]), np.array([0.0, 0.12]), PARAMS_THESIS, 1, 60)
    rates = table["theta_h_dot"][_stance_rows(table)]
    assert np.max(np.abs(rates - spin)) <= 1e-9
    torques = table["torque"][_stance_rows(table)]
    assert np.max(np.abs(torques)) > 1e-3  # the law does work to keep the force on the CoM


def _reversed(X):
    """Mirror (y -> -y) and time reversal of an apex: (z, pi - theta_h, ydot, theta_h_dot)."""
    z, theta_h, ydot, spin = X
    return np.array([z, math.pi - theta_h, ydot, spin])


def test_a_vpp_stride_run_backwards_in_the_mirror_is_a_vpp_stride(vpp_map):
    """A law of positions only is reversible: from the mirrored, reversed end of a stride,
    with the leg placed at minus its liftoff angle, the stride ends at the mirrored,
    reversed start. This is what makes VPP gaits symmetric."""
    X, u = np.array([0.4, math.radians(95), 0.5, -0.3]), np.array([0.02, 0.12])
    table = motion(vpp_map, X, u, PARAMS_THESIS, strides=1, samples=40)
    liftoff_angle = table["leg_angle"][_stance_rows(table)[-1]]
    end = vpp_map(X, u, PARAMS_THESIS)
    back = vpp_map(_reversed(end), np.array([u[0], -liftoff_angle]), PARAMS_THESIS)
    np.testing.assert_allclose(back, _reversed(X), atol=1e-10)


def test_vpp_jacobians_match_central_differences(vpp_map):
    X, u = APEX_UPRIGHT + np.array([0.0, 0.05, 0.0, -0.1]), np.array([0.02, 0.12])
    dr_dX, dr_du = vpp_map.jacobians(X, u, PARAMS_THESIS)
    h = 1e-6
    for jac, base, which in ((dr_dX, X, "X"), (dr_du, u, "u")):
        for j in range(len(base)):
            step = np.eye(len(base))[j] * h
            plus = vpp_map(X + step, u, PARAMS_THESIS) if which == "X" else vpp_map(X, u + step, PARAMS_THESIS)
            minus = vpp_map(X - step, u, PARAMS_THESIS) if which == "X" else vpp_map(X, u - step, PARAMS_THESIS)
            np.testing.assert_allclose(jac[:, j], (plus - minus) / (2 * h), atol=1e-6, err_msg=f"d r / d {which}[{j}]")
