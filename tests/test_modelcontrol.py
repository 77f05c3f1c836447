"""Stride-to-stride controllers of a described model's gait: designed from the map's
exact Jacobians, checked by their closed-loop multipliers, and measured by their basins."""

import sys
from pathlib import Path

import numpy as np
import pytest

from baslip.analysis.modelcontrol import RETURNED, basin, design, families, grid_starts, returns
from baslip.gait.modelsolver import ModelSolver
from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.problem.modelspec import ModelSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "problems" / "models"))
from hopper import HOPPER  # noqa: E402


@pytest.fixture(scope="module")
def hop():
    spec = ModelSpec(HOPPER, fixed={"z": 1.0, "ydot": 5.0}, guess={"theta_td": 0.38, "push": 0.01})
    solver = ModelSolver(spec)
    gait = solver.solve(spec)
    return solver, gait, {c.name: c for c in design(solver, gait)}


def test_the_open_loop_is_the_gaits_own_multipliers(hop):
    _, gait, controllers = hop
    assert np.sort(np.abs(controllers["constant"].multipliers)) == pytest.approx(np.sort(np.abs(gait.multipliers)))
    assert controllers["constant"].spectral_radius > 1  # the hop at 5 m/s is unstable


def test_deadbeat_puts_every_multiplier_at_zero_and_returns_in_one_stride(hop):
    solver, gait, controllers = hop
    deadbeat = controllers["deadbeat"]
    assert deadbeat.spectral_radius < 1e-10
    start = gait.section * np.array([1.001, 0.999])
    ok, strides = returns(solver, gait, deadbeat, start, 5)
    assert ok and strides <= 2  # the linear error left after one stride is second order: 1e-6 < RETURNED


def test_lqr_stabilises_the_closed_loop(hop):
    assert hop[2]["lqr"].spectral_radius < 1


def test_the_measured_basins_rank_the_controllers(hop):
    solver, gait, controllers = hop
    starts = grid_starts(solver, gait, 0.1, 3)
    assert len(starts) == 9 and np.any(np.all(np.isclose(starts, gait.section), axis=1))
    shares = {name: sum(ok for ok, _ in basin(solver, gait, c, starts, 40)) for name, c in controllers.items()}
    assert shares["constant"] == 1  # the gait itself, and none of its neighbours
    assert shares["deadbeat"] >= 5 and shares["lqr"] >= 5  # LQR (radius 0.84) needs some 26 strides from 10 %


def test_a_start_returns_only_within_the_threshold(hop):
    solver, gait, controllers = hop
    ok, strides = returns(solver, gait, controllers["constant"], gait.section * (1 + 0.5 * RETURNED), 1)
    assert ok and strides == 0


def test_a_family_no_control_reaches_is_left_to_itself():
    """The upright VPP gait at the human body (problems/hip_laws_human_vpp.yaml) is one of
    a family: a multiplier 1 that neither the pivot nor the touchdown angle moves. The LQR
    is designed on the other three, which it makes stable, and the 1 stays; the hopper's
    gait has no such multiplier."""
    spec = ModelSpec(BA_SLIP, law="vpp", fixed={"m": 80.0, "I": 4.58, "k": 20000.0, "rho0": 1.0, "d": 0.1,
                                                 "z": 1.06, "ydot": 3.0},
                     guess={"theta_h": 1.5707963267948588, "theta_h_dot": -0.0889504, "r_vpp": 0.1,
                            "theta_td": 0.306543})
    solver = ModelSolver(spec)
    gait = solver.solve(spec)
    assert sum(gait.trivial) == 1  # the VPP law declares its family
    outcome = solver.stride(spec, gait.values, gait.resolution, jacobian=True)
    A, by_theta = outcome.jacobians()
    B = by_theta[:, [solver.functions.theta_names.index(n) for n in ("r_vpp", "theta_td")]]
    assert families(A, B, np.array([0.1, 0.3]), 0) == 1  # and the PBH test finds it undeclared
    controllers = {c.name: c for c in design(solver, gait)}
    lqr = controllers["lqr"]
    assert lqr.neutral == 1
    assert np.min(np.abs(lqr.multipliers - 1.0)) < 1e-7
    assert lqr.spectral_radius < 1 < controllers["constant"].spectral_radius
    assert "deadbeat" not in controllers  # two controls cannot reach four coordinates


def test_a_gait_with_no_family_has_none(hop):
    solver, gait, _ = hop
    outcome = solver.stride(gait.spec, gait.values, gait.resolution, jacobian=True)
    A, by_theta = outcome.jacobians()
    B = by_theta[:, [solver.functions.theta_names.index(n) for n in ("theta_td", "push")]]
    assert families(A, B, np.ones(2), sum(gait.trivial)) == 0
