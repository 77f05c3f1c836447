"""Specification of baslip.engine.batch and ReturnMap.strides / simulate_many: many strides at
once, in threads, with the outcomes of one stride at a time; where the scout's event guess
is off by more than a grid step (a strong hip torque), the batch takes the pass again from
its own durations, as one stride does, instead of handing the stride to the careful path."""

import math

import numpy as np
import pytest

from baslip import Fall, Params, ReturnMap, Tolerances
from baslip.engine.outcome import TOUCHDOWN_GRID, precheck, prechecks, strides_can_start
from baslip.model.dynamics import descent_foot_height

PARAMS = Params()
GAIT_X = np.array([0.4, -1.5657, 0.5, 0.164274])
GAIT_U = np.array([-0.751879, 1.50002, -0.05246, 1.42038, 0.11471])


@pytest.fixture(scope="module")
def rmap():
    return ReturnMap(Tolerances(1e-12, 1e-12))


def mixed_starts(n: int, seed: int = 4):
    """Starts near the downward gait and all over the box, falls included."""
    rng = np.random.default_rng(seed)
    near = GAIT_X + rng.normal(scale=[0.01, 0.05, 0.05, 0.2], size=(n // 2, 4))
    far = np.column_stack([rng.uniform(0.05, 1.0, n - n // 2), rng.uniform(-math.pi, math.pi, n - n // 2),
                           rng.uniform(-1, 2, n - n // 2), rng.uniform(-10, 10, n - n // 2)])
    U = np.repeat(GAIT_U[None], n, axis=0)
    U[n // 2 :, 0] = rng.uniform(-10, 10, n - n // 2)
    return np.vstack([near, far]), U


def test_batched_strides_are_the_single_strides(rmap):
    X, U = mixed_starts(150)
    batched = rmap.strides(X, U, PARAMS)
    outcomes = set()
    for x, u, ours in zip(X, U, batched):
        single = rmap.stride(x, u, PARAMS)
        assert ours.fall == single.fall
        outcomes.add(ours.fall)
        if ours.ok:  # the same passes, accepted by the same estimate
            assert np.array_equal(ours.apex, single.apex) and ours.error == single.error
    assert None in outcomes and len(outcomes) >= 3  # apexes and at least two kinds of fall


def test_a_stiff_torque_gait_is_batched_through_with_the_single_strides_outcomes(rmap, monkeypatch):
    """The most stable upright gait of atlas_upright (Kp = 100 N m/rad, problems/
    controllers_upright_best.yaml): the scout's liftoff guess is 2 to 17 grid steps off at
    every step count, so each final pass is taken again from its own durations. Measured:
    all 1,000 strides of a basin box were handed to the careful path before (497 strides/s
    a lane), none after (1,165 strides/s)."""
    from baslip.engine.driver import CompiledEngine

    X = np.array([0.45, 1.0969043648889636, 0.7, -7.177354936057391])
    u = np.array([100.0, 0.7166531397649274, 4.671932884432172, 0.0, 0.3628822064434824])
    gait = rmap.stride(X, u, PARAMS)  # near the gait: the guess's apex, not the fixed point itself
    assert gait.ok
    starts = gait.apex + np.random.default_rng(3).uniform(-1, 1, (64, 4)) * [0.004, 0.04, 0.04, 0.2]
    careful = []
    single_stride = CompiledEngine.stride
    monkeypatch.setattr(CompiledEngine, "stride", lambda self, *a: careful.append(1) or single_stride(self, *a))
    batched = rmap.strides(starts, u, PARAMS)
    assert not careful
    monkeypatch.undo()
    for x, ours in zip(starts, batched):
        single = rmap.stride(x, u, PARAMS)
        assert ours.fall == single.fall
        if ours.ok:
            assert np.array_equal(ours.apex, single.apex) and ours.error == single.error
    assert sum(s.ok for s in batched) > 32


def test_simulate_many_runs_each_start_as_simulate(rmap):
    X, U = mixed_starts(20, seed=9)
    runs = rmap.simulate_many(X, U, PARAMS, strides=5)
    for x, u, run in zip(X, U, runs):
        alone = rmap.simulate(x, u, PARAMS, strides=5)
        assert (run.fall, run.fall_stride) == (alone.fall, alone.fall_stride)
        assert run.apexes.shape == alone.apexes.shape
        assert np.max(np.abs(run.apexes - alone.apexes)) <= 1e-11


def test_batch_in_the_virtual_machine_matches_the_compiled_batch(rmap):
    X, U = mixed_starts(6, seed=2)
    vm = ReturnMap(Tolerances(1e-12, 1e-12), compile=False)
    for ours, theirs in zip(vm.strides(X, U, PARAMS), rmap.strides(X, U, PARAMS)):
        assert ours.fall == theirs.fall
        if ours.ok:
            assert np.array_equal(ours.apex, theirs.apex)


def test_batched_prechecks_are_the_single_prechecks():
    """The closed-form checks for many apexes at once give each apex's own fall, and the
    same touchdown guess to the bit, over a box with non-finite entries, feet below
    ground and legs that cannot reach it."""
    rng = np.random.default_rng(1)
    n = 2000
    X = np.column_stack([rng.uniform(0.0, 1.5, n), rng.uniform(-4, 4, n), rng.uniform(-3, 3, n),
                         rng.uniform(-20, 20, n)])
    U = np.column_stack([rng.uniform(-20, 20, n), rng.uniform(0, 5, n), rng.uniform(-3, 3, n),
                         rng.uniform(-5, 5, n), rng.uniform(-2, 2, n)])
    X[::97, 0], U[::89, 3] = np.nan, np.inf
    falls, guesses = prechecks(X, U, PARAMS.vector())
    seen = set()
    for x, u, fall, guess in zip(X, U, falls, guesses):
        single, single_guess = precheck(x, u, PARAMS.vector())
        assert (fall is None) == (single is None)
        if single is None:
            assert guess == single_guess
        else:
            assert fall.fall is single.fall and np.isnan(guess)
        seen.add(None if single is None else single.fall)
    assert seen == {None, Fall.NOT_FINITE, Fall.FOOT_BELOW_GROUND, Fall.NO_TOUCHDOWN}
    # The cheap test of many points (no touchdown times refined) says the same as precheck.
    assert np.array_equal(strides_can_start(X, U, PARAMS.vector()), np.array([f is None for f in falls]))


@pytest.mark.parametrize("d", [PARAMS.d, 0.0])
def test_the_touchdown_search_skips_no_root_of_the_whole_grid(d):
    """The batched touchdown search starts each row's grid where a root becomes possible
    and stops at its first root; its guesses are those of a search of every grid point, to
    the bit, also where the clearance is within round-off of the hip offset (there no grid
    point may be skipped; with d = 0, the SLIP limit, round-off decides the signs) and
    where a fast spin makes the foot height wiggle."""
    rng = np.random.default_rng(5)
    n = 3000
    p = Params(d=d).vector()
    rho0, g = PARAMS.rho0, PARAMS.g
    theta_td = rng.uniform(-1.2, 1.2, n)
    clearance = np.concatenate([rng.uniform(-0.05, 0.5, n - 300), d + rng.uniform(-1e-13, 1e-13, 100),
                                d + rng.uniform(0, 1e-6, 100), d + rng.uniform(-1e-16, 1e-16, 100)])
    X = np.column_stack([clearance + rho0 * np.cos(theta_td), rng.uniform(-4, 4, n), rng.uniform(-1, 2, n),
                         rng.choice([1.0, 30.0, 300.0], n) * rng.uniform(-1, 1, n)])
    U = np.column_stack([np.zeros((n, 4)), theta_td])
    _, guesses = prechecks(X, U, p)
    whole = 0
    for x, u, guess in zip(X, U, guesses):
        if descent_foot_height(0.0, x[0], x[1], x[3], u[-1], d, rho0, g) < 0.0:
            continue  # the foot is below ground at the apex: a fall before any search
        bound = math.sqrt(2.0 * max(x[0] - rho0 * math.cos(u[-1]) + d, 0.0) / g) + 1e-9
        grid = bound * np.linspace(0.0, 1.0, TOUCHDOWN_GRID)
        below = np.nonzero(descent_foot_height(grid[1:], x[0], x[1], x[3], u[-1], d, rho0, g) <= 0.0)[0]
        assert np.isnan(guess) == (len(below) == 0)
        if len(below):
            single = precheck(x, u, p)[1]
            assert guess == single and grid[below[0]] <= guess <= grid[below[0] + 1]
            whole += 1
    assert whole > n // 2
