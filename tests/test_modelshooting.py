"""The multiple-shooting NLP of a described model's stride: from the first stride's
states it lands near the verified gait (its own discretisation), which Newton on the
exact map then polishes."""

import math

import pytest
from slip import ENERGY

from baslip.engine.hybrid import Resolution
from baslip.gait.modelshooting import ModelShootingNLP
from baslip.gait.modelsolver import ModelSolver
from baslip.model.catalogue.slip import SLIP
from baslip.problem.modelspec import ModelSpec


@pytest.fixture(scope="module")
def slip():
    spec = ModelSpec(SLIP, fixed={"energy": ENERGY, "theta_td": math.radians(22.0)}, guess={"z": 0.95, "ydot": 5.0})
    return spec, ModelSolver(spec)


def test_the_nlp_lands_near_the_verified_gait(slip):
    spec, solver = slip
    values = spec.values()
    first = solver.map.stride(*solver.split(spec, values), Resolution(0.01, 16), nodes=True)
    shot, status = ModelShootingNLP(solver.functions, spec, solver.kept_rows(spec, values)).solve(values, first)
    gait = solver.solve(spec)
    assert status == "Solve_Succeeded"
    assert shot["z"] == pytest.approx(gait.values["z"], abs=1e-6) and shot["ydot"] == pytest.approx(gait.values["ydot"],
                                                                                                   abs=1e-6)


def test_an_invariant_leaves_one_return_out_of_the_nlp(slip):
    spec, solver = slip
    assert len(solver.kept_rows(spec, spec.values())) == 1  # energy returns the other by itself
