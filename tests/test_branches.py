"""Specification of baslip.analysis.gaitsystem with baslip.numerics.continuation on the BA-SLIP itself.

The SLIP limit (d = 0, no torque) at the energy of Seyfarth, Geyer & Herr (2003),
J. Exp. Biol. 206:2547 (see test_slip_limit.py), continued in the touchdown angle: the
self-stable band is bounded by a period doubling and a fold. Rummel & Seyfarth (2008),
Int. J. Robot. Res. 27:919, give the band as about 2 deg wide at 5 m/s. The period
doubling is cross-checked with the independent SLIP implementation of test_slip_limit.py.
"""

import math
from dataclasses import replace

import numpy as np
import pytest
from slip import slip_apex_map, slip_fixed_point  # the independent SLIP (tests/ is on sys.path)

from baslip.analysis.gaitsystem import FixedPointSystem, NearestGuessSystem, branch_system, grazing_phase
from baslip.gait.fixedpoint import minimal_period
from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.gait.shooting import FixedPointSpec
from baslip.numerics.continuation import Settings, continue_branch, switch_branch
from baslip.problem.continuation import BranchError, check_branch
from baslip.problem.reader import load_problem


@pytest.fixture(scope="module")
def slip_branch(solver):
    problem = load_problem("problems/continuation_slip_attack.yaml")
    start = solver.solve(fixed_point_spec(problem))
    assert start.converged, start.message
    system = FixedPointSystem(fixed_point_spec(problem), "theta_td", solver.residual_map, solver.jacobian_map)
    v0 = system.pack(start.X, start.u, system.start_value())
    settings = Settings(step=0.05, lam_range=(math.radians(20) / system.lam_scale, math.radians(25) / system.lam_scale))
    branch = continue_branch(system, v0, +1, settings)
    return system, branch


@pytest.fixture(scope="module")
def slip_period_2_branch(slip_branch, solver):
    """The 2-stride orbits born at the SLIP's period doubling, by branch switching."""
    system, branch = slip_branch
    pd = branch.special[0]
    doubled = FixedPointSystem(replace(system.spec, strides=2), "theta_td", solver.residual_map, solver.jacobian_map)
    v, direction = switch_branch(doubled, pd, 0.05, Settings())
    def verified(v):
        return doubled.verification_failure(v, solver.verify_map)

    assert verified(v) is None
    return doubled, pd, continue_branch(doubled, v, direction, Settings(step=0.05, max_points=40), accept=verified)


def _attack_deg(system, point):
    return 90.0 - math.degrees(system.unpack(point.v)[3])


def test_the_stable_band_is_bounded_by_a_period_doubling_and_a_fold(slip_branch):
    system, branch = slip_branch
    kinds = [p.special for p in branch.special]
    assert kinds == ["period_doubling", "fold"]  # no false alarms from the three unit multipliers
    pd, fold = branch.special
    (pd_multiplier,) = [m for m, t in zip(pd.multipliers, pd.trivial) if not t]
    (fold_multiplier,) = [m for m, t in zip(fold.multipliers, fold.trivial) if not t]
    assert abs(pd_multiplier + 1) < 1e-5 and abs(fold_multiplier - 1) < 1e-3
    width = _attack_deg(system, pd) - _attack_deg(system, fold)
    assert 2.0 < width < 3.0  # "about 2 deg" (Rummel & Seyfarth 2008)
    stable = [p for p in branch.points if not p.special and max(abs(m) for m, t in zip(p.multipliers, p.trivial) if not t) < 1]
    lams = [system.unpack(p.v)[3] for p in stable]
    assert min(lams) > system.unpack(pd.v)[3] - 1e-9 and max(lams) < system.unpack(fold.v)[3] + 1e-9


def test_the_period_doubling_agrees_with_an_independent_slip(slip_branch):
    system, branch = slip_branch
    pd = branch.special[0]
    X, _, _, _ = system.unpack(pd.v)
    height, slope = slip_fixed_point(_attack_deg(system, pd), X[0])
    assert height == pytest.approx(X[0], abs=1e-6)
    assert slope == pytest.approx(-1.0, abs=1e-3)


def test_the_branch_turns_back_at_the_fold_and_stays_verified(slip_branch, solver):
    system, branch = slip_branch
    lams = np.array([system.unpack(p.v)[3] for p in branch.points if not p.special])
    turn = int(np.argmax(lams))
    assert 0 < turn < len(lams) - 1 and np.all(np.diff(lams[: turn + 1]) > 0) and np.all(np.diff(lams[turn:]) < 0)
    assert branch.stop_reason == "end of range"
    for point in branch.points[::5]:
        X, u, params, _ = system.unpack(point.v)
        check = solver.verify_map.stride(X, u, params)
        assert check.ok and np.linalg.norm(check.apex - X) / np.linalg.norm(X) <= 1e-10


def shape(spec: FixedPointSpec) -> tuple:
    """What the problem reader's branch check reads of a spec: fixed values, parameters, objective."""
    return spec.fixed, spec.params, spec.objective


def test_a_branch_needs_as_many_free_quantities_as_equations_or_an_objective_that_picks():
    problem = load_problem("problems/downward.yaml")
    spec = fixed_point_spec(problem)
    check_branch(*shape(spec), "ydot")  # 7 free, 4 equations: the nearest-guess family
    for objective in ("min_torque", "feasibility"):
        with pytest.raises(BranchError, match="as many free quantities as equations"):
            check_branch(*shape(replace(spec, objective=objective)), "ydot")
    too_few = replace(spec, fixed={**spec.fixed, "Kp": -0.75, "Kd": 1.5, "theta2_des": -0.05, "theta_td": 0.1})
    with pytest.raises(BranchError, match="3 free"):
        check_branch(*shape(too_few), "ydot")
    with pytest.raises(BranchError, match="must be fixed"):
        check_branch(*shape(FixedPointSpec(problem.params, fixed={}, guess={})), "z")


def test_a_model_parameter_can_be_varied(solver):
    """Continuation in the leg stiffness k uses dr/dp by AD; each point stays periodic."""
    problem = load_problem("problems/continuation_slip_attack.yaml")
    spec = fixed_point_spec(problem)
    start = solver.solve(spec)
    system = FixedPointSystem(spec, "k", solver.residual_map, solver.jacobian_map)
    v0 = system.pack(start.X, start.u, system.start_value())
    branch = continue_branch(system, v0, +1, Settings(step=0.5, max_points=4))
    ks = [system.unpack(p.v)[2].k for p in branch.points]
    assert len(ks) == 4 and all(b > a for a, b in zip(ks, ks[1:]))
    for point in branch.points:
        assert np.linalg.norm(system.residual(point.v)) <= 1e-10


def test_switching_at_the_period_doubling_gives_verified_two_stride_orbits(slip_period_2_branch, solver):
    doubled, pd, branch = slip_period_2_branch
    assert len(branch.points) > 5
    pd_X, _, _, pd_angle = doubled.unpack(pd.v)
    first = branch.points[0]
    X, u, params, angle = doubled.unpack(first.v)
    # Born at the period doubling: close to it, with the squared multiplier -1 -> +1.
    assert abs(angle - pd_angle) < 1e-3 and abs(X[0] - pd_X[0]) < 5e-3
    (multiplier,) = [m for m, t in zip(first.multipliers, first.trivial) if not t]
    assert abs(multiplier - 1) < 0.2
    for point in branch.points:
        X, u, params, _ = doubled.unpack(point.v)
        orbit = solver.verify_map.simulate(X, u, params, 2)
        assert orbit.fall is None and np.linalg.norm(orbit.apexes[2] - X) / np.linalg.norm(X) <= 1e-10
        assert minimal_period(orbit.apexes) == 2
        high, low = sorted(orbit.apexes[:2, 0], reverse=True)
        assert high > pd_X[0] > low  # the two apexes straddle the period-1 apex


def test_the_two_stride_orbit_agrees_with_the_independent_slip(slip_period_2_branch, solver):
    doubled, _, branch = slip_period_2_branch
    X, u, params, angle = doubled.unpack(branch.points[3].v)
    heights = solver.verify_map.simulate(X, u, params, 2).apexes[:, 0]
    attack = 90.0 - math.degrees(angle)
    assert slip_apex_map(heights[0], attack) == pytest.approx(heights[1], abs=1e-6)
    assert slip_apex_map(heights[1], attack) == pytest.approx(heights[0], abs=1e-6)


def test_the_two_stride_branch_ends_where_the_low_apex_grazes_touchdown(slip_period_2_branch, solver):
    """Past a few hundredths of a degree the low apex sinks to the touchdown height
    rho0 cos(theta_td): the descent time goes to zero and the orbits end there."""
    doubled, _, branch = slip_period_2_branch
    assert branch.stop_reason.startswith(("not verified", "step too small")), branch.stop_reason
    X, u, params, angle = doubled.unpack(branch.points[-1].v)
    orbit = solver.verify_map.simulate(X, u, params, 2)
    assert min(orbit.apexes[:2, 0]) - params.rho0 * math.cos(angle) < 1e-3
    assert min(d["descent"] for d in orbit.durations) < 1e-3


def test_the_two_stride_nlp_finds_the_switched_branch_orbit(slip_period_2_branch, solver):
    """Two methods, one orbit: multiple shooting over two strides (IPOPT, DOP853) from a
    rounded guess lands on the orbit that branch switching found."""
    doubled, _, branch = slip_period_2_branch
    X, u, params, angle = doubled.unpack(branch.points[3].v)
    spec = replace(doubled.spec, fixed={**doubled.spec.fixed, "theta_td": angle},
                   guess={"z": round(X[0], 3), "ydot": round(X[2], 2)})
    result = solver.solve(spec)
    assert result.converged and result.strides == 2, result.message
    heights = sorted(result.orbit[:, 0])
    expected = sorted(solver.verify_map.simulate(X, u, params, 2).apexes[:2, 0])
    assert heights == pytest.approx(expected, abs=1e-8)


def test_the_period_doubling_is_a_branch_point_of_the_two_stride_equations(slip_branch, solver):
    """Followed as 2-stride orbits, the 1-stride branch meets the switched branch at a
    branch point, located at the same angle as the period doubling."""
    system, branch = slip_branch
    pd = branch.special[0]
    doubled = FixedPointSystem(replace(system.spec, strides=2), "theta_td", solver.residual_map, solver.jacobian_map)
    end = math.radians(21.3) / system.lam_scale
    run = continue_branch(doubled, branch.points[0].v, +1, Settings(step=0.05, lam_range=(0.0, end)))
    assert [p.special for p in run.special] == ["branch_point"]
    assert abs(doubled.unpack(run.special[0].v)[3] - system.unpack(pd.v)[3]) < 1e-6


@pytest.mark.parametrize("name", ["continuation_slip_attack", "curve_downward_boundary", "curve_vpp_fold"])
def test_second_derivatives_agree_with_differences_of_the_ad_jacobians(name):
    """The exact second derivatives (Hessian-vector products of the compiled stride) that
    curves and the nearest-guess family use, against central differences of the AD
    Jacobians: in the SLIP limit (energy conserved, so the map's coordinates are lifted
    onto the energy; an energy row), at a hanging PD gait with its gains free, and at a
    symmetric VPP gait. The Hessian of a weighted residual is symmetric."""
    problem = load_problem(f"problems/{name}.yaml")
    solver = solver_for(problem)
    spec = fixed_point_spec(problem)
    start = solver.solve(spec)
    assert start.converged, start.message
    system = branch_system(spec, problem.continuation.parameter, solver.residual_map, solver.jacobian_map,
                           second=problem.continuation.second)
    points = system.fixed_points if isinstance(system, NearestGuessSystem) else system
    v = points.pack(start.X, start.u, *(points.start_value(n) for n in points.parameters))
    rng = np.random.default_rng(5)
    h = 1e-6

    def differenced(matrix_at, j):
        step = np.zeros(len(v))
        step[j] = h
        return (matrix_at(v + step) - matrix_at(v - step)) / (2 * h)

    k = len(points.map_jacobian(v))
    seed = rng.normal(size=(k, k))
    exact = points.map_jacobian_gradient(v, seed)
    reference = np.array([np.sum(seed * differenced(points.map_jacobian, j)) for j in range(len(v))])
    assert np.linalg.norm(exact - reference) <= 1e-5 * np.linalg.norm(reference)

    weights = rng.normal(size=len(points.residual(v)))
    hessian = points.residual_hessian(v, weights, range(len(v)))
    reference = np.column_stack([weights @ differenced(points.jacobian, j) for j in range(len(v))])
    assert np.linalg.norm(hessian - reference) <= 1e-5 * np.linalg.norm(reference)
    assert np.allclose(hessian, hessian.T, rtol=0, atol=1e-9 * np.abs(hessian).max())


@pytest.mark.parametrize(("durations", "named"), [
    # The runner barely leaves the ground: both flight phases vanish together, so neither
    # is a small share of the flight, but the flight is of the stride.
    ({"descent": 1.7e-7, "compression": 0.1, "decompression": 0.1, "ascent": 2.0e-7},
     "grazing: the flight of stride 2 vanishes (descent 0.00017 ms and ascent 0.0002 ms of a 200 ms stride)"),
    ({"descent": 1.7e-7, "compression": 0.1, "decompression": 0.1, "ascent": 0.02},
     "grazing: the apex of stride 2 (z = 1.05 m) is at the touchdown height (descent 0.00017 ms of a 20 ms flight)"),
    ({"descent": 0.02, "compression": 0.1, "decompression": 0.1, "ascent": 1e-5},
     "grazing: the liftoff of stride 2 is at the apex height: the ascent vanishes (ascent 0.01 ms of a 20 ms flight)"),
    ({"descent": 0.02, "compression": 1e-4, "decompression": 0.1, "ascent": 0.02},
     "grazing: the compression of stride 2 lasts 0.1 ms of a 100 ms stance"),
    ({"descent": 0.02, "compression": 0.1, "decompression": 0.1, "ascent": 0.02}, None),
])
def test_a_vanishing_phase_is_named_as_grazing_with_its_duration(durations, named):
    assert grazing_phase(durations, 1.05, stride=2) == named


def test_an_orbit_that_falls_with_its_foot_at_the_ground_at_apex_is_named_as_grazing(slip_branch):
    """A stride whose foot starts 1e-13 m below the ground falls at once (the foot below
    ground at apex), yet the branch it ends is grazing: its descent has vanished."""
    system, branch = slip_branch
    X, u, params, lam = system.unpack(branch.points[0].v)
    theta_td = system.spec.law.control_dict(u)["theta_td"]
    X = X.copy()
    X[0] = params.d * math.sin(X[1]) + params.rho0 * math.cos(theta_td) - 1e-13
    assert system.residual_map.simulate(X, u, params, 1).fall is not None
    named = system.grazing(system.pack(X, u, lam))
    assert named is not None and named.startswith("grazing: the foot is at the ground at the apex of stride 1")
    X[0] += 1e-3  # a millimetre clear: a stride with a descent, not grazing
    assert system.grazing(system.pack(X, u, lam)) is None
