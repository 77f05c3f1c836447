"""Specification of baslip.studies.curve and of the branch families behind it: bifurcation
curves of the BA-SLIP in two parameters, on the shipped problems.

* The SLIP band's edges, followed in (theta_td, energy), pass through the edges that the
  one-parameter branch locates at the Seyfarth energy.
* On a curve the critical multipliers are where the curve says: -1 on a period-doubling
  curve, a pair on the unit circle on a Neimark-Sacker curve.
* When a problem leaves more quantities free than there are equations, the branch follows
  the family that the solver's nearest-guess objective picks.
* A generalised period doubling is where the two-stride orbits born at the period doubling
  change stability, which two independent branch runs confirm.
* A curve type asked for but not found is a failure, not a result.
* Under the VPP law, a period-doubling curve keeps -1 besides the symmetric gaits' structural
  +1, passes through the branch's period doubling, and ends the stable band it bounds at a
  fold-flip point, where a second multiplier crosses +1.
* Under the VPP law, a fold curve keeps two multipliers at +1 (the structural one and the
  critical one), and meets the period-doubling curve at the same fold-flip point: two
  curves, deflated in two ways, locate one point.
* Exact second derivatives and central differences of the AD Jacobian steer Newton to the
  same curve points.
* The curves' halves are traced on both cores, each from its first point alone: one worker
  process or two give the same curve.csv, byte for byte.
"""

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from runs import ROOT, run_problem

from baslip.analysis.bifurcation import CurveSystem, trace_curve
from baslip.analysis.gaitsystem import NearestGuessSystem, branch_system
from baslip.cli.solve import main
from baslip.gait.from_problem import fixed_point_spec
from baslip.model.dynamics import APEX
from baslip.model.quantities import DESIGN, NOMINAL
from baslip.numerics.continuation import Settings, continue_branch
from baslip.problem.reader import load_problem

SEYFARTH_ENERGY = 1784.8  # J: 5 m/s at a 1 m apex height, m = 80 kg


def run(tmp_path, name: str, **replacements) -> tuple[dict, list[dict], list[dict]]:
    """The summary, branch.csv rows and curve.csv rows (none if not written) of a run."""
    summary, out = run_problem(tmp_path, name, **replacements)
    return summary, read_csv(out / "branch.csv"), read_csv(out / "curve.csv")


def read_csv(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def multipliers(row: dict) -> np.ndarray:
    return np.array([complex(float(row[f"mult{i}_re"]), float(row[f"mult{i}_im"])) for i in range(1, 5)])


@pytest.fixture(scope="module")
def slip_band(tmp_path_factory):
    """The band's two curves from the Seyfarth energy up to 1800 J."""
    return run(tmp_path_factory.mktemp("band"), "curve_slip_band",
               **{"second_range: [1424.8, 2224.8]": f"second_range: [{SEYFARTH_ENERGY}, 1800.0]"})


def test_slip_band_curves_pass_through_the_one_parameter_edges(slip_band):
    summary, _, curve = slip_band
    edges = {p["type"]: p["theta_td"] for p in summary["special_points"]}
    assert set(edges) >= {"period_doubling", "fold"}  # where they lie: test_branch_runs, against an independent SLIP
    for kind in ("period_doubling", "fold"):
        rows = [r for r in curve if r["type"] == kind]
        at_energy = [r for r in rows if abs(float(r["energy"]) - SEYFARTH_ENERGY) < 1e-9]
        assert at_energy, kind
        assert float(at_energy[0]["theta_td"]) == pytest.approx(edges[kind], abs=1e-6)
    stops = [c["stop_reason"] for c in summary["curves"]["curves"]]
    assert stops == ["lower end: end of range; upper end: end of range"] * 2
    assert summary["curves"]["codimension_two_points"] == []


def test_a_period_doubling_curve_keeps_a_multiplier_at_minus_one(slip_band):
    _, _, curve = slip_band
    rows = [r for r in curve if r["type"] == "period_doubling"]
    assert len(rows) > 3
    for row in rows:
        assert np.min(np.abs(multipliers(row) + 1)) < 1e-8
        assert row["stability_boundary"] == "true"


def test_a_neimark_sacker_curve_keeps_a_pair_on_the_unit_circle(tmp_path):
    summary, _, curve = run(tmp_path, "curve_downward_neimark_sacker",
                            **{"second_range: [0.005, 1.6]": "second_range: [0.45, 0.55]"})
    assert len(curve) > 3
    for row in curve:
        mu = multipliers(row)
        pair = mu[np.abs(mu.imag) > 1e-6]
        assert len(pair) == 2 and np.max(np.abs(np.abs(pair) - 1)) < 1e-8
        assert float(row["kappa"]) == pytest.approx(pair[0].real, abs=1e-8)
    # ydot is the second parameter: its range's ends are met exactly.
    speeds = sorted(float(r["ydot"]) for r in curve)
    assert speeds[0] == pytest.approx(0.45, abs=1e-12) and speeds[-1] == pytest.approx(0.55, abs=1e-12)


def test_the_nearest_guess_family_is_the_solvers_choice(solver):
    """downward.yaml fixes only z and ydot; the branch in z follows the optimality
    conditions of the nearest-guess objective, and agrees with fresh solves."""
    problem = load_problem(ROOT / "problems" / "downward.yaml")
    spec = fixed_point_spec(problem)
    system = branch_system(spec, "z", solver.residual_map, solver.jacobian_map)
    assert isinstance(system, NearestGuessSystem)
    start = solver.solve(spec)
    branch = continue_branch(system, system.pack(start.X, start.u, 0.4), 1.0, Settings(step=0.1, max_points=4))
    for point in branch.points[1:]:
        X, u, _, z = system.unpack(point.v)
        fresh = solver.solve(replace(spec, fixed={**spec.fixed, "z": z}))
        assert fresh.converged
        ours = np.concatenate([X, u]) / np.array([NOMINAL[n] for n in DESIGN])
        theirs = np.concatenate([fresh.X, fresh.u]) / np.array([NOMINAL[n] for n in DESIGN])
        assert np.max(np.abs(ours - theirs)) < 1e-5
    assert branch.points[-1].v[-1] * system.lam_scale > 0.42


def test_generalised_period_doubling_is_where_born_two_stride_orbits_change_stability(tmp_path):
    """The curve run puts a generalised period doubling on the hanging gaits' period-doubling
    curve at ydot = 0.533 m/s. Independently: switching onto the two-stride branch at the
    period doubling of the z-branch, the born orbits' multiplier near +1 lies above 1 at
    0.5 m/s and below 1 at 0.6 m/s, so the flip's cubic coefficient changes sign between."""
    summary, _, _ = run(tmp_path, "curve_downward_neimark_sacker",
                        **{"follow: neimark_sacker": "follow: period_doubling", "second_range: [0.005, 1.6]": "second_range: [0.45, 0.65]"})
    points = summary["curves"]["codimension_two_points"]
    assert [p["type"] for p in points] == ["generalised_period_doubling"]
    assert 0.5 < points[0]["ydot"] < 0.6
    signs = []
    for ydot in ("0.5", "0.6"):
        (tmp_path / ydot).mkdir()
        _, rows, _ = run(tmp_path / ydot, "continuation_downward_height",
                         **{"  ydot: 0.5": f"  ydot: {ydot}", "  z: 0.4": "  z: 0.465", "range: [0.3, 0.6]": "range: [0.46, 0.48]",
                            "step: 0.05": "step: 0.002", "direction: both": "direction: 1"})
        born = [r for r in rows if r["branch"] == "1"][1:4]
        assert born
        signs.append({float(np.sign(min(multipliers(r), key=lambda m: abs(m - 1)).real - 1)) for r in born})
    assert signs == [{1.0}, {-1.0}]


def test_one_worker_or_two_trace_the_same_curves(tmp_path):
    narrow = {"second_range: [1424.8, 2224.8]": f"second_range: [{SEYFARTH_ENERGY}, 1790.0]"}
    texts = []
    for jobs in (1, 2):
        folder = tmp_path / f"jobs{jobs}"
        folder.mkdir()
        _, out = run_problem(folder, "curve_slip_band", jobs=jobs, **narrow)
        texts.append((out / "curve.csv").read_text())
    assert texts[0] == texts[1]
    assert len(texts[0].splitlines()) > 6


def test_a_curve_asked_for_but_not_found_is_a_failure(tmp_path, capsys):
    text = (ROOT / "problems" / "curve_slip_band.yaml").read_text()
    text = text.replace("follow: [period_doubling, fold]", "follow: neimark_sacker").replace(
        'range: ["15 deg", "30 deg"]', 'range: ["20 deg", "22 deg"]')
    path = tmp_path / "no_ns.yaml"
    path.write_text(text)
    code = main([str(path), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert err == ["error: curve_slip_band: no neimark sacker curve was traced (see result.json)"]
    summary = json.loads((tmp_path / "out" / "result.json").read_text())
    assert summary["curves"]["curves"] == []


def test_a_model_parameter_can_be_the_second_parameter(tmp_path):
    """The period-doubling edge followed in (theta_td, k): through dr/dp by AD."""
    summary, _, curve = run(tmp_path, "curve_slip_band", **{
        "second: energy": "second: k", "second_range: [1424.8, 2224.8]": "second_range: [19500.0, 20500.0]",
        "follow: [period_doubling, fold]": "follow: period_doubling"})
    edge = [p["theta_td"] for p in summary["special_points"] if p["type"] == "period_doubling"][0]
    at_start = [r for r in curve if abs(float(r["k"]) - 20000.0) < 1e-6]
    assert at_start and float(at_start[0]["theta_td"]) == pytest.approx(edge, abs=1e-6)
    stiffness = sorted(float(r["k"]) for r in curve)
    assert stiffness[0] == pytest.approx(19500.0, abs=1e-9) and stiffness[-1] == pytest.approx(20500.0, abs=1e-9)
    assert all(np.min(np.abs(multipliers(r) + 1)) < 1e-8 for r in curve)


def test_a_vpp_period_doubling_curve_ends_its_stable_band_at_a_fold_flip(tmp_path):
    """curve_vpp_pivot (human scale, z = 1.1 m) in (r_vpp, ydot) from the branch's period
    doubling at 5 m/s, over 3.9 to 5.1 m/s (measured: the fold-flip at r_vpp = 0.23264 m,
    ydot = 4.00187 m/s)."""
    summary, _, curve = run(tmp_path, "curve_vpp_pivot", **{"range: [0.05, 0.5]": "range: [0.09, 0.3]",
                                                           "second_range: [3.0, 6.0]": "second_range: [3.9, 5.1]"})
    assert len(curve) > 10
    for row in curve:
        mu = multipliers(row)
        assert np.min(np.abs(mu + 1)) < 1e-8 and np.min(np.abs(mu - 1)) < 1e-5  # critical, and by symmetry
    (start,) = summary["special_points"]
    along = sorted(curve, key=lambda r: float(r["ydot"]))
    speeds, pivots = [float(r["ydot"]) for r in along], [float(r["r_vpp"]) for r in along]
    assert np.interp(5.0, speeds, pivots) == pytest.approx(start["r_vpp"], abs=1e-5)
    (fold_flip,) = summary["curves"]["codimension_two_points"]
    assert fold_flip["type"] == "fold_flip" and fold_flip["ydot"] == pytest.approx(4.0019, abs=1e-3)
    near_one = [m for m in fold_flip["multipliers"] if abs(complex(*m) - 1) < 1e-4]
    assert len(near_one) == 2  # the structural one and the one crossing
    for row in along:  # the curve bounds stable gaits on the fast side of the fold-flip only
        if abs(float(row["ydot"]) - fold_flip["ydot"]) > 0.01:
            assert (row["stability_boundary"] == "true") == (float(row["ydot"]) > fold_flip["ydot"])


def test_a_vpp_fold_curve_keeps_a_second_multiplier_at_one_and_meets_the_period_doubling_curve(tmp_path):
    """curve_vpp_fold from the branch's +1 crossing at 3.9 m/s (measured: r_vpp = 0.39616
    m), over 3.8 to 4.2 m/s: two multipliers within 1e-6 of +1 at every point (measured
    6e-8), and its fold-flip is curve_vpp_pivot's (committed: r_vpp = 0.232644 m, ydot =
    4.001857 m/s), which a curve of the other kind, with the other deflation, located."""
    summary, branch, curve = run(tmp_path, "curve_vpp_fold", **{"second_range: [3.0, 6.0]": "second_range: [3.8, 4.2]"})
    (fold,) = [p for p in summary["special_points"] if p["type"] == "fold"]
    assert 0.3 < fold["r_vpp"] < 0.5
    assert [r for r in branch if r["special"] == "fold"]
    pivots = [float(r["r_vpp"]) for r in branch]  # the branch does not turn: r_vpp runs one way along it
    assert all(np.diff(pivots) > 0) or all(np.diff(pivots) < 0)
    assert len(curve) > 20
    for row in curve:
        near_one = np.sort(np.abs(multipliers(row) - 1))
        assert near_one[1] < 1e-6
    (fold_flip,) = summary["curves"]["codimension_two_points"]
    pd_summary = json.loads((ROOT / "results" / "curve_vpp_pivot" / "result.json").read_text())
    (pd_fold_flip,) = pd_summary["curves"]["codimension_two_points"]
    assert fold_flip["type"] == pd_fold_flip["type"] == "fold_flip"
    assert fold_flip["r_vpp"] == pytest.approx(pd_fold_flip["r_vpp"], abs=1e-5)
    assert fold_flip["ydot"] == pytest.approx(pd_fold_flip["ydot"], abs=1e-4)
    minus_one = [m for m in fold_flip["multipliers"] if abs(complex(*m) + 1) < 1e-4]
    assert len(minus_one) == 1  # the period doubling's multiplier, met there


class FreshNewtonCurve(CurveSystem):
    """A curve corrected by Newton's method with fresh Jacobians (not updated ones)."""

    costly_jacobian = False


def test_exact_and_differenced_second_derivatives_trace_the_same_curve(solver):
    """From a point of the committed Neimark-Sacker curve of the hanging gaits, the curve
    traced with exact second derivatives (AD of the compiled stride's Jacobian) and with
    central differences of the AD Jacobian takes the same steps to the same
    points, to 1e-8 in scaled units: the derivatives steer Newton and do not move points.
    Traced with fresh Newton Jacobians: the updated corrector's path, and with it whether
    a step counts as easy, follows its starting Jacobian, so that the two traces may
    choose other steps along the same curve."""
    problem = load_problem(ROOT / "problems" / "curve_downward_neimark_sacker.yaml")
    spec = problem.continuation
    start = read_csv(ROOT / "results" / "curve_downward_neimark_sacker" / "curve.csv")[0]
    traces = []
    for exact in (True, False):
        base = branch_system(fixed_point_spec(problem), spec.parameter, solver.residual_map, solver.jacobian_map,
                             second=spec.second, exact=exact)
        X = np.array([float(start[n]) for n in APEX.names])
        u = np.array([float(start[n]) for n in problem.hip_law.controls.names])
        v = base.pack(X, u, float(start[spec.parameter]), float(start[spec.second]))
        settings = Settings(step=spec.step, max_step=0.25, max_points=4)
        curve = trace_curve(FreshNewtonCurve(base, "neimark_sacker"), v, settings)
        traces.append(np.array([p.v for p in curve.points]))
    exact_points, differenced_points = traces
    assert exact_points.shape == differenced_points.shape and len(exact_points) >= 4
    assert np.max(np.abs(exact_points - differenced_points)) < 1e-8
