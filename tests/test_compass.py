"""Specification of baslip.analysis.compass, the derivative-free compass search:

* its directions are the axes and the pairwise diagonals, both ways (2 n^2);
* it finds the minimum of a smooth bowl, and of a kinked valley that runs obliquely to the
  axes, where no axis step descends (the diagonals do);
* a successful step doubles the next, so a long slope costs tens of trials, not hundreds;
* a trial that cannot be placed is not counted, and the search says when its budget ran out.
"""

import numpy as np
import pytest

from baslip.analysis.compass import CompassSettings, compass_directions, compass_search


def moves_on(f, domain=lambda x: True):
    """A ``move`` for compass_search over points of R^n, with value f."""
    def move(point, displacement):
        trial = point + displacement
        return (f(trial), trial, trial) if domain(trial) else None
    return move


@pytest.mark.parametrize("n", [1, 2, 3])
def test_the_directions_are_the_axes_then_the_diagonals_each_both_ways(n):
    directions = compass_directions(n)
    assert len(directions) == 2 * n * n
    assert {tuple(d) for d in directions} == {tuple(-d) for d in directions}
    assert len({tuple(d) for d in directions}) == len(directions)
    assert all(np.count_nonzero(d) == 1 for d in directions[:2 * n])
    assert all(np.count_nonzero(d) == 2 and set(np.abs(d)) <= {0.0, 1.0} for d in directions[2 * n:])


def test_it_finds_the_bottom_of_a_smooth_bowl():
    centre = np.array([0.3, -0.7])
    found = compass_search(moves_on(lambda x: float(np.sum((x - centre) ** 2))), np.zeros(2), float(centre @ centre), 2)
    assert found.converged
    assert np.linalg.norm(found.accepted[-1] - centre) < 1e-5
    assert found.value == pytest.approx(np.sum((found.accepted[-1] - centre) ** 2))


def test_it_follows_a_kinked_valley_oblique_to_the_axes():
    """On the valley floor x = y of |x - y| + 0.01 (x + y)^2, every axis step climbs: the
    kink rises by the step and the bowl falls by less. The diagonal goes down the floor."""
    def f(x):
        return abs(x[0] - x[1]) + 0.01 * (x[0] + x[1]) ** 2

    start = np.array([1.0, 1.0])
    assert all(f(start + 0.05 * d) > f(start) for d in compass_directions(2)[:4])
    found = compass_search(moves_on(f), start, f(start), 2)
    assert found.converged
    assert np.max(np.abs(found.accepted[-1])) < 1e-5


def test_a_successful_step_doubles_the_next_so_a_long_slope_is_cheap():
    """Down the slope f = x to the edge of the domain x >= -10: a fixed first step of 0.05
    would take 200 trials; doubling up to 0.4 takes about 30, then halving settles on the edge."""
    found = compass_search(moves_on(lambda x: float(x[0]), lambda x: x[0] >= -10), np.zeros(1), 0.0, 1)
    assert found.converged
    assert found.accepted[-1][0] == pytest.approx(-10, abs=2e-6)
    assert found.trials < 100


def test_trials_that_cannot_be_placed_are_not_counted():
    found = compass_search(lambda point, displacement: None, np.zeros(2), 1.0, 2)
    assert found.converged and found.trials == 0 and found.accepted == () and found.value == 1.0


def test_it_says_when_the_trial_budget_ran_out():
    found = compass_search(moves_on(lambda x: float(x[0])), np.zeros(1), 0.0, 1, CompassSettings(trials=5))
    assert not found.converged
    assert found.trials == 5
    assert found.value == pytest.approx(found.accepted[-1][0]) and found.value < 0
