"""Specification of baslip.stability: multipliers, trivial ones labelled and set aside."""

import numpy as np
import pytest

from baslip import Params
from baslip.stability import classify, trivial_labels

NO_TORQUE = [0.0, 0.0, 0.3, 0.0, 0.1]
PD = [2.0, 0.5, 0.3, 0.0, 0.1]


def test_trivial_multipliers_follow_from_structure():
    assert trivial_labels(Params(), PD) == []
    assert trivial_labels(Params(), NO_TORQUE) == ["energy"]
    assert trivial_labels(Params(d=0.0), NO_TORQUE) == ["energy", "spin", "spin"]
    assert trivial_labels(Params(d=0.0), PD) == []


def test_radius_and_verdict_skip_trivial_multipliers():
    jac = np.diag([1.0 + 1e-9, 0.5, -0.9, 0.1])
    neutral = classify(jac, Params(), NO_TORQUE)
    assert [m.label for m in neutral.multipliers] == ["energy", None, None, None]
    assert neutral.spectral_radius == pytest.approx(0.9) and neutral.stable
    driven = classify(jac, Params(), PD)
    assert driven.spectral_radius == pytest.approx(1.0 + 1e-9) and not driven.stable


def test_complex_pair_radius():
    rotation = 1.2 * np.array([[np.cos(0.3), -np.sin(0.3)], [np.sin(0.3), np.cos(0.3)]])
    jac = np.block([[rotation, np.zeros((2, 2))], [np.zeros((2, 2)), np.diag([0.2, 0.1])]])
    result = classify(jac, Params(), PD)
    assert result.spectral_radius == pytest.approx(1.2) and not result.stable
    assert sum(1 for m in result.multipliers if m.value.imag != 0) == 2


def test_slip_limit_hop_has_three_unit_multipliers(tight_map):
    """d = 0, no torque: energy and the free spin (a Jordan pair) give three multipliers at 1."""
    params = Params(d=0.0)
    X, u = np.array([0.35, np.pi / 2, 0.6, 0.0]), np.array(NO_TORQUE)
    # Not a fixed point, but the unit multipliers are structural, present at any apex.
    jac = tight_map.jacobians(X, u, params)[0]
    np.testing.assert_allclose(jac[:, 1], [0, 1, 0, 0], atol=1e-10)  # theta_h only shifts itself
    np.testing.assert_allclose(jac[3, :], [0, 0, 0, 1], atol=1e-10)  # the spin rate is kept
    assert jac[1, 3] > 0  # ... and turns theta_h by the stride time
    result = classify(jac, params, u)
    labelled = sorted(m.label for m in result.multipliers if m.trivial)
    assert labelled == ["energy", "spin", "spin"]
