"""Specification of baslip.analysis.bifurcation: bifurcation curves in two parameters and the
codimension-two points on them, checked on maps whose answers are known in closed form."""

import math

import casadi as ca
import numpy as np
import pytest

from baslip.analysis.bifurcation import CurveSystem, SmoothMap, bialternate, defining_matrix, defining_seed, trace_curve
from baslip.numerics.continuation import Settings


def smooth(size, expression):
    x, p = ca.SX.sym("x", size), ca.SX.sym("p", 2)
    return SmoothMap(ca.Function("f", [x, p], [expression(x, p[0], p[1])]))


def trace(base, kind, start, first_range, second_range, max_points=400):
    settings = Settings(step=0.05, max_step=0.1, max_points=max_points, lam_range=second_range,
                        other_ranges=((-2, *first_range),))
    return trace_curve(CurveSystem(base, kind), np.array(start, dtype=float), settings)


def specials(branch):
    return {p.special: p.v for p in branch.special}


# The Henon map (x, y) -> (1 + y - a x^2, b x): its fixed points fold on a = -(1 - b)^2/4,
# double their period on a = 3 (1 - b)^2/4, and have multipliers with product -b, so that
# b = -1 is a Neimark-Sacker curve (a neutral saddle where the pair is real).
HENON = smooth(2, lambda x, a, b: ca.vertcat(1 + x[1] - a * x[0] ** 2, b * x[0]))


def henon_fixed_point(a, b):
    x = (-(1 - b) + math.sqrt((1 - b) ** 2 + 4 * a)) / (2 * a)
    return [x, b * x]


def test_bialternate_product_has_the_pairwise_products_as_eigenvalues():
    A = np.random.default_rng(1).normal(size=(4, 4))
    mu = np.linalg.eigvals(A)
    products = sorted((mu[i] * mu[j] for i in range(4) for j in range(i)), key=lambda z: (z.real, z.imag))
    found = sorted(np.linalg.eigvals(bialternate(A)), key=lambda z: (z.real, z.imag))
    assert np.allclose(found, products, atol=1e-10)


@pytest.mark.parametrize("kind, a, b", [("fold", -0.12, 0.3), ("period_doubling", 0.3675, 0.3),
                                         ("neimark_sacker", 0.5, -1.0)])
def test_the_test_functions_gradient_is_that_of_differences_of_the_residual(kind, a, b):
    """The curve's last Jacobian row, from the seed on the map Jacobian and the map's own
    second derivatives, against central differences of g: near each Henon curve."""
    curve = CurveSystem(HENON, kind)
    v = np.array([*henon_fixed_point(a, b), a, b]) + 1e-3
    jacobian = curve.jacobian(v)
    h = 1e-6
    differenced = np.array([(curve.residual(v + h * e)[-1] - curve.residual(v - h * e)[-1]) / (2 * h)
                            for e in np.eye(len(v))])
    assert np.allclose(jacobian[-1], differenced, rtol=1e-7, atol=1e-8)


def test_a_seed_of_a_quadratic_defining_matrix_is_exact_with_a_unit_step():
    """The bialternate product is quadratic in A, so the central difference with a unit step
    is its derivative: it agrees with small steps, which carry truncation error only."""
    rng = np.random.default_rng(2)
    A, phi, psi = rng.normal(size=(4, 4)), rng.normal(size=6), rng.normal(size=6)
    matrix = lambda R: defining_matrix("neimark_sacker", R)  # noqa: E731
    exact = defining_seed(matrix, A, phi, psi, quadratic=True)
    small = np.empty_like(A)
    for index in np.ndindex(*A.shape):
        shift = np.zeros_like(A)
        shift[index] = 1e-5
        small[index] = psi @ (matrix(A + shift) - matrix(A - shift)) @ phi / 2e-5
    assert np.allclose(exact, small, rtol=1e-7, atol=1e-9)


def test_henon_period_doubling_curve_and_its_1_2_resonance():
    a0 = 0.75 * 0.7**2 + 1e-3  # off the curve: the start is pulled onto it
    curve = trace(HENON, "period_doubling", [*henon_fixed_point(a0, 0.3), a0, 0.3], (-3, 5), (-1.5, 0.9))
    assert curve.stop_reason == "lower end: end of range; upper end: end of range"
    assert len(curve.points) > 50
    errors = [abs(p.v[2] - 0.75 * (1 - p.v[3]) ** 2) for p in curve.points]
    assert max(errors) < 1e-6
    b_values = [p.v[3] for p in curve.points]
    assert min(b_values) == pytest.approx(-1.5, abs=1e-12) and max(b_values) == pytest.approx(0.9, abs=1e-12)
    # A double -1 at b = -1 (the determinant -b is then 1): a = 3.
    assert specials(curve)["resonance_1_2"][2:] == pytest.approx([3.0, -1.0], abs=1e-6)


def test_henon_fold_curve_and_its_bogdanov_takens_point():
    a0 = -0.25 * 0.7**2
    x0 = -0.7 / (2 * a0)
    curve = trace(HENON, "fold", [x0, 0.3 * x0, a0 - 1e-3, 0.3], (-3, 5), (-1.5, 0.9))
    assert max(abs(p.v[2] + 0.25 * (1 - p.v[3]) ** 2) for p in curve.points) < 1e-6
    assert specials(curve)["bogdanov_takens"][2:] == pytest.approx([-1.0, -1.0], abs=1e-6)


def test_henon_neimark_sacker_curve_and_its_resonances():
    x0 = (-1 + math.sqrt(1.5)) / 0.5
    curve = trace(HENON, "neimark_sacker", [x0, -x0, 0.5, -1 + 1e-3], (-1.5, 3.5), (-1.5, -0.5), max_points=600)
    assert max(abs(p.v[3] + 1) for p in curve.points) < 1e-9
    found = specials(curve)
    # kappa = cos(theta) = 1 - sqrt(1 + a) on b = -1: 1:1 at a = -1, 1:4 at 0, 1:3 at 5/4, 1:2 at 3.
    expected = {"resonance_1_1": -1.0, "resonance_1_4": 0.0, "resonance_1_3": 1.25, "resonance_1_2": 3.0}
    assert set(found) == set(expected)
    for label, a in expected.items():
        assert found[label][2] == pytest.approx(a, abs=1e-6), label
    kinds = {CurveSystem(HENON, "neimark_sacker").on_curve(p.v) for p in curve.points}
    assert kinds == {"neimark_sacker", "neutral_saddle"}


def test_a_rotation_map_has_its_neimark_sacker_curve_on_a_b_equal_1():
    # About the fixed point (a, b): the linear part is a b times a rotation by a.
    def rotation(x, a, b):
        u, v = x[0] - a, x[1] - b
        return ca.vertcat(a + a * b * (ca.cos(a) * u - ca.sin(a) * v) + u * v,
                          b + a * b * (ca.sin(a) * u + ca.cos(a) * v) + u**2)

    curve = trace(smooth(2, rotation), "neimark_sacker", [1.0, 1.0, 1.0, 1.001], (0.2, 3.0), (0.2, 5.0))
    assert max(abs(p.v[2] * p.v[3] - 1) for p in curve.points) < 1e-9
    found = specials(curve)
    assert found["resonance_1_4"][2] == pytest.approx(math.pi / 2, abs=1e-7)
    assert found["resonance_1_3"][2] == pytest.approx(2 * math.pi / 3, abs=1e-7)


def test_cusp_on_the_fold_curve_of_its_normal_form():
    # x -> x + a + b x - x^3 folds on a = -+2 (b/3)^(3/2); the two fold curves meet at a cusp at 0.
    x0 = math.sqrt(0.1)
    curve = trace(smooth(1, lambda x, a, b: x + a + b * x - x**3), "fold", [x0, x0**3 - 0.3 * x0, 0.3], (-1, 1), (-0.5, 0.5))
    assert max(abs(p.v[1] ** 2 - 4 * (p.v[2] / 3) ** 3) for p in curve.points) < 1e-9
    assert specials(curve)["cusp"][1:] == pytest.approx([0.0, 0.0], abs=1e-6)


def test_generalised_period_doubling_where_the_flip_coefficient_vanishes():
    # x -> -(1 + a) x + b x^3 + x^5 flips at a = 0 with cubic coefficient c = b.
    curve = trace(smooth(1, lambda x, a, b: -(1 + a) * x + b * x**3 + x**5), "period_doubling", [0.0, 0.01, 0.3],
                  (-1, 1), (-0.5, 0.5))
    # Located by a third difference of the Jacobian, whose truncation error
    # (h^2 f^(5) / 12 at h = 1e-3) moves the point by 1.7e-6.
    assert specials(curve)["generalised_period_doubling"][1:] == pytest.approx([0.0, 0.0], abs=3e-6)


def test_fold_flip_seen_from_both_curves():
    # (x, y) -> (x + a - x^2, -(1 + b) y + x y): folds on a = 0 (at x = 0), where the
    # other multiplier is -(1 + b); flips on a = b^2 (at x = -b).
    fold_flip = smooth(2, lambda x, a, b: ca.vertcat(x[0] + a - x[0] ** 2, -(1 + b) * x[1] + x[0] * x[1]))
    along_fold = trace(fold_flip, "fold", [0.0, 0.0, 0.01, 0.3], (-1, 1), (-0.5, 0.5))
    along_flip = trace(fold_flip, "period_doubling", [-0.3, 0.0, 0.09, 0.3], (-1, 1), (-0.5, 0.5))
    assert specials(along_fold)["fold_flip"][2:] == pytest.approx([0.0, 0.0], abs=1e-6)
    assert specials(along_flip)["fold_flip"][2:] == pytest.approx([0.0, 0.0], abs=1e-6)
    assert max(abs(p.v[2] - p.v[3] ** 2) for p in along_flip.points) < 1e-9


def test_fold_neimark_sacker():
    # A fold in x times a pair rotating by 1 rad with modulus 1 + b: fold-NS at b = 0.
    def fold_and_rotation(x, a, b):
        return ca.vertcat(x[0] + a - x[0] ** 2,
                          (1 + b) * (ca.cos(1.0) * x[1] - ca.sin(1.0) * x[2]) + x[1] ** 2,
                          (1 + b) * (ca.sin(1.0) * x[1] + ca.cos(1.0) * x[2]))

    curve = trace(smooth(3, fold_and_rotation), "fold", [0.0, 0.0, 0.0, 0.01, 0.3], (-1, 1), (-0.5, 0.5))
    assert specials(curve).keys() == {"fold_neimark_sacker"}
    assert specials(curve)["fold_neimark_sacker"][3:] == pytest.approx([0.0, 0.0], abs=1e-6)


def test_no_codimension_two_point_is_claimed_where_there_is_none():
    # Henon's period-doubling curve for b in [0, 0.9] has no codimension-two point.
    a0 = 0.75 * 0.7**2
    curve = trace(HENON, "period_doubling", [*henon_fixed_point(a0, 0.3), a0, 0.3], (-3, 5), (0.0, 0.9))
    assert curve.special == []
