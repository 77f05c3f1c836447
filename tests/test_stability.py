"""Specification of baslip.gait.stability: multipliers, trivial ones labelled and set aside,
and the symmetry multiplier deflated (moved to 0, the others kept) for the curves: by its
spectral projector, or by its right eigenvector alone where a second +1 meets it."""

import numpy as np
import pytest

from baslip import Params
from baslip.gait.stability import classify, trivial_labels, without_symmetry_direction, without_symmetry_multiplier

NO_TORQUE = [0.0, 0.0, 0.3, 0.0, 0.1]
PD = [2.0, 0.5, 0.3, 0.0, 0.1]


def test_trivial_multipliers_follow_from_structure():
    assert trivial_labels(Params(), PD) == []
    assert trivial_labels(Params(), NO_TORQUE) == ["energy"]
    assert trivial_labels(Params(d=0.0), NO_TORQUE) == ["spin", "spin", "energy"]
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


def test_free_spin_gives_a_unit_jordan_pair_at_any_apex(tight_map):
    """d = 0, no torque: (theta_h, theta_h_dot) map as [[1, T], [0, 1]] at every apex.

    The energy multiplier is 1 only at a fixed point (see test_slip_limit.py); here, away
    from one, it is not, and so it is not labelled.
    """
    params = Params(d=0.0)
    X, u = np.array([0.35, np.pi / 2, 0.6, 0.0]), np.array(NO_TORQUE)
    jac = tight_map.jacobians(X, u, params)[0]
    np.testing.assert_allclose(jac[:, 1], [0, 1, 0, 0], atol=1e-10)  # theta_h only shifts itself
    np.testing.assert_allclose(jac[3, :], [0, 0, 0, 1], atol=1e-10)  # the spin rate is kept
    assert jac[1, 3] > 0  # ... and turns theta_h by the stride time
    labels = sorted(m.label for m in classify(jac, params, u).multipliers if m.trivial)
    assert labels == ["spin", "spin"]


def test_a_structural_label_needs_a_multiplier_near_one():
    far = classify(np.diag([1.3, 0.5, 0.2, 0.1]), Params(), NO_TORQUE)
    assert not any(m.trivial for m in far.multipliers)
    assert far.spectral_radius == pytest.approx(1.3) and not far.stable


def test_a_radius_within_the_margin_of_one_is_not_stable():
    neutral = classify(np.diag([1.0 - 1e-9, 0.5, 0.2, 0.1]), Params(), PD)
    assert not neutral.stable


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_deflation_moves_the_real_multiplier_nearest_one_to_zero_and_keeps_the_others(seed):
    rng = np.random.default_rng(seed)
    block = np.array([[0.6, -0.7], [0.7, 0.6]])  # a complex pair, 0.6 +- 0.7i
    D = np.zeros((4, 4))
    D[:2, :2], D[2, 2], D[3, 3] = block, 1.0 + 1e-4, -3.0
    V = rng.normal(size=(4, 4))
    A = V @ D @ np.linalg.inv(V)
    mu = np.sort_complex(np.linalg.eigvals(without_symmetry_multiplier(A)))
    assert mu == pytest.approx(np.sort_complex(np.array([0.0, -3.0, 0.6 + 0.7j, 0.6 - 0.7j])), abs=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_direction_deflation_moves_an_exact_one_to_zero_and_keeps_the_others(seed):
    rng = np.random.default_rng(seed)
    D = np.zeros((4, 4))
    D[:2, :2], D[2, 2], D[3, 3] = np.array([[0.6, -0.7], [0.7, 0.6]]), 1.0, -3.0
    V = rng.normal(size=(4, 4))
    A = V @ D @ np.linalg.inv(V)
    mu = np.sort_complex(np.linalg.eigvals(without_symmetry_direction(A)))
    assert mu == pytest.approx(np.sort_complex(np.array([0.0, -3.0, 0.6 + 0.7j, 0.6 - 0.7j])), abs=1e-10)


def test_at_a_double_one_the_direction_deflation_keeps_the_second_one():
    """A Jordan block at +1 (a fold of the symmetric family: the critical multiplier meets
    the structural one and their eigenvectors merge): one +1 is moved to 0, the other
    stays, so the fold's matrix A - I is singular there, as it must be."""
    J = np.array([[1.0, 1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.5, 0.0], [0.0, 0.0, 0.0, -2.0]])
    V = np.random.default_rng(3).normal(size=(4, 4))
    A = V @ J @ np.linalg.inv(V)
    mu = np.sort_complex(np.linalg.eigvals(without_symmetry_direction(A)))
    assert mu == pytest.approx(np.sort_complex(np.array([0.0, 1.0, 0.5, -2.0])), abs=1e-6)
