"""Specification of baslip.numerics.continuation: pseudo-arclength continuation and special points.

A smooth test map with known bifurcations: f(x) = mu - x^2. Its fixed points solve
x^2 + x - mu = 0, with a fold at mu = -1/4 (x = -1/2) and, on the upper branch, a
multiplier -2x that crosses -1 at x = 1/2, mu = 3/4 (period doubling). Beyond it, the
period-2 orbit is x = (1 +- sqrt(4 mu - 3)) / 2, with multiplier 4 x1 x2 = 4 (1 - mu),
which crosses -1 at mu = 5/4 (the next period doubling).
"""

import math

import numpy as np

from baslip.numerics.continuation import Settings, continue_branch, switch_branch


class QuadraticMap:
    def residual(self, v):
        x, mu = v
        return np.array([mu - x * x - x])

    def jacobian(self, v):
        x, _ = v
        return np.array([[-2 * x - 1, 1.0]])

    def multipliers(self, v):
        return np.array([complex(-2 * v[0])]), [False]


class TwiceQuadraticMap:
    """The same map applied twice: its fixed points are the period-2 orbits of f."""

    def residual(self, v):
        x, mu = v
        return np.array([mu - (mu - x * x) ** 2 - x])

    def jacobian(self, v):
        x, mu = v
        y = mu - x * x
        return np.array([[4 * x * y - 1, 1 - 2 * y]])

    def multipliers(self, v):
        x, mu = v
        return np.array([complex(4 * x * (mu - x * x))]), [False]


def run(direction, lam_range=(-1.0, 1.0), step=0.05):
    return continue_branch(QuadraticMap(), np.array([0.0, 0.0]), direction, Settings(step=step, lam_range=lam_range))


def test_period_doubling_is_located_to_1e_6():
    branch = run(+1)
    (pd,) = [p for p in branch.special if p.special == "period_doubling"]
    assert abs(pd.v[1] - 0.75) < 1e-6 and abs(pd.v[0] - 0.5) < 1e-6
    assert branch.stop_reason == "end of range"


def test_the_branch_passes_through_the_fold():
    branch = run(-1)
    (fold,) = [p for p in branch.special if p.special == "fold"]
    assert abs(fold.v[1] + 0.25) < 1e-6 and abs(fold.v[0] + 0.5) < 1e-4
    # Past the fold, lambda grows again along the lower branch x = (-1 - sqrt(1 + 4 mu)) / 2.
    after = [p.v for p in branch.points if p.v[0] < -0.6]
    assert after and all(abs(x - (-1 - math.sqrt(1 + 4 * mu)) / 2) < 1e-9 for x, mu in after)
    assert branch.stop_reason == "end of range"


def test_every_point_solves_the_equations():
    for point in run(+1).points + run(-1).points:
        assert abs(QuadraticMap().residual(point.v)[0]) <= 1e-10


def test_limits_stop_the_run():
    assert run(+1, step=0.01, lam_range=(-1, 1)).stop_reason == "end of range"
    short = continue_branch(QuadraticMap(), np.zeros(2), 1, Settings(step=0.01, max_points=5))
    assert short.stop_reason == "maximum number of points" and len(short.points) == 5


def test_switching_at_the_period_doubling_traces_the_period_2_orbits():
    pd = next(p for p in run(+1).special if p.special == "period_doubling")
    v, direction = switch_branch(TwiceQuadraticMap(), pd, 0.05, Settings())
    branch = continue_branch(TwiceQuadraticMap(), v, direction, Settings(step=0.05, lam_range=(-1.0, 1.6)))
    assert branch.stop_reason == "end of range"
    points = [p.v for p in branch.points]
    assert len(points) > 10 and max(mu for _, mu in points) > 1.5
    assert all(mu > 0.75 for _, mu in points)  # the orbit exists only past the period doubling
    for x, mu in points:
        root = math.sqrt(4 * mu - 3)
        assert min(abs(x - (1 + root) / 2), abs(x - (1 - root) / 2)) < 1e-9
    (next_pd,) = [p for p in branch.special if p.special == "period_doubling"]
    assert abs(next_pd.v[1] - 1.25) < 1e-6


def test_a_branch_point_is_located_where_the_period_2_orbits_cross():
    """Fixed points of f are fixed points of f o f too; in those equations the period
    doubling at mu = 3/4 is a branch point, where the period-2 orbits cross."""
    branch = continue_branch(TwiceQuadraticMap(), np.zeros(2), +1, Settings(step=0.05, lam_range=(-1.0, 1.0)))
    (bp,) = [p for p in branch.special if p.special == "branch_point"]
    assert abs(bp.v[1] - 0.75) < 1e-6 and abs(bp.v[0] - 0.5) < 1e-6


class CostlyQuadraticMap(QuadraticMap):
    """The test map, marked as a system whose Jacobian is costly; its calls are counted."""

    costly_jacobian = True

    def __init__(self):
        self.jacobians = self.residuals = 0

    def residual(self, v):
        self.residuals += 1
        return super().residual(v)

    def jacobian(self, v):
        self.jacobians += 1
        return super().jacobian(v)


class CountedQuadraticMap(CostlyQuadraticMap):
    costly_jacobian = False


def test_a_costly_jacobian_is_updated_from_the_last_point_with_the_same_answers():
    """Where the system's Jacobian is costly, the corrector starts from the last point's
    and updates it by Broyden's formula: the same fold and period doubling, every point
    a solution, and less than half the Jacobians a point that plain Newton takes (each
    point still needs one for its tangent and tests; 1.95 against 4.5 when written)."""
    settings = Settings(step=0.05, lam_range=(-1.0, 1.0))
    answers = {}
    for system in (CountedQuadraticMap(), CostlyQuadraticMap()):
        down = continue_branch(system, np.array([0.0, 0.0]), -1, settings)
        up = continue_branch(system, np.array([0.0, 0.0]), +1, settings)
        points = down.points + up.points
        assert all(abs(system.residual(p.v)[0]) <= 1e-10 for p in points)
        (fold,) = [p for p in down.special if p.special == "fold"]
        (pd,) = [p for p in up.special if p.special == "period_doubling"]
        answers[system.costly_jacobian] = (fold.v, pd.v, system.jacobians / len(points))
    for costly in (False, True):
        fold, pd, _ = answers[costly]
        assert np.allclose(fold, [-0.5, -0.25], atol=1e-6) and np.allclose(pd, [0.5, 0.75], atol=1e-6)
    assert answers[True][2] < 0.5 * answers[False][2]
