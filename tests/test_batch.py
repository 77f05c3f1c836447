"""Specification of baslip.batch and ReturnMap.strides / simulate_many: many strides at
once, in threads, with the outcomes of one stride at a time."""

import math

import numpy as np
import pytest

from baslip import Fall, Params, ReturnMap, Tolerances
from baslip.batch import _events_in_one_call
from baslip.engine import MAX_SCOUT_STEP_RATE, SCOUT_STEPS_PER_HALF_PERIOD
from baslip.model import PARAMS as PARAM_LAYOUT
from baslip.outcome import precheck, prechecks
from baslip.stride import half_period, stiffness_rate

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


def test_one_scout_call_for_many_strides_gives_each_single_scout(rmap):
    """Where the batch path's event search calls one scout call clean, the single stride's
    scout gives the same bottom, liftoff and error estimate (which picks the step count)
    to the bit: both paths plan the same final passes."""
    engine, p = rmap.compiled_engine, PARAMS.vector()
    X, U = mixed_starts(300, seed=7)
    clean_seen = 0
    for x, u in zip(X, U):
        fallen, t_descent = precheck(x, u, p)
        if fallen is not None:
            continue
        x_td = engine.functions.touchdown_state(x, u, p, t_descent)[0].ravel()
        theta = np.concatenate([u, p])
        h = np.array([min(half_period(p) / SCOUT_STEPS_PER_HALF_PERIOD, MAX_SCOUT_STEP_RATE / stiffness_rate(x, u, p))])
        nodes, rates, clearance, errors = engine.functions.scout(x_td, h[0], theta)
        clean, bottom, liftoff, error = _events_in_one_call(nodes[:, None, :], rates[:, None, :], clearance[:, None, :],
                                                            errors, h, p[PARAM_LAYOUT.index("rho0")])
        if clean[0]:
            single = engine._scout(x_td, theta, x, u, p)
            assert (single.bottom, single.liftoff, single.error) == (bottom[0], liftoff[0], error[0])
            clean_seen += 1
    assert clean_seen >= 100
