"""Specification of the compiled stride engine (baslip.engine.kernels, baslip.engine.driver) behind
``ReturnMap()``: as accurate as a tight adaptive reference over the design box, the same
falls, the same numbers in C and in CasADi's virtual machine, exact Jacobians.
"""

import math

import casadi as ca
import numpy as np
import pytest

from baslip import Fall, Params, ReturnMap, Tolerances
from baslip.engine.driver import (
    RICHARDSON_SAFETY,
    first_tiers,
    first_tiers_many,
    hermite_root,
    richardson_error,
    scout_step,
)
from baslip.engine.kernels import DIAGNOSTICS, TIERS, stiffness_rate
from baslip.engine.kernels import hermite_root as hermite_root_in_graph
from baslip.engine.outcome import precheck

PARAMS = Params()


@pytest.fixture(scope="module")
def compiled():
    return ReturnMap(Tolerances(1e-12, 1e-12))


@pytest.fixture(scope="module")
def reference():
    """The adaptive erk event map at rtol = atol = 1e-13."""
    return ReturnMap(Tolerances(1e-13, 1e-13))


def design_box(rng, n: int, Kd_high: float = 30.0):
    """Random (X, u) over the design box: hanging to upright trunks, spins up to
    15 rad/s, Kp up to 20 N m/rad, Kd up to ``Kd_high`` N m s/rad."""
    for _ in range(n):
        X = np.array([rng.uniform(0.25, 0.8), rng.uniform(-math.pi, math.pi), rng.uniform(-1, 3), rng.uniform(-15, 15)])
        u = np.array([rng.uniform(-20, 20), rng.uniform(0, Kd_high), rng.uniform(-math.pi, math.pi),
                      rng.uniform(-5, 5), rng.uniform(-0.6, 0.6)])
        yield X, u


GAIT_X = np.array([0.4, -1.5657, 0.5, 0.164274])  # near the shipped downward gait
GAIT_U = np.array([-0.751879, 1.50002, -0.05246, 1.42038, 0.11471])


def relative_gap(a, b) -> float:
    return float(np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b))))


def test_default_map_is_the_compiled_engine():
    assert ReturnMap().plugin == "compiled"
    assert ReturnMap(Tolerances(1e-13, 1e-13)).plugin == "erk"


@pytest.mark.parametrize("tolerance", [1e-10, 1e-12])
def test_compiled_strides_match_the_tight_reference_over_the_design_box(reference, tolerance):
    """Every stride the compiled engine vouches for is within the tolerance of the
    reference, and so is its error estimate; the rest go to the event map."""
    compiled = ReturnMap(Tolerances(tolerance, tolerance))
    rng = np.random.default_rng(8)
    checked = 0
    for X, u in design_box(rng, 250):
        before = compiled.fallbacks
        ours, theirs = compiled.stride(X, u, PARAMS), reference.stride(X, u, PARAMS)
        assert ours.fall == theirs.fall
        if ours.ok and compiled.fallbacks == before:
            assert ours.error <= tolerance
            assert relative_gap(ours.apex, theirs.apex) <= tolerance
            checked += 1
    assert checked >= 30  # the compiled engine, not its fallback, carried the test


def passes_of(engine, X, u, params):
    """{step count: next apex and phase durations, stacked} of every final pass of the
    stride from ``X``, on the grid of the pass the engine accepts; None if it accepts none."""
    p = params.vector()
    settled = engine.settled_pass(X, u, p, precheck(X, u, p)[1])
    if settled is None:
        return None
    return {n: np.concatenate([o.ravel() for o in engine.functions.final(n)(X, u, p, settled[1])[:2]]) for n in TIERS}


def test_richardson_estimate_bounds_the_error_over_the_design_box(compiled):
    """For every two neighbouring step counts at random points of the design box, the
    Richardson estimate of the finer pass, made without its safety factor, is at least a
    third of its true error (against 1,024 steps a phase) wherever that error is above
    round-off: the factor of 5 covers it."""
    rng = np.random.default_rng(21)
    engine, ratios = compiled.compiled_engine, []
    for X, u in design_box(rng, 400):
        passes = passes_of(engine, X, u, PARAMS)
        if passes is None or not np.all(np.isfinite(passes[512])) or relative_gap(passes[512], passes[1024]) > 1e-14:
            continue  # no accepted pass, or no converged reference
        for coarse, fine in zip(TIERS[:-3], TIERS[1:-2]):
            error = relative_gap(passes[fine], passes[1024])
            if error > 1e-13 and np.all(np.isfinite(passes[coarse])):
                estimate = float(richardson_error(passes[fine], passes[coarse], coarse, fine)) / RICHARDSON_SAFETY
                ratios.append(error / estimate)
    assert len(ratios) >= 200
    assert max(ratios) <= RICHARDSON_SAFETY
    assert np.median(ratios) == pytest.approx(1.0, abs=0.1)  # the estimate is sharp, not just safe


def test_a_pass_whose_own_estimate_is_too_cautious_is_accepted_by_richardson():
    """Near the downward gait at 1e-10, the DOP853 estimate of 24 steps a phase is above the
    tolerance although the pass is within 1e-11 of the reference: the Richardson estimate
    against 16 steps accepts it, and the stride reports that estimate."""
    X, u = [0.4, -1.5657, 0.5, 0.164274], [-0.751879, 1.50002, -0.05246, 1.42038, 0.11471]
    rmap = ReturnMap(Tolerances(1e-10, 1e-10))
    engine, p = rmap.compiled_engine, PARAMS.vector()
    n, guesses = engine.settled_pass(X, u, p, precheck(X, u, p)[1])
    own = engine.judge(*engine.functions.final(n)(X, u, p, guesses))
    passes = passes_of(engine, X, u, PARAMS)
    stride = rmap.stride(X, u, PARAMS)
    assert n == 24 and own == "refine"
    assert stride.error == float(richardson_error(passes[24], passes[16], 16, 24)) <= 1e-10
    assert relative_gap(stride.apex, ReturnMap(Tolerances(1e-13, 1e-13)).stride(X, u, PARAMS).apex) <= 1e-11


#: Points of a stability descent among fast-swinging upright gaits at (0.7 m/s, 0.45 m):
#: the trunk turns at 3 to 7 rad/s at the apex under Kp = 10 to 23 N m/rad. The scout's
#: bottom estimate is too far for the final pass's Newton steps on that event to converge.
SWINGING = [([0.45, 1.0987949001, 0.7, -3.3819619645], [14.5909986358, 0.1650005595, 3.62359531, 0.0, 0.3804381364]),
            ([0.45, 1.277701489, 0.7, -4.4190986299], [9.7887295016, 0.1884309893, 3.9859324943, 0.0, 0.409627831]),
            ([0.45, 1.04722664, 0.7, -6.566213599], [22.8710047924, 0.3003288542, 4.4560674708, 0.0, 0.4095734948])]


@pytest.mark.parametrize("X, u", SWINGING)
def test_a_pass_whose_event_newton_is_unsettled_is_taken_again_from_its_own_durations(compiled, reference, X, u):
    """The first pass leaves the bottom event's Newton update unconverged; the engine
    takes the pass again from that pass's own durations and vouches for the stride and its
    Jacobian (no event-map fallback), within the tolerance of the tight reference."""
    engine, p = compiled.compiled_engine, PARAMS.vector()
    X, u = np.array(X), np.array(u)
    lowest, start, guesses = engine._plan(X, u, p, precheck(X, u, p)[1])
    first = engine.judge(*engine.functions.final(TIERS[start])(X, u, p, guesses))
    assert first is None  # the first pass alone could not be vouched for
    before = compiled.fallbacks
    ours = compiled.stride(X, u, PARAMS)
    jacobians = compiled.all_jacobians(X, u, PARAMS)
    assert compiled.fallbacks == before
    assert relative_gap(ours.apex, reference.stride(X, u, PARAMS).apex) <= 1e-12
    # The Jacobian is that of the pass taken again (its own event guesses), not of the first.
    for a, b in zip(jacobians, reference.all_jacobians(X, u, PARAMS)):
        assert np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b))) <= 1e-8


def assert_vouched_as_the_reference(compiled, reference, X, u):
    """The engine vouches for the stride and its Jacobian (no event-map fallback), with
    the reference's phase durations, its apex within the tolerance and its Jacobians
    within 1e-8."""
    before = compiled.fallbacks
    ours, theirs = compiled.stride(X, u, PARAMS), reference.stride(X, u, PARAMS)
    jacobians = compiled.all_jacobians(X, u, PARAMS)
    assert compiled.fallbacks == before
    assert relative_gap(ours.apex, theirs.apex) <= 1e-12
    for phase, duration in theirs.durations.items():
        assert ours.durations[phase] == pytest.approx(duration, abs=1e-9)
    for a, b in zip(jacobians, reference.all_jacobians(X, u, PARAMS)):
        assert np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b))) <= 1e-8


#: Points of a stability descent at (0.3 m/s, 0.35 m) under Kp = 25 to 31 N m/rad with the
#: trunk spinning back at 3.1 to 3.7 rad/s: rho turns back up for a moment early in
#: compression, between two nodes of the scout, which finds only the later bottom.
DOUBLE_BOTTOM = [([0.35, 1.1213, 0.3, -3.2622], [27.7463, 0.1484, 3.2585, 0.0, 0.2704]),
                 ([0.35, 1.0864, 0.3, -3.6523], [31.107, 0.1608, 3.294, 0.0, 0.2842]),
                 ([0.35, 1.1486, 0.3, -3.1367], [25.086, 0.1231, 3.2388, 0.0, 0.2632])]


@pytest.mark.parametrize("X, u", DOUBLE_BOTTOM)
def test_a_bottom_the_scout_missed_is_found_by_a_finer_scout(compiled, reference, X, u):
    """The first plan's final pass sees rhodot >= 0 in compression, so it cannot vouch for
    the stride, at any step count; a scout in finer steps finds the first bottom, and the
    engine vouches for the stride and its Jacobian (no event-map fallback), with the
    reference's phase durations and within the tolerance of its apex."""
    engine, p = compiled.compiled_engine, PARAMS.vector()
    X, u = np.array(X), np.array(u)
    lowest, start, guesses = engine._plan(X, u, p, precheck(X, u, p)[1])
    diagnostics = engine.functions.final(TIERS[start])(X, u, p, guesses)[2]
    assert DIAGNOSTICS.to_dict(np.asarray(diagnostics).ravel())["rhodot_max_compression"] >= 0.0
    assert_vouched_as_the_reference(compiled, reference, X, u)


#: Apexes of the re-solved runner 32 times the tracking study's perturbation from the
#: upright gait: the controller has raised Kd to 16.6 N m s/rad (Kd / I about 5,000 /s).
#: The scout's coarse steps put the liftoff 44 to 50 ms early (its own error estimate
#: is above 3), so the final pass at the step count it plans ends in NaN.
STIFF_HIP = [([0.6901204682, 1.5267008492, 0.511179445, 0.1342355046],
              [-25.3011018625, 16.5567672228, -6.2831853072, -13.1280428446, 0.1121453337]),
             ([0.7367690575, 1.5320613908, 0.5142149596, 0.1318655514],
              [-15.9743808784, 16.6907519489, -6.2831853072, -7.8544400165, 0.1102300593])]


@pytest.mark.parametrize("X, u", STIFF_HIP)
def test_events_the_scout_left_rough_are_found_by_a_finer_scout(compiled, reference, X, u):
    """The first plan's final pass cannot vouch for its events (they end in NaN); a
    scout in finer steps finds them, and the engine vouches for the stride and its
    Jacobian (no event-map fallback), with the reference's phase durations and within the
    tolerance of its apex."""
    engine, p = compiled.compiled_engine, PARAMS.vector()
    X, u = np.array(X), np.array(u)
    lowest, start, guesses = engine._plan(X, u, p, precheck(X, u, p)[1])
    assert not np.all(np.isfinite(engine.functions.final(TIERS[start])(X, u, p, guesses)[1]))
    assert_vouched_as_the_reference(compiled, reference, X, u)


@pytest.mark.parametrize("Kd", [5.0, 30.0, 100.0])
def test_stiff_hip_damping(compiled, reference, Kd):
    """Kd / (I + m d^2) up to 20,000 /s: more steps, or the fallback, never a wrong apex."""
    X, u = [0.4, -math.pi / 2 + 0.02, 0.5, 0.1], [0.5, Kd, -0.05, 1.4, 0.12]
    ours, theirs = compiled.stride(X, u, PARAMS), reference.stride(X, u, PARAMS)
    assert ours.ok and theirs.ok
    assert relative_gap(ours.apex, theirs.apex) <= 1e-12


@pytest.mark.parametrize("drop", [1e-3, 1e-5, 1e-7, 1e-9])
def test_grazing_touchdown_matches_the_vertical_hop_closed_form(compiled, drop):
    """A drop of ``drop`` metres onto the leg: rhodot at touchdown near 0, stance times known.

    rho then peaks only about ``drop`` above rho0, for a fraction of a scout step: the
    liftoff is the first crossing, not one several oscillations later. (The adaptive erk
    reference at 1e-13 itself misses it at a 1e-8 m drop.)"""
    p = PARAMS
    z = p.rho0 + p.d + drop
    stride = compiled.stride([z, math.pi / 2, 0.0, 0.0], [0, 0, 0, 0, 0], p)
    omega = math.sqrt(p.k / p.m)
    v_touchdown = -math.sqrt(2 * p.g * drop)
    t_bottom = (math.pi + math.atan2(v_touchdown / omega, p.m * p.g / p.k)) / omega
    assert abs(stride.durations["compression"] - t_bottom) <= 1e-12
    assert abs(stride.apex[0] - z) <= 1e-12


def test_5000_random_strides_end_in_an_apex_or_a_named_fall(compiled, reference):
    """A broad box (drops from 0.05 to 3 m, spins to 15 rad/s, any body angle): no call
    raises or returns NaN; every fifth is also run by the reference, with the same outcome
    and, for an apex, the same apex within 1e-10."""
    rng = np.random.default_rng(11)
    outcomes = set()
    for i in range(5000):
        X = np.array([rng.uniform(0.05, 3.0), rng.uniform(-math.pi, math.pi), rng.uniform(-3, 3), rng.uniform(-15, 15)])
        u = np.array([rng.uniform(-20, 20), rng.uniform(0, 2), rng.uniform(-math.pi, math.pi),
                      rng.uniform(-5, 5), rng.uniform(-0.6, 0.6)])
        ours = compiled.stride(X, u, PARAMS)
        assert (ours.fall is None and np.all(np.isfinite(ours.apex))) or (ours.fall in Fall and ours.apex is None)
        outcomes.add(ours.fall)
        if i % 5 == 0:
            theirs = reference.stride(X, u, PARAMS)
            assert ours.fall == theirs.fall
            if ours.ok:
                assert relative_gap(ours.apex, theirs.apex) <= 1e-10
    assert {None, Fall.FOOT_BELOW_GROUND, Fall.COM_HITS_GROUND, Fall.HIP_HITS_GROUND, Fall.LEG_COLLAPSES,
            Fall.LIFTOFF_DESCENDING} <= outcomes


def test_virtual_machine_gives_the_compiled_numbers(compiled, running_point):
    X, u = running_point
    vm = ReturnMap(Tolerances(1e-12, 1e-12), compile=False)
    assert np.array_equal(vm.stride(X, u, PARAMS).apex, compiled.stride(X, u, PARAMS).apex)
    for ours, theirs in zip(vm.all_jacobians(X, u, PARAMS), compiled.all_jacobians(X, u, PARAMS)):
        assert np.allclose(ours, theirs, rtol=1e-13, atol=1e-13)


def test_jacobians_match_the_reference_and_differences(compiled, reference, running_point):
    X, u = running_point
    ours = compiled.all_jacobians(X, u, PARAMS)
    theirs = reference.all_jacobians(X, u, PARAMS)
    for a, b in zip(ours, theirs):
        assert np.max(np.abs(a - b)) <= 1e-9
    step = 1e-5
    for i in range(4):
        dX = np.zeros(4)
        dX[i] = step
        central = (compiled(X + dX, u, PARAMS) - compiled(X - dX, u, PARAMS)) / (2 * step)
        assert np.max(np.abs(central - ours[0][:, i])) <= 1e-6


def test_hermite_root_in_the_graph_is_the_scalar_one():
    """The compiled planning's Hermite root (built in the graph) and the careful path's
    (plain floats) do the same arithmetic: the same root to the bit, over 500 brackets."""
    rng = np.random.default_rng(5)
    n = 500
    t0 = rng.uniform(0, 0.2, n)
    t1 = t0 + rng.uniform(1e-4, 0.02, n)
    g0, g1 = -rng.uniform(1e-9, 1, n), rng.uniform(0, 1, n)
    dg0, dg1 = rng.normal(scale=50, size=n), rng.normal(scale=50, size=n)
    args = [ca.SX.sym(name) for name in ("t0", "t1", "g0", "g1", "dg0", "dg1")]
    root = ca.Function("root", args, [hermite_root_in_graph(*args)]).map(n)
    roots = np.asarray(root(t0, t1, g0, g1, dg0, dg1)).ravel()
    for i in range(n):
        assert roots[i] == hermite_root([t0[i], t1[i]], [g0[i], g1[i]], [dg0[i], dg1[i]])


@pytest.mark.parametrize("in_c", [True, False])
def test_compiled_planning_gives_the_careful_scout_events(in_c):
    """Where the compiled planning calls one scout call clean, the careful path's scout
    gives the same bottom, liftoff and error estimate (which picks the step count) to the
    bit, in C and in CasADi's virtual machine: a stride's final passes do not depend on
    the path that planned them."""
    engine, p = ReturnMap(Tolerances(1e-12, 1e-12), compile=in_c).compiled_engine, PARAMS.vector()
    rng = np.random.default_rng(7)
    near = [(GAIT_X + rng.normal(scale=[0.01, 0.05, 0.05, 0.2]), GAIT_U) for _ in range(60)]
    clean_seen = 0
    for X, u in near + list(design_box(rng, 120)):
        X, u = np.asarray(X, dtype=float), np.asarray(u, dtype=float)
        fallen, t_descent = precheck(X, u, p)
        if fallen is not None:
            continue
        rate = stiffness_rate(X, u, p)
        h = scout_step(p, rate)
        x_td, _, clean, bottom, liftoff, error = engine.functions.plan(X, u, p, t_descent, h)
        if clean[0, 0]:
            careful = engine._scout(x_td.ravel(), np.concatenate([u, p]), rate, h, p)
            assert (careful.bottom, careful.liftoff, careful.error) == (bottom[0, 0], liftoff[0, 0], error[0, 0])
            clean_seen += 1
    assert clean_seen >= 60


@pytest.mark.parametrize("tolerance", [1e-10, 1e-12])
def test_many_plans_at_once_are_the_single_ones(tolerance):
    """The batch path's first step counts are the single stride's, over phases, rates and
    scout estimates from easy to beyond the finest count."""
    rng = np.random.default_rng(9)
    n = 2000
    longest, rate = rng.uniform(0.01, 0.3, n), 10 ** rng.uniform(1, 4.5, n)
    error, step = 10 ** rng.uniform(-16, 0, n), 10 ** rng.uniform(-4, -2, n)
    lowest, start = first_tiers_many(longest, rate, error, step, tolerance)
    single = [first_tiers(*stride, tolerance) for stride in zip(longest, rate, error, step)]
    assert [tuple(map(int, pair)) for pair in zip(lowest, start)] == single
    assert len(set(start)) >= 8  # from the least count to none stable
