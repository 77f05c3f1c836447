"""Specification of baslip.gait.fixedpoint (with baslip.gait.shooting): verified fixed points.

Every converged result must survive an independent re-simulation at rtol = atol = 1e-12
with eps (thesis eq. 4.1) <= 1e-10; anything else is reported as not verified or failed.
"""

import math

import numpy as np
import pytest

from baslip import Params, ReturnMap, Tolerances
from baslip.gait.fixedpoint import ACCEPTED_IPOPT
from baslip.gait.from_problem import fixed_point_spec
from baslip.gait.shooting import FixedPointSpec
from baslip.problem.reader import load_problem

DOWNWARD_GUESS = {
    "theta_h": -math.pi / 2, "theta_h_dot": 0.0, "Kp": 2.0, "Kd": 0.5,
    "theta2_des": 0.0, "theta2_dot_des": 2.0, "theta_td": 0.113,
}
HANGING = {"theta_h": (-100 * math.pi / 180, -80 * math.pi / 180)}


def eps(X, apex):
    return np.linalg.norm(apex - X) / np.linalg.norm(X)


RECHECK_MAP = ReturnMap(Tolerances(1e-13, 1e-13))


def recheck(result):
    """Re-simulate with settings the solver uses nowhere (erk at rtol = atol = 1e-13)."""
    return eps(result.X, RECHECK_MAP(result.X, result.u, result.params))


@pytest.fixture(scope="module")
def downward(solver):
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5}, guess=DOWNWARD_GUESS, bounds=HANGING)
    return solver.solve(spec, name="downward")


def test_downward_fixed_point_is_verified(downward):
    assert downward.status == "converged", downward.message
    assert downward.residual <= 1e-10
    assert recheck(downward) <= 1e-10
    assert downward.apex["z"] == 0.4 and downward.apex["ydot"] == 0.5  # fixed values held exactly
    assert -100 <= math.degrees(downward.apex["theta_h"]) <= -80
    assert all(t > 0 for t in downward.durations.values())


def test_result_record_has_exactly_the_documented_keys(downward):
    record = downward.to_json_dict()
    assert list(record) == [
        "name", "status", "solver", "params", "hip_law", "apex", "control", "durations",
        "energy", "residual", "eigenvalues", "spectral_radius", "stable", "on_bounds", "diagnosis",
    ]
    assert set(record["solver"]) == {"return_status", "iterations", "time_s", "compile_s", "tries"}
    assert record["diagnosis"] is None and record["on_bounds"] == []
    assert set(record["durations"]) == {"descent", "compression", "decompression", "ascent"}
    assert len(record["eigenvalues"]) == 4 and all(len(pair) == 2 for pair in record["eigenvalues"])
    radius = max(math.hypot(*pair) for pair in record["eigenvalues"])
    assert record["spectral_radius"] == pytest.approx(radius)  # no trivial multipliers here
    assert record["stable"] == (radius < 1)


def test_set_up_is_timed_apart_from_the_solve_and_reported_once(monkeypatch):
    """A library compiled on the way counts in compile_s, its own summary line, and not in
    time_s; the next solve reports no set-up (a fake clock: nothing waits)."""
    from baslip import FixedPointSolver
    from baslip.engine import setuptime

    clock = [1000.0]
    monkeypatch.setattr(setuptime.time, "perf_counter", lambda: clock[0])
    solver = FixedPointSolver(few_calls=True)
    simulate = solver.verify_map.simulate

    def compile_then_simulate(*arguments):
        with setuptime.setting_up():
            clock[0] += 30.0  # gcc, say
        clock[0] += 0.5  # the re-simulation itself
        return simulate(*arguments)

    monkeypatch.setattr(solver.verify_map, "simulate", compile_then_simulate)
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5}, guess=DOWNWARD_GUESS, bounds=HANGING)
    first = solver.solve(spec, name="downward")
    assert first.converged
    assert first.solver.compile_s == pytest.approx(30.0) and first.solver.time_s == pytest.approx(0.5)
    assert "  compile  30.00 s (" in first.summary() and ", 0.50 s" in first.summary()
    monkeypatch.setattr(solver.verify_map, "simulate", simulate)
    again = solver.solve(spec, name="downward")
    assert again.solver.compile_s == 0.0 and again.solver.time_s == 0.0


def test_fixed_energy_is_held(solver):
    spec = FixedPointSpec(Params(), fixed={"energy": 4.1, "ydot": 0.5}, guess={**DOWNWARD_GUESS, "z": 0.4}, bounds=HANGING)
    result = solver.solve(spec)
    assert result.status == "converged", result.message
    assert result.energy == pytest.approx(4.1, abs=1e-10)
    assert recheck(result) <= 1e-10


@pytest.mark.parametrize("objective", ["min_torque", "feasibility"])
def test_other_objectives_give_verified_points(solver, objective):
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5}, guess=DOWNWARD_GUESS, bounds=HANGING, objective=objective)
    result = solver.solve(spec)
    assert result.status == "converged", result.message
    assert recheck(result) <= 1e-10


def test_min_torque_needs_no_more_torque_than_nearest_guess(solver, downward):
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5}, guess=DOWNWARD_GUESS, bounds=HANGING, objective="min_torque")
    least = solver.solve(spec)
    assert solver.torque_effort(least) <= solver.torque_effort(downward) + 1e-9


def test_torque_free_gait_is_rank_deficient_but_verified(solver):
    """Kp = Kd = 0: energy is conserved, so the periodicity equations are dependent."""
    spec = FixedPointSpec(
        Params(),
        fixed={"z": 0.4, "ydot": 0.5, "Kp": 0.0, "Kd": 0.0, "theta2_des": 0.0, "theta2_dot_des": 0.0},
        guess={"theta_h": -math.pi / 2, "theta_h_dot": 0.0, "theta_td": 0.11},
        bounds=HANGING,
    )
    result = solver.solve(spec)
    assert result.status == "converged", result.message
    assert recheck(result) <= 1e-10
    assert [m.label for m in result.stability.multipliers if m.trivial] == ["energy"]


def test_ipopt_failure_is_reported_not_raised(solver):
    # 1 J cannot lift 1 kg to 0.4 m: the fixed values are inconsistent.
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5, "energy": 1.0}, guess=DOWNWARD_GUESS, bounds=HANGING)
    result = solver.solve(spec)
    assert result.status == "failed"
    assert result.solver.return_status not in ACCEPTED_IPOPT
    assert result.stability is None and result.to_json_dict()["eigenvalues"] is None


def test_a_failure_reports_each_ipopt_try_and_what_binds(solver):
    """The default Hessian's failure gets a second try with the exact one; both are
    reported, their iterations adding up to the total, and the summary says so."""
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5, "energy": 1.0}, guess=DOWNWARD_GUESS, bounds=HANGING)
    result = solver.solve(spec)
    tries = result.to_json_dict()["solver"]["tries"]
    assert [t["settings"] for t in tries] == [{"hessian": "objective"}, {"hessian": "exact"}]
    assert sum(t["iterations"] for t in tries) == result.solver.iterations
    assert tries[-1]["return_status"] == result.solver.return_status
    assert f"IPOPT: try 1 (hessian objective) {tries[0]['return_status']} in {tries[0]['iterations']} iterations; try 2" \
        in result.summary()
    assert result.diagnosis is not None and result.to_json_dict()["diagnosis"]["violated"]


HUMAN_AT_3_M_S = {
    "params": {"m": 80.0, "I": 4.58, "k": 20000.0, "rho0": 1.0, "d": 0.1, "g": 9.81},
    "fix": {"z": 1.05, "ydot": 3.0},
    "guess": {"theta_h": "90 deg", "theta_h_dot": -0.1, "theta_td": "23.6 deg"},
}


@pytest.fixture(scope="module", params=["vpp", "pd"])
def human_at_the_foot_clearance(request):
    """The human body at z = 1.05 m and 3 m/s (issue 56), under each law from the
    human-scale guess of problems/vpp_human.yaml: no gait lets the foot clear the ground
    at apex with the touchdown angle it needs."""
    from baslip.gait.from_problem import solve_problem
    from baslip.problem.reader import parse_problem

    law = request.param
    data = {**HUMAN_AT_3_M_S, "hip_law": law}
    if law == "vpp":
        data["fix"] = {**data["fix"], "r_vpp": 0.1}
    return solve_problem(parse_problem(data, f"{law}_human_slow"))


def test_a_failure_at_the_foot_clearance_limit_names_it_and_how_to_move_it(human_at_the_foot_clearance):
    """Under VPP IPOPT finds the problem infeasible with theta_td on the limit; under PD it
    runs out of iterations 0.6 mm from it. Either way the limit is named (binding or
    near) and the summary gives the least theta_td in degrees and the height to aim for."""
    result = human_at_the_foot_clearance
    assert result.status == "failed", result.message
    theta_td_limit = math.degrees(math.acos((1.05 - 0.1 * math.sin(result.X[1])) / 1.0))  # about 18.19 deg
    assert math.degrees(result.control["theta_td"]) == pytest.approx(theta_td_limit, abs=0.15)
    diagnosis = result.to_json_dict()["diagnosis"]
    named = {limit["name"] for limit in diagnosis["binding"] or diagnosis["near"]}
    assert "foot clearance at apex" in named
    summary = result.summary()
    assert "foot clearance at apex = " in summary
    assert f"keeps theta_td above {theta_td_limit:.2f} deg" in summary and "raise z (z > 1.055 m" in summary
    if result.law.name == "vpp":
        assert result.solver.return_status == "Infeasible_Problem_Detected"
        assert "binding  foot clearance at apex" in summary


def test_a_gait_on_a_bound_says_so(solver, downward):
    """Bounding theta_h where the free gait has it puts the verified gait on that bound;
    result.json and the summary name the quantity, its value and the bound."""
    theta_h = downward.apex["theta_h"]
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5}, guess=DOWNWARD_GUESS,
                          bounds={"theta_h": (-math.pi, theta_h)})
    result = solver.verify_point(spec, downward.X, downward.u)
    assert result.status == "converged", result.message
    assert result.to_json_dict()["on_bounds"] == [{"name": "theta_h", "value": theta_h, "bound": theta_h, "unit": "rad"}]
    assert f"on bound theta_h = {math.degrees(theta_h):.6g} deg" in result.summary()
    assert downward.on_bounds == ()  # inside (-100, -80) deg: on no bound


def test_disagreeing_re_simulation_is_not_verified(solver):
    """If the independent map disagrees (here: a deliberately loose one), nothing converges."""
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5}, guess=DOWNWARD_GUESS, bounds=HANGING)
    strict = solver.verify_map
    solver.verify_map = ReturnMap(Tolerances(1e-3, 1e-3), plugin="rosenbrock")
    try:
        result = solver.solve(spec)
    finally:
        solver.verify_map = strict
    assert result.status == "not_verified" and "eps" in result.message
    assert result.residual > 1e-10 and result.stability is None
    # Explained from IPOPT's point, which met every row: nothing violated.
    assert result.diagnosis is not None and result.diagnosis.violated == ()


def test_an_energy_bound_holds_after_the_polish(solver):
    spec = FixedPointSpec(
        Params(), fixed={"ydot": 0.5}, guess={**DOWNWARD_GUESS, "z": 0.4},
        bounds={**HANGING, "energy": (-math.inf, 4.0)},
    )
    result = solver.solve(spec)
    assert result.status == "converged", result.message
    assert result.energy <= 4.0 + 1e-10
    assert recheck(result) <= 1e-10


def test_a_two_stride_orbit_is_solved_and_verified(solver, tight_map):
    """problems/downward_period2.yaml: a hanging-trunk gait that repeats every two strides
    (it lies on the branch switched from the period doubling of the height branch)."""
    result = solver.solve(fixed_point_spec(load_problem("problems/downward_period2.yaml")), name="period2")
    assert result.converged and result.strides == 2, result.message
    first, second = result.orbit
    assert eps(first, second) > 1e-2  # a genuine 2-stride orbit, not a fixed point twice
    # Each apex maps to the other under one stride, re-simulated by another integrator.
    assert eps(second, RECHECK_MAP(first, result.u, result.params)) < 1e-9
    assert eps(first, RECHECK_MAP(second, result.u, result.params)) < 1e-9
    # The orbit's multipliers do not depend on the apex it is started from (eig(AB) = eig(BA)).
    from_second = np.linalg.eigvals(tight_map.jacobians(second, result.u, result.params, strides=2)[0])
    assert np.sort_complex(from_second) == pytest.approx(np.sort_complex(np.array(result.eigenvalues)), abs=1e-6)
    record = result.to_json_dict()
    assert record["strides"] == 2 and record["minimal_period"] == 2 and len(record["orbit"]) == 2


# --- under the VPP hip law -----------------------------------------------------------------


@pytest.fixture(scope="module")
def vpp_human():
    from baslip.gait.from_problem import solve_problem

    return solve_problem(load_problem("problems/vpp_human.yaml"))


def test_a_vpp_gait_with_only_height_speed_and_pivot_fixed_is_symmetric_and_verified(vpp_human):
    result = vpp_human
    assert result.converged and result.residual <= 1e-10 and result.law.name == "vpp"
    assert list(result.control) == ["r_vpp", "theta_td"] and result.to_json_dict()["hip_law"] == "vpp"
    # Symmetric under mirror and time reversal: upright at the apex.
    assert abs(result.X[1] - math.pi / 2) <= 1e-8
    recheck_map = ReturnMap(Tolerances(1e-13, 1e-13), law=result.law)
    assert eps(result.X, recheck_map(result.X, result.u, result.params)) <= 1e-10
    labels = [m.label for m in result.multipliers]
    assert labels.count("symmetry") == 1 and labels.count(None) == 3


def test_the_symmetry_multiplier_is_one_and_the_others_decide_the_radius(vpp_human):
    multipliers = vpp_human.multipliers
    symmetric = [m.value for m in multipliers if m.label == "symmetry"][0]
    assert abs(symmetric - 1.0) <= 1e-7
    others = max(abs(m.value) for m in multipliers if m.label is None)
    assert vpp_human.spectral_radius == pytest.approx(others) and vpp_human.stable == (others < 1 - 1e-6)


def test_a_point_of_another_hip_law_is_refused_not_polished(solver, vpp_human):
    """verify_point of the (PD) solver refuses a VPP problem's point: its controls would be
    read in the wrong layout."""
    from baslip.gait.from_problem import fixed_point_spec

    spec = fixed_point_spec(load_problem("problems/vpp_human.yaml"))
    with pytest.raises(ValueError, match="built for hip law pd, not vpp"):
        solver.verify_point(spec, vpp_human.X, vpp_human.u)


def test_a_point_a_hair_past_a_bound_is_verified_on_it(solver, downward):
    """IPOPT may return a quantity it holds on a bound about 1e-8 past it: such a point is
    put on the bound, polished from there and verified, not refused."""
    theta_h = downward.apex["theta_h"]
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5}, guess=DOWNWARD_GUESS,
                          bounds={"theta_h": (-math.pi, theta_h - 5e-9)})
    result = solver.verify_point(spec, downward.X, downward.u)
    assert result.status == "converged", result.message
    assert result.apex["theta_h"] == theta_h - 5e-9 and recheck(result) <= 1e-10


def _slow_failing_nlp(seconds):
    """A stand-in for IPOPT that takes ``seconds`` of the fake clock and then fails."""
    from baslip import diagnostics
    from baslip.gait.shooting import NlpSolution

    def solve(nlp, spec, w0=None, rmap=None, ipopt=None):
        diagnostics.CLOCK.advance(seconds)
        return NlpSolution(spec.start_design()[:4], spec.start_design()[4:], np.full(3, np.nan),
                           "Maximum_Iterations_Exceeded", 300, seconds)

    return solve


def test_ipopt_tries_are_announced_and_heard_from_every_10_s_and_quiet_silences_them(solver, monkeypatch,
                                                                                     fake_clock):
    """Two slow, failing tries (25 s each on a fake clock): the second is announced as it
    starts, with how the first ended, and neither is silent for more than 10 s."""
    from baslip.gait.shooting import ShootingNLP

    monkeypatch.setattr(ShootingNLP, "solve", _slow_failing_nlp(25.0))
    monkeypatch.setattr(solver, "nlp_for", lambda strides, exact=False: solver.nlp)  # no exact NLP to build
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5}, guess=DOWNWARD_GUESS, bounds=HANGING)
    clock = fake_clock()
    result = solver.solve(spec)
    assert result.solver.return_status == "Maximum_Iterations_Exceeded"
    said = clock.messages()
    first = f"IPOPT try 1 of up to 2 ({solver.options.hessian} Hessian): still solving, "
    assert said[:2] == [first + "9 s", first + "18 s"]
    assert said[2] == ("IPOPT try 2 of 2 (exact Hessian): starting from the same start; "
                       "try 1 ended Maximum_Iterations_Exceeded after 300 iterations")
    assert said[3:] == ["IPOPT try 2 of 2 (exact Hessian): still solving, 9 s",
                        "IPOPT try 2 of 2 (exact Hessian): still solving, 18 s"]
    assert clock.time == 50.0 and clock.longest_silence(0.0, 50.0) <= 10.0 and clock.running() == 0

    quiet = fake_clock(shown=False)
    solver.solve(spec)
    assert quiet.time == 50.0 and quiet.said == [] and quiet.running() == 0
