"""Verified fixed points of a described model: the SLIP's against an independent SLIP, the
guide's hopper, and a guard that never fires named as the description's fault."""

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from slip import ENERGY, slip_fixed_point

from baslip.gait.modelsolver import ModelSolver, NoFixedPoint
from baslip.model.catalogue.slip import SLIP
from baslip.model.catalogue.walker import WALKER
from baslip.model.description import ModelError
from baslip.problem.modelspec import ModelSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "problems" / "models"))
from hopper import HOPPER  # noqa: E402


@pytest.fixture(scope="module")
def slip_gait():
    spec = ModelSpec(SLIP, fixed={"energy": ENERGY, "theta_td": math.radians(22.0)}, guess={"z": 0.95, "ydot": 5.0})
    return ModelSolver(spec).solve(spec)


def test_the_slip_gait_is_the_independent_slips(slip_gait):
    """Seyfarth et al.'s runner at 68 deg: tests/slip.py (RK4, bisected liftoff) gives the
    apex height and the one non-trivial multiplier."""
    z, multiplier = slip_fixed_point(68.0, 0.95)
    assert slip_gait.values["z"] == pytest.approx(z, abs=1e-9)
    nontrivial = [m for m, t in zip(slip_gait.multipliers, slip_gait.trivial) if not t]
    assert nontrivial == [pytest.approx(multiplier, abs=1e-5)]
    assert slip_gait.stable


def test_the_energys_multiplier_is_one_and_marked_trivial(slip_gait):
    trivial = [m for m, t in zip(slip_gait.multipliers, slip_gait.trivial) if t]
    assert trivial == [pytest.approx(1.0, abs=1e-9)]


def test_a_gait_is_verified_independently_and_keeps_its_energy(slip_gait):
    assert slip_gait.verification <= 1e-10 and slip_gait.residual <= 1e-10
    z, ydot = slip_gait.section
    assert 0.5 * 80 * ydot**2 + 80 * 9.81 * z == pytest.approx(ENERGY, rel=1e-13)


def test_the_result_is_plain_json(slip_gait):
    import json
    text = json.dumps(slip_gait.to_dict())
    assert '"model": "slip"' in text and '"trivial": true' in text


def test_the_guides_hopper_solves_with_its_push_making_up_for_its_damper():
    spec = ModelSpec(HOPPER, fixed={"z": 1.0, "ydot": 5.0}, guess={"theta_td": 0.38, "push": 0.01})
    gait = ModelSolver(spec).solve(spec)
    assert gait.verification <= 1e-10
    assert gait.values["push"] > 0
    assert len(gait.durations) == 4 and all(d > 0 for d in gait.durations)


def test_a_guard_that_never_fires_on_the_first_stride_is_the_descriptions_fault():
    never = replace(SLIP, transitions=(replace(SLIP.transitions[0], guard=lambda s, p, u: s.ydot + 10.0),
                                       SLIP.transitions[1]))
    spec = ModelSpec(never, fixed={"z": 1.0, "theta_td": 0.38}, guess={"ydot": 5.0})
    with pytest.raises(ModelError, match=r"model\.transitions\.touchdown\.guard: never fires on the stride from the guess"):
        ModelSolver(spec).solve(spec)


def test_a_start_that_falls_is_reported_as_no_fixed_point():
    spec = ModelSpec(SLIP, fixed={"z": 0.3, "theta_td": math.radians(80.0)}, guess={"ydot": 5.0})
    with pytest.raises(NoFixedPoint, match=r"the stride from the guess fails: fell: mass hit the ground"):
        ModelSolver(spec).solve(spec)


def test_the_jacobian_in_the_free_quantities_is_the_maps(slip_gait):
    solver = ModelSolver(slip_gait.spec)
    spec, values, resolution = slip_gait.spec, slip_gait.values, slip_gait.resolution
    r, jac = solver.residual(spec, values, resolution, jacobian=True)
    for i, name in enumerate(spec.free):
        up, down = dict(values), dict(values)
        up[name] += 1e-6
        down[name] -= 1e-6
        central = (solver.residual(spec, up, resolution)[0] - solver.residual(spec, down, resolution)[0]) / 2e-6
        assert jac[:, i] == pytest.approx(central, abs=1e-6)
    assert np.max(np.abs(r)) < 1e-10


def test_a_walker_steps_through_double_support_with_no_flight():
    """Nothing assumes one stance or a flight: the bipedal spring-mass walker at 820 J and
    a 69 deg angle of attack walks symmetrically (the two single supports equal, no
    vertical leg speed at mid-stance), verified, energy kept, one multiplier 1."""
    spec = ModelSpec(WALKER, fixed={"theta_td": math.radians(21.0), "energy": 820.0},
                     guess={"rho": 0.98, "rhodot": 0.0, "theta_dot": -1.1})
    gait = ModelSolver(spec).solve(spec)
    first, double, last = gait.durations
    assert gait.verification <= 1e-10 and 0 < double < first
    assert last == pytest.approx(first, rel=1e-9) and abs(gait.values["rhodot"]) < 1e-9
    assert sum(gait.trivial) == 1 and abs(gait.multipliers[list(gait.trivial).index(True)] - 1) < 1e-8


def test_a_family_with_an_invariant_solves_where_it_starts():
    """With the landing angle and the stiffness free at 820 J the walks form a surface;
    Newton's least-norm steps on the independent equations stay on it (the return the
    energy implies, kept, made a Jacobian singular but for rounding, and a step through
    that rounding leapt 15 deg off the walks)."""
    walk = {"rho": 0.9751422437843256, "rhodot": 0.0, "theta_dot": -1.1473830296337435,
            "theta_td": math.radians(21.0), "k": 15000.0}
    spec = ModelSpec(WALKER, fixed={"energy": 820.0}, guess=walk)
    gait = ModelSolver(spec).solve(spec)
    assert gait.verification <= 1e-10
    assert gait.values["theta_td"] == pytest.approx(walk["theta_td"], abs=1e-8)
    assert gait.values["k"] == pytest.approx(walk["k"], rel=1e-8)
