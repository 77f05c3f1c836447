"""Specification of bodies that are the same runner at another size (:mod:`baslip.model.similarity`):

* the groups of the thesis body are k rho0/(m g), I/(m rho0^2) and d/rho0, and a body
  rebuilt from its groups at its own size is itself;
* carrying values to another body and back gives them back, angles unchanged;
* a gait of the thesis body carried to a body of the same groups at another size (length
  x 0.1 to 10, mass x 0.1 to 100, another gravity) is a fixed point there, with the same
  multipliers to 1e-8: the return maps are conjugate by the scaling.
"""

import math

import numpy as np
import pytest

from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.gait.knowngaits import known_gaits
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.similarity import body_with, carried, froude, groups, normalised_body

THESIS = Params()
TIGHT = Tolerances(1e-12, 1e-12)


def test_the_thesis_body_has_the_groups_of_its_definition():
    assert groups(THESIS).values() == pytest.approx((1000.0 * 0.2 / 9.81, 0.0033 / 0.04, 0.04 / 0.2), rel=1e-15)
    human = Params(m=80.0, I=4.58, k=20000.0, rho0=1.0, d=0.1, g=9.81)
    assert groups(human).stiffness == pytest.approx(20000.0 / (80.0 * 9.81), rel=1e-15)
    assert froude(3.0, human) == pytest.approx(9.0 / 9.81, rel=1e-15)


@pytest.mark.parametrize("body", [THESIS, Params(m=80.0, I=4.58, k=20000.0, rho0=1.0, d=0.1, g=9.81),
                                  Params(m=3.0, I=0.02, k=3000.0, rho0=0.3, d=0.0, g=1.62)])
def test_a_body_rebuilt_from_its_groups_at_its_own_size_is_itself(body):
    rebuilt = body_with(groups(body), size=body)
    for name in ("m", "I", "k", "rho0", "d", "g"):
        assert getattr(rebuilt, name) == pytest.approx(getattr(body, name), rel=1e-14, abs=1e-15)
    assert groups(normalised_body(body)).distance(groups(body)) < 1e-14


def test_carrying_values_there_and_back_gives_them_back_and_leaves_angles_alone():
    values = {"z": 0.4, "theta_h": -1.5, "ydot": 0.5, "theta_h_dot": 0.2, "Kp": -0.75, "Kd": 1.5, "theta2_des": 0.1,
              "theta2_dot_des": 1.4, "theta_td": 0.11, "r_vpp": 0.03, "energy": 4.0}
    far = Params(m=37.0, I=0.0033 * 37.0 * 25.0, k=1000.0 * 37.0 / 5.0, rho0=1.0, d=0.2, g=9.81)
    there = carried(values, THESIS, far)
    back = carried(there, far, THESIS)
    assert back == pytest.approx(values, rel=1e-14)
    assert there["theta_h"] == values["theta_h"] and there["theta_td"] == values["theta_td"]
    assert there["z"] == pytest.approx(2.0, rel=1e-14) and there["Kp"] == pytest.approx(-0.75 * 37.0 * 5.0, rel=1e-14)


@pytest.mark.parametrize("length, mass, gravity", [(0.1, 0.1, 9.81), (3.7, 25.0, 9.81), (10.0, 100.0, 1.62),
                                                   (0.5, 4.0, 24.8)])
def test_a_gait_carried_to_a_similar_body_has_the_same_multipliers(length, mass, gravity):
    gait = next(g for g in known_gaits() if g.name == "downward")
    size = Params(m=THESIS.m * mass, rho0=THESIS.rho0 * length, g=gravity, k=THESIS.k, I=THESIS.I, d=THESIS.d)
    body = body_with(groups(THESIS), size=size)
    rmap = ReturnMap(TIGHT, law=HIP_LAWS[gait.law])
    jacobians = []
    for params, values in ((THESIS, gait.values), (body, carried(gait.values, THESIS, body))):
        X = np.array([values[n] for n in APEX.names])
        u = np.array([values[n] for n in rmap.law.controls.names])
        apex = rmap.stride(X, u, params).apex
        assert np.linalg.norm(apex - X) / np.linalg.norm(X) < 1e-10
        jacobians.append(rmap.jacobians(X, u, params)[0])
    here, there = (np.sort_complex(np.linalg.eigvals(J)) for J in jacobians)
    assert np.max(np.abs(here - there)) < 1e-8
    assert math.isclose(max(abs(here)), 0.8990481949, rel_tol=1e-8)  # results/downward's spectral radius
