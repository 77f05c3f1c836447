"""Specification of the atlas's corrector (:mod:`baslip.numerics.corrector`): it lands on
the manifold within the predicting chart's hyperplane; Broyden's update spares Jacobians
(one at the solution, for its tangent, where the chart's own is good enough to start
from); a system's rough evaluation does the far steps and F itself the last ones and the
test of convergence; a step that plain Newton would overshoot is damped; a seed is
projected onto the manifold; each reason for giving up names its kind of edge."""

import math

import numpy as np
import pytest

from baslip.numerics.corrector import (
    DIVERGED,
    SINGULAR_FOLD,
    SINGULAR_RANK,
    Evaluation,
    broyden_update,
    correct,
    kind_of,
    project_seed,
)


class Sphere:
    """|w|^2 = 1 in R^3, counting its evaluations and Jacobians."""

    def __init__(self):
        self.evaluations = self.jacobians = 0

    def evaluate(self, w):
        self.evaluations += 1
        return Evaluation(np.array([w @ w - 1.0]))

    def jacobian(self, w):
        self.jacobians += 1
        return 2 * w[None, :]

    def outside(self, w):
        return ""

    def solved(self, w, residual):
        return abs(residual[0]) <= 1e-14


class RoughSphere(Sphere):
    """The sphere, with a rough evaluation off by a fixed 1e-8: the corrector must still
    end at |F| <= 1e-14, which only the exact evaluation can tell."""

    rough_error = 1e-8

    def __init__(self):
        super().__init__()
        self.rough = 0

    def evaluate_roughly(self, w):
        self.rough += 1
        return Evaluation(np.array([w @ w - 1.0 + 1e-8]))


def chart_at(point):
    """The tangent basis of the unit sphere at ``point`` (columns)."""
    _, _, vt = np.linalg.svd(point[None, :])
    return vt[1:].T


def predicted(system, angle):
    """A chart at (1, 0, 0) and the point ``angle`` [rad] along its first tangent direction."""
    centre = np.array([1.0, 0.0, 0.0])
    tangent = chart_at(centre)
    return centre, tangent, centre + angle * tangent[:, 0]


def test_the_corrector_lands_on_the_manifold_in_the_charts_hyperplane():
    system = Sphere()
    centre, tangent, target = predicted(system, 0.4)
    w, jacobian, steps = correct(system, target, tangent, system.jacobian(centre), 30)
    assert abs(w @ w - 1) <= 1e-14
    assert np.allclose(tangent.T @ (w - target), 0, atol=1e-14)
    assert np.allclose(jacobian, 2 * w[None, :])  # dF/dw at the solution, for its tangent
    assert steps >= 1


def test_broyden_updates_spare_jacobians_where_the_charts_own_is_good_enough():
    """From a chart's Jacobian 0.4 rad away, the updates converge with none fresh: the one
    Jacobian taken is at the solution."""
    system = Sphere()
    centre, tangent, target = predicted(system, 0.4)
    start = system.jacobian(centre)
    system.jacobians = 0
    found = correct(system, target, tangent, start, 30)
    assert not isinstance(found, str)
    assert system.jacobians == 1
    assert system.evaluations <= 8


def test_a_rough_evaluation_does_the_far_steps_and_f_itself_the_last():
    system = RoughSphere()
    centre, tangent, target = predicted(system, 0.4)
    found = correct(system, target, tangent, system.jacobian(centre), 30)
    assert not isinstance(found, str)
    w = found[0]
    assert abs(w @ w - 1) <= 1e-14  # the exact F decided convergence, not the rough one
    assert system.rough >= 2 and system.evaluations <= 3


def test_broydens_update_meets_the_secant_equation_and_changes_nothing_across_the_step():
    rng = np.random.default_rng(0)
    jacobian, step, change = rng.normal(size=(4, 6)), rng.normal(size=6), rng.normal(size=4)
    updated = broyden_update(jacobian, step, change)
    assert np.allclose(updated @ step, change)
    across = rng.normal(size=6)
    across -= (across @ step) / (step @ step) * step
    assert np.allclose(updated @ across, jacobian @ across)
    assert broyden_update(jacobian, np.zeros(6), change) is jacobian


class Arctangent:
    """atan(x) = 0 in R^2: the line x = 0, on which plain Newton from |x| > 1.39 diverges
    (each step overshoots further), the classic case for a damped step."""

    def evaluate(self, w):
        return Evaluation(np.array([math.atan(w[0])]))

    def jacobian(self, w):
        return np.array([[1.0 / (1.0 + w[0] ** 2), 0.0]])

    def outside(self, w):
        return ""

    def solved(self, w, residual):
        return abs(residual[0]) <= 1e-13


def test_the_corrector_damps_a_step_that_plain_newton_would_overshoot():
    system, tangent = Arctangent(), np.array([[0.0], [1.0]])
    x = 2.0
    for _ in range(3):  # plain Newton from x = 2: |x| grows every step
        x -= math.atan(x) * (1 + x**2)
    assert abs(x) > 100
    found = correct(system, np.array([2.0, 0.3]), tangent, system.jacobian(np.zeros(2)), 20)
    assert not isinstance(found, str), found
    w, _, _ = found
    assert abs(w[0]) <= 1e-13 and w[1] == pytest.approx(0.3, abs=1e-15)  # on the line, in the chart's hyperplane


def test_a_fold_of_the_projection_is_a_singular_chart():
    """Correcting (1.2, 0, 0) onto the sphere within a plane spanned by x and z (one that
    the sphere's normal there lies in: the sphere folds over it) is a singular system."""
    system = Sphere()
    found = correct(system, np.array([1.2, 0.0, 0.0]), np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]]),
                    system.jacobian(np.array([1.0, 0.0, 0.0])), 10)
    assert found == SINGULAR_FOLD


def test_a_seed_is_projected_onto_the_manifold():
    system = Sphere()
    w, jacobian = project_seed(system, np.array([1.3, -0.4, 0.2]))
    assert abs(w @ w - 1) <= 1e-14 and np.allclose(jacobian, 2 * w[None, :])


@pytest.mark.parametrize("reason, kind", [(SINGULAR_FOLD, "singular"), (SINGULAR_RANK, "singular"),
                                          (DIVERGED, "corrector"), ("Newton did not converge in 20 iterations", "corrector"),
                                          ("a fall: no touchdown", "domain"), ("leaves the bounds of Kp", "domain")])
def test_each_reason_names_its_kind_of_edge(reason, kind):
    assert kind_of(reason) == kind
