"""Specification of the homotopy paths (:mod:`baslip.gait.homotopy`):

* a path's body and fixed values run straight from its start (s = 0) to its end (s = 1);
* followed by pseudo-arclength, a path whose equations are square (the thesis's hanging
  gait with its gains held, carried from z = 0.40 m to 0.44 m) ends on the fixed point
  that a direct solve finds there, and the system's Jacobian agrees with central
  differences of its residual, the column along the path included;
* the start from the body alone follows the path by pseudo-arclength where natural steps
  break, and says so.
"""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baslip.gait import anybody
from baslip.gait.anybody import start_from_body
from baslip.gait.from_problem import fixed_point_spec, solve_problem, solver_for
from baslip.gait.homotopy import PathSystem, StraightPath, follow_path
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.quantities import POSTURE_BOUNDS
from baslip.model.similarity import Groups, groups
from baslip.problem.reader import Problem, load_problem
from baslip.status import Status

ROOT = Path(__file__).resolve().parents[1]
HELD = ("z", "ydot", "Kp", "Kd", "theta2_des")


@pytest.fixture(scope="module")
def held_gait():
    """The hanging gait of continuation_downward_height (its gains held), its values and solver."""
    problem = replace(load_problem(ROOT / "problems" / "continuation_downward_height.yaml"), continuation=None)
    solver = solver_for(problem)
    gait = solve_problem(problem, solver, progress=False)
    values = {**dict(zip(APEX.names, map(float, gait.X))), **dict(zip(gait.law.controls.names, map(float, gait.u)))}
    return problem, solver, values


def test_a_path_runs_straight_from_its_start_to_its_end():
    path = StraightPath(Groups(20.0, 0.08, 0.2), Groups(30.0, 0.05, 0.1), {"z": 0.4}, {"z": 0.5})
    assert path.body(0.0) == pytest.approx(path.body(0.0))
    for s in (0.0, 0.3, 1.0):
        group, fixed = path.at(s)
        assert group.stiffness == pytest.approx(20.0 + 10.0 * s) and fixed["z"] == pytest.approx(0.4 + 0.1 * s)
    middle = path.body(0.5).vector()
    assert middle == pytest.approx((path.body(0.0).vector() + path.body(1.0).vector()) / 2, rel=1e-12)


def test_a_square_path_followed_by_pseudo_arclength_ends_on_the_direct_solve(held_gait):
    problem, solver, values = held_gait
    start = {n: values[n] for n in HELD}
    path = StraightPath(groups(Params()), groups(Params()), start, {**start, "z": 0.44})
    followed = follow_path(path, problem.hip_law, values, 0.0, solver.residual_map,
                           {"theta_h": POSTURE_BOUNDS["hanging"]})
    assert followed.values is not None and not followed.turned and followed.points >= 2
    direct = solve_problem(replace(problem, fix={**problem.fix, "z": 0.44}), solver, progress=False)
    assert direct.status == Status.CONVERGED
    ended = [followed.values[n] for n in APEX.names + problem.hip_law.controls.names]
    assert ended == pytest.approx(list(direct.X) + list(direct.u), rel=1e-8, abs=1e-10)


def test_the_path_system_s_jacobian_agrees_with_differences_of_its_residual(held_gait):
    problem, solver, values = held_gait
    start = {n: values[n] for n in HELD}
    path = StraightPath(groups(Params()), Groups(24.0, 0.07, 0.15), start, {**start, "z": 0.42, "ydot": 0.6})
    system = PathSystem(path, problem.hip_law, values, 0.0, solver.residual_map, {})
    v = system.pack(0.0)
    h = 1e-6
    differences = np.column_stack([(system.residual(v + h * e) - system.residual(v - h * e)) / (2 * h)
                                   for e in np.eye(len(v))])
    assert system.jacobian(v) == pytest.approx(differences, rel=1e-5, abs=1e-7)


def test_where_natural_steps_break_the_start_follows_the_path_by_pseudo_arclength(monkeypatch):
    monkeypatch.setattr(anybody, "_solved", lambda *args: None)  # every natural step breaks
    human = Params(m=80.0, I=4.58, k=20000.0, rho0=1.0, d=0.1, g=9.81)
    task = Problem(name="arclength", params=human, hip_law=HIP_LAWS["pd"], fix={"z": 1.06, "ydot": 3.0},
                   posture="hanging")
    found = start_from_body(fixed_point_spec(task), solver_for(task, few_calls=True), "hanging")
    assert found.guess is not None and "by pseudo-arclength from 0% of the way" in found.origin
    assert math.sin(found.guess["theta_h"]) < 0
