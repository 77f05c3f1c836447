"""Specification of a gait's start from the body alone (:mod:`baslip.gait.anybody`):

* a body of the thesis's groups at another size, at the carried fixed values, takes the
  shipped gait carried over exactly, in one solve, and solves to it;
* a problem with no guess at all solves, verified (eps <= 1e-10), at each reference body
  (the thesis's; a human's, m 80 kg, I 4.58 kg m^2, k 20,000 N/m, rho0 1 m, d 0.1 m; a
  robot's of 2.474 kg, the Penn Jerboa's mass, leg and stiffness) under PD and under VPP,
  with the trunk as asked (upright or hanging);
* the shipped gaits are ranked by how far their body and fixed values lie;
* a posture no shipped gait has under a law is said, and the solve then starts from the
  default guess;
* where no path arrives, a seed at the cell (the nearest gait carried to the body, with
  its own gains or with gains drawn over their bounds) is the start;
* where no gait is found, the answer says which limit bounds it: at z = 0.9 m and 3 m/s
  the human under VPP is held by the foot's clearance at the apex.
"""

import logging

import numpy as np
import pytest

from baslip.gait import anybody
from baslip.gait.anybody import path_length, ranked_gaits, start_from_body
from baslip.gait.from_problem import fixed_point_spec, solve_problem, solver_for
from baslip.gait.knowngaits import known_gaits
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.similarity import body_with, carried, groups
from baslip.problem.reader import Problem
from baslip.status import Status

THESIS = Params()
HUMAN = Params(m=80.0, I=4.58, k=20000.0, rho0=1.0, d=0.1, g=9.81)
#: The Penn Jerboa's mass, leg and stiffness; its inertia and hip offset at the thesis's proportions.
ROBOT = Params(m=2.474, I=0.005624, k=1607.0, rho0=0.166, d=0.0332, g=9.81)


def problem(params: Params, law: str, fix: dict, posture: str = "any", **more) -> Problem:
    return Problem(name="body_alone", params=params, hip_law=HIP_LAWS[law], fix=fix, posture=posture, **more)


def test_a_similar_body_takes_the_shipped_gait_carried_over_exactly():
    downward = next(g for g in known_gaits() if g.name == "downward")
    body = body_with(groups(THESIS), size=Params(m=50.0, rho0=1.0, k=THESIS.k, I=THESIS.I, d=THESIS.d, g=THESIS.g))
    expected = carried(downward.values, THESIS, body)
    task = problem(body, "pd", {n: expected[n] for n in ("z", "ydot")}, "hanging")
    solver = solver_for(task, few_calls=True)
    found = start_from_body(fixed_point_spec(task), solver, "hanging")
    assert found.steps == 1 and "carried over exactly" in found.origin
    assert found.guess == pytest.approx({n: v for n, v in expected.items() if n not in ("z", "ydot")}, rel=1e-9)
    result = solve_problem(task, solver, progress=False)
    assert result.status == Status.CONVERGED and result.residual <= 1e-10
    assert result.X == pytest.approx([expected[n] for n in APEX.names], rel=1e-8)


CELLS = [
    ("thesis, PD", THESIS, "pd", {"z": 0.4, "ydot": 0.5}, "any"),
    ("thesis, PD, upright", THESIS, "pd", {"z": 0.45, "ydot": 0.6}, "upright"),
    ("thesis, VPP", THESIS, "vpp", {"z": 0.4, "ydot": 0.5, "r_vpp": 0.03}, "any"),
    ("human, PD, hanging", HUMAN, "pd", {"z": 1.06, "ydot": 3.0}, "hanging"),
    ("human, PD, upright", HUMAN, "pd", {"z": 1.06, "ydot": 3.0}, "upright"),
    ("human, VPP", HUMAN, "vpp", {"z": 1.06, "ydot": 3.0, "r_vpp": 0.1}, "any"),
    ("robot, PD, hanging", ROBOT, "pd", {"z": 0.21, "ydot": 1.0}, "hanging"),
    ("robot, PD, upright", ROBOT, "pd", {"z": 0.21, "ydot": 1.0}, "upright"),
    ("robot, VPP", ROBOT, "vpp", {"z": 0.21, "ydot": 1.0, "r_vpp": 0.0166}, "any"),
]


@pytest.mark.parametrize("params, law, fix, posture", [c[1:] for c in CELLS], ids=[c[0] for c in CELLS])
def test_a_problem_with_no_guess_solves_at_each_reference_body(params, law, fix, posture):
    result = solve_problem(problem(params, law, fix, posture), progress=False)
    assert result.status == Status.CONVERGED, result.message
    assert result.residual <= 1e-10
    assert result.X[APEX.index("z")] == fix["z"] and result.X[APEX.index("ydot")] == fix["ydot"]
    theta_h = result.X[APEX.index("theta_h")]
    assert posture == "any" or (np.sin(theta_h) > 0) == (posture == "upright")


def test_the_shipped_gaits_are_ranked_nearest_first():
    spec = fixed_point_spec(problem(HUMAN, "vpp", {"z": 1.1, "ydot": 5.0, "r_vpp": 0.1}))
    ranked = ranked_gaits(spec)
    assert [g.name for g in ranked] == ["vpp_human", "vpp"]
    assert path_length(ranked[0], spec) < 1e-12  # the shipped human gait is this very cell
    assert [g.name for g in ranked_gaits(fixed_point_spec(problem(THESIS, "pd", {"z": 0.4})), "hanging")] == ["downward"]


def test_a_posture_no_shipped_gait_has_is_said_and_the_default_guess_is_used(caplog):
    task = problem(THESIS, "vpp", {"z": 0.4, "ydot": 0.5, "r_vpp": 0.03}, "hanging")
    found = start_from_body(fixed_point_spec(task), solver_for(task, few_calls=True), "hanging")
    assert found.guess is None and found.origin.startswith("baslip ships no hanging gait under the vpp law to start from")
    with caplog.at_level(logging.WARNING, logger="baslip"):
        solve_problem(task, progress=False)
    assert "no start from the body alone (baslip ships no hanging gait under the vpp law" in caplog.text


def test_where_no_path_arrives_a_seed_with_drawn_gains_at_the_cell_is_the_start(monkeypatch):
    monkeypatch.setattr(anybody, "TRIED_GAITS", 0)  # as if every path broke
    task = problem(THESIS, "pd", {"z": 0.4, "ydot": 0.5, "theta2_dot_des": 0.0}, "hanging")
    solver = solver_for(task, few_calls=True)
    found = start_from_body(fixed_point_spec(task), solver, "hanging")
    assert found.guess is not None and "from seed" in found.origin and "at this cell" in found.origin
    assert 1 <= found.steps <= anybody.SEEDS and found.guess["theta_h"] < 0
    result = solve_problem(task, solver, progress=False)
    assert result.status == Status.CONVERGED and result.residual <= 1e-10


def test_where_no_gait_is_found_the_binding_limit_is_named():
    result = solve_problem(problem(HUMAN, "vpp", {"z": 0.9, "ydot": 3.0, "r_vpp": 0.1}), progress=False)
    assert result.status == Status.FAILED
    assert "foot clearance at apex" in [limit.name for limit in result.diagnosis.binding]
    assert any("raise z" in text for text in result.diagnosis.suggestions)
