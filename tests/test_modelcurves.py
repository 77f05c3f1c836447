"""Bifurcation curves of a described model: the SLIP's period-doubling and fold curves in
(touchdown angle, energy) are those the BA-SLIP's SLIP limit traced (curve_slip_band),
every point verified independently."""

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from slip import ENERGY

from baslip.analysis.modelcurves import ModelCurveBase, trace_model_curve
from baslip.analysis.modelfamilies import continue_model
from baslip.errors import ArgumentError
from baslip.gait.modelsolver import ModelSolver
from baslip.model.catalogue.slip import SLIP
from baslip.numerics.continuation import Settings
from baslip.problem.modelspec import ModelSpec

COMMITTED = Path(__file__).resolve().parents[1] / "results" / "curve_slip_band" / "curve.csv"


@pytest.fixture(scope="module")
def band():
    spec = ModelSpec(SLIP, fixed={"energy": ENERGY, "theta_td": math.radians(21.0)}, guess={"z": 0.94, "ydot": 5.1})
    solver = ModelSolver(spec)
    gait = solver.solve(spec)
    branch = continue_model(solver, gait, "theta_td", (math.radians(20.0), math.radians(25.0)),
                            Settings(step=0.05, max_step=0.2))
    return solver, gait, {p.special: p for p in branch.points if p.special}


def committed_ends(kind: str) -> list[dict]:
    rows = [r for r in csv.DictReader(COMMITTED.open()) if r["type"] == kind]
    return [rows[0], rows[-1]]


@pytest.mark.parametrize("kind", ["period_doubling", "fold"])
def test_the_slips_band_edges_are_the_ba_slip_limits_curves(band, kind):
    solver, gait, special = band
    curve = trace_model_curve(solver, gait, kind, ("theta_td", "energy"), ((0.2, 0.6), (1424.8, 2224.8)),
                              at=special[kind].values)
    ends = {round(p.values["energy"], 6): p for p in (curve.points[0], curve.points[-1])}
    for row in committed_ends(kind):
        ours = ends[round(float(row["energy"]), 6)]
        assert ours.values["theta_td"] == pytest.approx(float(row["theta_td"]), abs=1e-9)
        assert ours.values["z"] == pytest.approx(float(row["z"]), abs=1e-8)
    assert all(p.verification <= 1e-10 for p in curve.points)
    critical = -1.0 if kind == "period_doubling" else 1.0
    for p in curve.points:  # one multiplier at the bifurcation's, besides the energy's 1
        assert np.min(np.abs(np.delete(p.multipliers, np.argmin(np.abs(p.multipliers - 1.0))) - critical)) < 1e-4


def test_the_map_on_the_energys_level_set_has_no_structural_multiplier(band):
    solver, gait, _ = band
    base = ModelCurveBase(solver, gait.spec, {**gait.values, "energy": ENERGY}, ("z", "ydot", "theta_td", "energy"),
                          gait.resolution)
    v = np.array([base.point(np.ones(4))[n] for n in base.names]) / base.scales
    reduced = base.map_jacobian(v)
    nontrivial = [m for m, t in zip(gait.multipliers, gait.trivial) if not t]
    assert reduced.shape == (1, 1) and reduced[0, 0] == pytest.approx(nontrivial[0].real, abs=1e-9)


def test_a_curve_needs_fixed_parameters_and_a_known_kind(band):
    solver, gait, _ = band
    with pytest.raises(ArgumentError, match=r"kind: expected one of"):
        trace_model_curve(solver, gait, "cusp", ("theta_td", "energy"), ((0.2, 0.6), (1400.0, 2200.0)))
    with pytest.raises(ArgumentError, match=r"parameters: 'z' must be a fixed quantity"):
        trace_model_curve(solver, gait, "fold", ("z", "energy"), ((0.2, 0.6), (1400.0, 2200.0)))
