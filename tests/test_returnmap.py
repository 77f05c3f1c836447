"""Specification of baslip.engine.returnmap: the event-located apex return map r(X, u).

Checked against closed forms (vertical hopping), invariants (energy without torque,
mirror symmetry), finite differences of the tight map (first derivatives) and of its AD
Jacobian (second derivatives), and the named ways to fall.
"""

import math

import casadi as ca
import numpy as np
import pytest

from baslip import Fall, Params, ReturnMap, Tolerances
from baslip.engine.returnmap import NoSecondDerivatives, RunnerFell, param_vector
from baslip.model.dynamics import APEX, apex_to_flight, ballistic_flight, build_model

MODEL = build_model()


def apex_energy(X, params):
    return float(MODEL.apex_energy(X, params.vector()))


@pytest.mark.parametrize(
    "X, theta_td",
    [
        ([0.4, -math.pi / 2 + 0.02, 0.5, 0.1], 0.15),
        ([0.35, math.pi / 2 - 0.1, 0.8, -0.4], 0.2),
        ([0.5, 0.3, 0.2, 1.5], 0.05),  # trunk far from vertical, spinning
    ],
)
def test_energy_is_conserved_without_torque(tight_map, params, X, theta_td):
    u = [0.0, 0.0, 0.3, 0.0, theta_td]  # Kp = Kd = 0: no hip torque
    stride = tight_map.stride(X, u, params)
    assert stride.ok, stride.fall
    before, after = apex_energy(X, params), apex_energy(stride.apex, params)
    assert abs(after - before) / before <= 1e-9


@pytest.mark.parametrize("z", [0.26, 0.4, 0.7])
@pytest.mark.parametrize("theta_h", [math.pi / 2, -math.pi / 2])
def test_hopping_in_place_is_a_fixed_point(tight_map, params, z, theta_h):
    X = np.array([z, theta_h, 0.0, 0.0])
    apex = tight_map(X, [0.0, 0.0, 0.0, 0.0, 0.0], params)
    assert np.linalg.norm(apex - X) / np.linalg.norm(X) <= 1e-11


def test_event_times_match_the_vertical_hop_closed_form(tight_map, params):
    """Vertical hopping: stance is a linear spring-mass oscillation about rho0 - m g / k."""
    z = 0.4
    X = [z, math.pi / 2, 0.0, 0.0]
    stride = tight_map.stride(X, [0.0, 0.0, 0.0, 0.0, 0.0], params)
    drop = z - params.d - params.rho0  # CoM fall from apex to touchdown
    v_touchdown = -math.sqrt(2 * params.g * drop)
    omega = math.sqrt(params.k / params.m)
    offset = params.m * params.g / params.k  # rho0 - rho at static equilibrium
    phase = math.atan2(v_touchdown / omega, offset)
    t_bottom = (math.pi + phase) / omega
    assert stride.durations["descent"] == pytest.approx(math.sqrt(2 * drop / params.g), abs=1e-14)
    assert abs(stride.durations["compression"] - t_bottom) <= 1e-12
    assert abs(stride.durations["decompression"] - t_bottom) <= 1e-12
    assert abs(stride.durations["ascent"] - stride.durations["descent"]) <= 1e-12


def mirror_apex(X):
    z, th, ydot, thdot = X
    return np.array([z, math.pi - th, -ydot, -thdot])


def mirror_control(u):
    """theta2 maps to 2 pi - theta2 (= -theta2 modulo 2 pi). The PD law uses the plain
    difference theta2 - theta2_des, so the mirrored set point must be on the same branch."""
    kp, kd, th2, th2dot, td = u
    return np.array([kp, kd, 2 * math.pi - th2, -th2dot, -td])


def test_return_map_commutes_with_the_mirror(tight_map, params, running_point):
    X, u = running_point
    direct = mirror_apex(tight_map(X, u, params))
    mirrored = tight_map(mirror_apex(X), mirror_control(u), params)
    angle_gap = (direct[1] - mirrored[1] + math.pi) % (2 * math.pi) - math.pi
    assert abs(angle_gap) <= 1e-11
    np.testing.assert_allclose(np.delete(direct, 1), np.delete(mirrored, 1), atol=1e-11)


def test_ad_jacobians_match_central_differences(tight_map, params, running_point):
    X, u = running_point
    dr_dX, dr_du = tight_map.jacobians(X, u, params)
    h = 1e-6
    for jac, base, which in ((dr_dX, X, "X"), (dr_du, u, "u")):
        for j in range(len(base)):
            step = np.zeros(len(base))
            step[j] = h
            args_plus = (X + step, u) if which == "X" else (X, u + step)
            args_minus = (X - step, u) if which == "X" else (X, u - step)
            column = (tight_map(*args_plus, params) - tight_map(*args_minus, params)) / (2 * h)
            np.testing.assert_allclose(jac[:, j], column, atol=1e-6, err_msg=f"d r / d {which}[{j}]")


def test_event_location_is_independent_of_the_integrator(params, running_point):
    """erk and rosenbrock at 1e-12 agree on the next apex to 1e-11."""
    X, u = running_point
    erk = ReturnMap(Tolerances(1e-12, 1e-12), plugin="erk")(X, u, params)
    rosenbrock = ReturnMap(Tolerances(1e-12, 1e-12), plugin="rosenbrock")(X, u, params)
    np.testing.assert_allclose(erk, rosenbrock, atol=1e-11)


@pytest.mark.parametrize("plugin", ["erk", "rosenbrock"])
def test_event_map_strides_in_c_are_those_of_the_virtual_machine(params, running_point, plugin):
    """The event map's compiled stride gives the virtual machine's apex, durations and
    outcome, bit for bit, for a clean stride, a fall in stance and a failed integration
    (the C code's error status is the virtual machine's exception)."""
    X, u = running_point
    cases = [
        (X, u, params),
        ([3.0, math.pi / 2, 0.0, 0.0], [0, 0, 0, 0, 0.0], params),  # a 3 m drop: the leg collapses
        ([0.4, math.pi / 2, 0.5, 0.0], [2, 0.1, 0, 0, 0.1], Params(I=1e-9)),  # integrator gives up
    ]
    compiled = ReturnMap(Tolerances(1e-12, 1e-12), plugin=plugin, compile=True)
    virtual = ReturnMap(Tolerances(1e-12, 1e-12), plugin=plugin, compile=False)
    outcomes = set()
    for X_, u_, p_ in cases:
        ours, theirs = compiled.stride(X_, u_, p_), virtual.stride(X_, u_, p_)
        assert ours.fall is theirs.fall and ours.durations == theirs.durations
        assert (ours.apex is None and theirs.apex is None) or np.array_equal(ours.apex, theirs.apex)
        outcomes.add(ours.fall)
    assert {None, Fall.LEG_COLLAPSES} <= outcomes
    assert (Fall.INTEGRATION_FAILED in outcomes) == (plugin == "erk")  # rosenbrock copes with I = 1e-9


def test_stance_samples_in_c_are_those_of_the_virtual_machine(params, running_point):
    """The stance samples generated as C and cached (for the atlas's trunk ranges) are the
    virtual machine's, bit for bit, through the bottom and liftoff events."""
    X, u = running_point
    compiled = ReturnMap(Tolerances(1e-10, 1e-10), compile=True)
    virtual = ReturnMap(Tolerances(1e-10, 1e-10), plugin="erk", compile=False)  # compiles nothing
    stride = compiled.stride(X, u, params)
    flight = ca.evalf(ballistic_flight(apex_to_flight(ca.DM(X)), stride.durations["descent"], params.vector()))
    x_td = np.asarray(MODEL.touchdown_map(flight, u[-1], params.vector())).ravel()
    stance = stride.durations["compression"] + stride.durations["decompression"]
    for n in (1, 100):
        ours = compiled.stance_samples(x_td, u, params, stance, n, compiled=True)
        assert ours.shape == (6, n) and np.array_equal(ours, compiled.stance_samples(x_td, u, params, stance, n))
        assert np.array_equal(ours, virtual.stance_samples(x_td, u, params, stance, n, compiled=True))
    assert abs(ours[0, -1] - params.rho0) < 1e-9  # the last sample is the liftoff


@pytest.mark.parametrize(
    "X, u, fall",
    [
        ([0.1, math.pi / 2, 0.5, 0.0], [0, 0, 0, 0, 0.1], Fall.FOOT_BELOW_GROUND),
        ([0.4, math.pi / 2, 0.5, 0.0], [0, 0, 0, 0, math.pi / 2], Fall.NO_TOUCHDOWN),
        ([3.0, math.pi / 2, 0.0, 0.0], [0, 0, 0, 0, 0.0], Fall.LEG_COLLAPSES),
        ([0.4, math.pi / 2, 3.0, 0.0], [0, 0, 0, 0, -0.6], Fall.LEG_EXTENDING_AT_TOUCHDOWN),
        ([0.4, -math.pi / 2, 0.0, 0.0], [0, 0, 0, 0, 0.6], Fall.COM_HITS_GROUND),
        ([0.4, math.pi / 2, 0.5, 0.0], [-50, 0, 0, 0, 0.1], Fall.LIFTOFF_DESCENDING),
        ([float("nan"), math.pi / 2, 0.5, 0.0], [0, 0, 0, 0, 0.1], Fall.NOT_FINITE),
    ],
)
def test_falls_are_named_outcomes(tight_map, params, X, u, fall):
    stride = tight_map.stride(X, u, params)
    assert stride.fall is fall and stride.apex is None


def test_a_com_already_underground_at_touchdown_is_a_fall(tight_map):
    """A long hip offset hangs the CoM below the foot: no crossing event would see it."""
    stride = tight_map.stride([0.3, -math.pi / 2, 0.0, 0.0], [0, 0, 0, 0, 0], Params(d=0.25))
    assert stride.fall is Fall.COM_HITS_GROUND


def test_integrator_failure_is_a_named_outcome(tight_map):
    """A nearly massless trunk under a stiff PD law makes the integrator give up."""
    X, u, params = [0.4, math.pi / 2, 0.5, 0.0], [2, 0.1, 0, 0, 0.1], Params(I=1e-9)
    assert tight_map.stride(X, u, params).fall is Fall.INTEGRATION_FAILED
    with pytest.raises(RunnerFell):
        tight_map.jacobians(X, u, params)


def test_simulate_returns_the_apex_sequence_or_the_fall(tight_map, params):
    # Hopping in place is unstable (round-off grows about 20x a stride), so only 3 strides.
    hop = tight_map.simulate([0.4, -math.pi / 2, 0.0, 0.0], [0, 0, 0, 0, 0], params, strides=3)
    assert hop.fall is None and hop.apexes.shape == (4, 4)
    np.testing.assert_allclose(hop.apexes, np.tile(hop.apexes[0], (4, 1)), atol=1e-12)
    # A forward runner whose leg is planted too steeply: speed drains away until it falls.
    run = tight_map.simulate([0.4, math.pi / 2, 0.5, 0.0], [0, 0, 0, 0, 0.3], params, strides=50)
    assert run.fall is not None and run.fall_stride is not None
    assert run.apexes.shape == (run.fall_stride + 1, 4)


def test_multi_stride_jacobians_match_central_differences_of_two_strides(tight_map, params, running_point):
    """dr^2/d(X, u, p) by the chain rule over the strides, against differences of r(r(.))."""
    X, u = running_point
    dr_dX, dr_du = tight_map.jacobians(X, u, params, strides=2)
    dr_dp = tight_map.parameter_jacobian(X, u, params, strides=2)
    p = params.vector()

    def twice(X, u, p):
        run = tight_map.simulate(X, u, p, 2)
        assert run.fall is None
        return run.apexes[-1]

    h = 1e-6
    for jac, which in ((dr_dX, 0), (dr_du, 1), (dr_dp, 2)):
        base = (X, u, p)[which]
        for j in range(len(base)):
            shift = np.zeros(len(base))
            shift[j] = h * max(1.0, abs(base[j]))
            plus, minus = [list((X, u, p)) for _ in range(2)]
            plus[which], minus[which] = base + shift, base - shift
            column = (twice(*plus) - twice(*minus)) / (2 * shift[j])
            np.testing.assert_allclose(jac[:, j], column, rtol=1e-5, atol=1e-5, err_msg=f"column {j} of input {which}")


def test_hessian_vector_products_match_differences_of_the_ad_jacobian(tight_map, params, running_point):
    """H S, with H the Hessian of w . r in z = (X, u, p) by AD (reverse over forward mode),
    against central differences of the AD Jacobian's w-weighted rows along S; and H is
    symmetric, a . H b = b . H a, as second derivatives are."""
    X, u = running_point
    p = param_vector(params)
    z = np.concatenate([X, u, p])
    rng = np.random.default_rng(3)
    w = rng.normal(size=APEX.size)
    S = rng.normal(size=(len(z), 3)) * np.maximum(np.abs(z), 0.1)[:, None]  # each input moved on its own scale
    product = tight_map.hessian_vectors(X, u, params, w, S)

    def weighted_gradient(point):
        jacobians = tight_map.all_jacobians(point[: APEX.size], point[APEX.size : APEX.size + u.size],
                                            point[APEX.size + u.size :])
        return np.hstack(jacobians).T @ w

    h = 1e-6
    for k in range(S.shape[1]):
        differenced = (weighted_gradient(z + h * S[:, k]) - weighted_gradient(z - h * S[:, k])) / (2 * h)
        assert np.linalg.norm(product[:, k] - differenced) <= 1e-5 * np.linalg.norm(differenced)
    assert S[:, 0] @ product[:, 1] == pytest.approx(S[:, 1] @ product[:, 0], rel=1e-10)


def test_the_gradient_of_a_seeded_jacobian_matches_its_differences(tight_map, params, running_point):
    """grad_z <G, dr/dX> for a full seed G (the Jacobian's forward directions, one reverse
    sweep) and a rank-one seed (one Hessian-vector product) against central differences of
    <G, dr/dX> along random directions of z = (X, u, p); a zero seed has a zero gradient."""
    X, u = running_point
    z = np.concatenate([X, u, param_vector(params)])
    rng = np.random.default_rng(4)
    G = rng.normal(size=(APEX.size, APEX.size))
    gradient = tight_map.jacobian_gradient(X, u, params, G)

    def seeded_by(seed, point):
        dr_dX = tight_map.all_jacobians(point[: APEX.size], point[APEX.size : APEX.size + u.size],
                                        point[APEX.size + u.size :])[0]
        return float(np.sum(seed * dr_dX))

    def seeded(point):
        return seeded_by(G, point)

    h = 1e-6
    for _ in range(3):
        s = rng.normal(size=len(z)) * np.maximum(np.abs(z), 0.1)
        differenced = (seeded(z + h * s) - seeded(z - h * s)) / (2 * h)
        assert gradient @ s == pytest.approx(differenced, rel=1e-5)
    rank_one = np.outer(G[:, 0], G[0])  # a rank-one seed takes the Hessian-vector route
    differenced = (seeded_by(rank_one, z + h * s) - seeded_by(rank_one, z - h * s)) / (2 * h)
    assert tight_map.jacobian_gradient(X, u, params, rank_one) @ s == pytest.approx(differenced, rel=1e-5)
    assert not np.any(tight_map.jacobian_gradient(X, u, params, np.zeros((APEX.size, APEX.size))))


def test_an_event_map_has_no_second_derivatives(params, running_point):
    X, u = running_point
    with pytest.raises(NoSecondDerivatives):
        ReturnMap(Tolerances(1e-12, 1e-12), plugin="erk").hessian_vectors(X, u, params, np.ones(APEX.size),
                                                                           np.ones((APEX.size + u.size + 6, 1)))


def test_a_return_map_takes_its_hip_law_by_name():
    """Issue 56: ``ReturnMap(hip_law="vpp")`` raised a TypeError."""
    from baslip.errors import InputError
    from baslip.model.hiplaw import PD, VPP

    assert ReturnMap(plugin="erk", hip_law="vpp").law is VPP
    assert ReturnMap(plugin="erk", hip_law="pd").law is PD
    with pytest.raises(InputError, match=r"hip_law: expected one of pd, vpp, got 'spring'"):
        ReturnMap(plugin="erk", hip_law="spring")
    with pytest.raises(InputError, match="contradicts"):
        ReturnMap(plugin="erk", law=VPP, hip_law="pd")
