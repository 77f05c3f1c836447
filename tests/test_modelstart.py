"""A described model's gait with no guess: its reference carried to the problem, exactly
where the body is similar, along a homotopy where it is not; each end verified."""

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baslip.analysis.modelstart import NoStart, reference_start
from baslip.gait.modelsolver import ModelSolver
from baslip.model.catalogue.slip import SLIP
from baslip.model.catalogue.walker import WALKER
from baslip.model.sizes import similarity
from baslip.problem.modelspec import ModelSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "problems" / "models"))
from hopper import HOPPER  # noqa: E402

#: A robot-sized SLIP of the human runner's groups: 2.5 kg on a 0.17 m leg.
SMALL = {"m": 2.5, "l0": 0.17, "k": 20000.0 * (2.5 / 80.0) / 0.17}


def test_a_similar_body_runs_the_reference_gait_scaled_with_its_multipliers():
    """Fixing only what scales (the angle, and the apex height in leg lengths), the
    carried start is the reference gait itself, scaled: a fixed point already."""
    reference = SLIP.reference
    spec = ModelSpec(SLIP, fixed={**SMALL, "theta_td": reference["theta_td"], "z": reference["z"] * 0.17},
                     guess={"ydot": 1.0})
    solver = ModelSolver(spec)
    start = reference_start(solver, spec)
    assert start["ydot"] == pytest.approx(reference["ydot"] * math.sqrt(0.17), rel=1e-12)
    gait = solver.solve(replace(spec, guess={"ydot": start["ydot"]}))
    human = solver.solve(ModelSpec(SLIP, fixed={"theta_td": reference["theta_td"], "z": reference["z"]},
                                   guess={"ydot": 5.0}))
    assert gait.verification <= 1e-10
    assert np.sort(gait.multipliers.real) == pytest.approx(np.sort(human.multipliers.real), abs=1e-8)


def test_another_body_and_cell_are_reached_along_the_path_and_verified():
    spec = ModelSpec(SLIP, fixed={**SMALL, "k": 3 * SMALL["k"], "theta_td": math.radians(25.0), "z": 0.1615},
                     guess={"ydot": 1.0})
    solver = ModelSolver(spec)
    start = reference_start(solver, spec)
    gait = solver.solve(replace(spec, guess={"ydot": start["ydot"]}))
    assert gait.verification <= 1e-10 and gait.values["ydot"] == pytest.approx(start["ydot"], abs=1e-8)


def test_the_hopper_at_robot_size_starts_from_its_reference():
    spec = ModelSpec(HOPPER, fixed={"m": 2.5, "k": 1600.0, "c": 2.0, "l0": 0.17, "z": 0.17, "ydot": 1.0},
                     guess={"theta_td": 0.0, "push": 0.0})
    solver = ModelSolver(spec)
    start = reference_start(solver, spec)
    gait = solver.solve(replace(spec, guess={n: start[n] for n in spec.free}))
    assert gait.verification <= 1e-10 and 0 < gait.values["push"] < 0.17


def test_a_body_changed_in_one_parameter_starts_on_the_similar_body_not_the_default():
    """Only k is fixed, to 15 kN/m: the nearest similar body changes m, l0 and g too, and
    the path starts there (every quantity held at the start's value), not on a mix of
    that body's k and the defaults' m, l0 and g, where the scaled walk is no walk."""
    spec = ModelSpec(WALKER, fixed={"k": 15000.0, "theta_td": math.radians(21.0), "energy": 820.0},
                     guess={"rho": 1.0, "rhodot": 0.0, "theta_dot": -1.0})
    scale = similarity(WALKER, {**spec.values()})
    assert scale.distance > 0.01 and not math.isclose(scale.length, 1.0, rel_tol=1e-3)
    solver = ModelSolver(spec)
    start = reference_start(solver, spec)
    gait = solver.solve(replace(spec, guess={n: start[n] for n in spec.free}))
    assert gait.verification <= 1e-10 and abs(gait.values["rhodot"]) < 1e-9
    assert gait.values["theta_dot"] == pytest.approx(start["theta_dot"], rel=1e-8)


def test_a_model_without_a_reference_asks_for_a_guess():
    bare = replace(SLIP, reference={})
    spec = ModelSpec(bare, fixed={"z": 1.0, "theta_td": 0.4}, guess={"ydot": 5.0})
    with pytest.raises(NoStart, match="names no reference gait to start from: give a guess"):
        reference_start(ModelSolver(spec), spec)


def test_the_time_scale_is_the_bodys_own():
    assert SLIP.time_scale({"m": 80.0, "k": 2e4, "l0": 1.0, "g": 9.81}) > 0
    ratio = SLIP.time_scale({**SMALL, "g": 9.81}) / SLIP.time_scale({"m": 80.0, "k": 2e4, "l0": 1.0, "g": 9.81})
    assert ratio == pytest.approx(math.sqrt(0.17))
