"""Families of a described model's gaits: a branch through folds and period doublings,
and an atlas whose every chart centre is a verified gait, polished where it lies."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from slip import ENERGY

from baslip.analysis.atlas import AtlasSettings
from baslip.analysis.modelfamilies import continue_model, cover_model
from baslip.engine.hybrid import Resolution
from baslip.errors import ArgumentError
from baslip.gait.modelsolver import ModelSolver
from baslip.model.catalogue.slip import SLIP
from baslip.model.catalogue.walker import WALKER
from baslip.numerics.continuation import Settings
from baslip.problem.modelspec import ModelSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "problems" / "models"))
from hopper import HOPPER  # noqa: E402


@pytest.fixture(scope="module")
def hopper():
    spec = ModelSpec(HOPPER, fixed={"z": 1.0}, guess={"ydot": 5.0, "theta_td": 0.38, "push": 0.01},
                     bounds={"ydot": (2.0, 12.0)})
    solver = ModelSolver(spec)
    return solver, solver.solve(spec)


def test_the_hoppers_speed_branch_is_verified_throughout(hopper):
    solver, gait = hopper
    fixed = ModelSpec(HOPPER, fixed={"z": 1.0, "ydot": gait.values["ydot"]},
                      guess={"theta_td": gait.values["theta_td"], "push": gait.values["push"]})
    branch = continue_model(solver, solver.solve(fixed), "ydot", (3.0, 7.0), Settings(step=0.05, max_step=0.2))
    speeds = [p.values["ydot"] for p in branch.points]
    assert min(speeds) == pytest.approx(3.0) and max(speeds) == pytest.approx(7.0)
    assert all(p.verification <= 1e-10 for p in branch.points)
    assert np.all(np.diff(speeds) > 0)


def test_the_hoppers_gaits_at_one_height_are_covered_by_an_atlas(hopper):
    solver, gait = hopper
    atlas, charts = cover_model(solver, gait, AtlasSettings(max_charts=60))
    assert atlas.dimension == 1 and atlas.complete
    speeds = [c.values["ydot"] for c in charts]
    assert min(speeds) < 2.2
    assert max(speeds) > 11.8
    assert all(c.verification <= 1e-10 for c in charts)
    radii = sorted(c.spectral_radius for c in charts)
    assert radii[0] < 1.0 < radii[-1]  # the family crosses from unstable to stable gaits


def test_an_atlas_far_from_its_seed_polishes_each_centre_at_its_own_resolution():
    """The walker's walks at 820 J over landing angle and stiffness, from a seed at
    15 kN/m: one resolution for the whole atlas would miss the tolerance at some centres
    past 23 kN/m if it had 8 steps a mode (as the seed's calibration chose before it kept a
    margin of ten), and each centre is polished and verified at a resolution calibrated
    where it lies."""
    walk = {"rho": 0.9751422437843256, "rhodot": 0.0, "theta_dot": -1.1473830296337435,
            "theta_td": math.radians(21.0), "k": 15000.0}
    spec = ModelSpec(WALKER, fixed={"energy": 820.0}, guess=walk,
                     bounds={"k": (14000.0, 26000.0), "theta_td": (math.radians(20.0), math.radians(24.0))})
    solver = ModelSolver(spec)
    seed = solver.solve(spec)
    _, charts = cover_model(solver, seed, AtlasSettings(max_charts=25, radius=0.3, max_radius=0.5))
    far = [c for c in charts if c.values["k"] > 23000.0]
    assert len(far) >= 3
    # An unstable centre's own rounding is amplified by its multipliers: one may pass 1e-10 by a little.
    assert sum(c.verification <= 1e-10 for c in far) >= len(far) - 1
    assert max(c.verification for c in far) < 2e-10
    eight = Resolution(seed.resolution.scout, 8)
    coarse = [np.max(np.abs(solver.residual(spec, c.values, eight)[0])) for c in far]
    assert max(coarse) > 1e-10  # one such resolution would have missed the tolerance there


def test_an_atlas_needs_more_free_quantities_than_equations():
    spec = ModelSpec(SLIP, fixed={"energy": ENERGY, "theta_td": math.radians(22.0)}, guess={"z": 0.95, "ydot": 5.0})
    solver = ModelSolver(spec)
    with pytest.raises(ArgumentError, match=r"free: an atlas needs 1 to 3 more free quantities than equations"):
        cover_model(solver, solver.solve(spec))


def test_a_branch_parameter_must_be_fixed(hopper):
    solver, gait = hopper
    with pytest.raises(ArgumentError, match=r"parameter: 'ydot' must be a fixed quantity"):
        continue_model(solver, gait, "ydot", (3.0, 7.0))


def test_a_branch_may_follow_a_fixed_invariant_and_meets_the_band_edge_there():
    """The SLIP at 21 deg, followed in its energy: it crosses the period doubling where the
    branch in the touchdown angle at that energy has it (the same bifurcation)."""
    spec = ModelSpec(SLIP, fixed={"energy": ENERGY, "theta_td": math.radians(21.0)}, guess={"z": 0.94, "ydot": 5.1})
    solver = ModelSolver(spec)
    branch = continue_model(solver, solver.solve(spec), "energy", (1500.0, 2100.0), Settings(step=0.05, max_step=0.2))
    doubling = [p for p in branch.points if p.special == "period_doubling"]
    assert len(doubling) == 1 and doubling[0].verification <= 1e-10
    energy = doubling[0].values["energy"]
    assert 1500.0 < energy < ENERGY  # at 21 deg the band starts below 5 m/s
    at = ModelSpec(SLIP, fixed={"energy": energy, "theta_td": math.radians(21.5)},
                   guess={"z": doubling[0].values["z"], "ydot": doubling[0].values["ydot"]})
    crossing = continue_model(solver, solver.solve(at), "theta_td", (math.radians(20.5), math.radians(22.0)),
                              Settings(step=0.02, max_step=0.1))
    edge = [p for p in crossing.points if p.special == "period_doubling"]
    assert edge[0].values["theta_td"] == pytest.approx(math.radians(21.0), abs=1e-7)
