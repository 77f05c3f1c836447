"""Specification of the ``families`` study (:mod:`baslip.studies.families`): which gaits
exist at one cell, and the most stable one.

* it takes the atlas's keys but ``vary`` (its cell is the problem's own), with a short
  budget of its own, and refuses a problem that fixes no cell;
* from the body alone (no guess) at the thesis's hanging cell, asked from Python
  (``baslip.families`` with a budget of its own), its answer
  agrees with the atlas files it wrote: each piece's charts, least radius and stable
  share; its best gait is a fixed point of the independent re-simulation (eps <= 1e-10)
  no less stable than the least chart; the search it reports (region, seeds, charts,
  where the covering stopped) is the one the files hold; its summary says so in words;
* at a body of the thesis's groups at another size (x 0.25 to x 5 in length, x 0.3 to x 50
  in mass) the answer is the thesis body's: the same charts and radii (its search is
  measured in the body's own units);
* where no gait exists (the human body with its apex too low for a leg within 20 deg of
  vertical to clear the ground), the answer says so and names the limits that bind, with
  what to change.
"""

import numpy as np
import pytest

import baslip
from baslip.errors import ProblemError
from baslip.files.rows import read_points
from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.gait.polish import eps
from baslip.model.dynamics import APEX, Params
from baslip.model.similarity import body_with, carried, groups
from baslip.problem.reader import parse_problem
from baslip.problem.study import Families, parse_study

THESIS = {"m": 1.0, "I": 0.0033, "k": 1000.0, "rho0": 0.2, "d": 0.04, "g": 9.81}
HUMAN = {"m": 80.0, "I": 4.58, "k": 20000.0, "rho0": 1.0, "d": 0.1, "g": 9.81}


def hanging_cell(**study) -> dict:
    """The thesis body at the downward gait's cell, trunk hanging, with no guess."""
    return {"name": "families_small", "params": THESIS, "fix": {"ydot": 0.5, "z": 0.4, "theta2_dot_des": 0.0},
            "posture": "hanging",
            "bounds": {"theta_h": ["-120 deg", "-60 deg"], "Kp": [-100, 100], "Kd": [-10, 10],
                       "theta_td": ["-45 deg", "45 deg"]},
            "study": {"kind": "families", **study}}


def test_a_families_study_has_the_atlas_keys_but_vary_and_a_short_budget_of_its_own():
    study = parse_study({"kind": "families"})
    assert isinstance(study, Families) and study.axes == ()
    assert (study.seeds, study.max_charts, study.polish, study.iterations, study.compass_trials) == (6, 120, 2, 20, 40)
    assert parse_study({"kind": "families", "seeds": 3, "max_charts": 50}).max_charts == 50
    with pytest.raises(ProblemError) as refused:
        parse_study({"kind": "families", "vary": {"ydot": [0.5, 0.5, 0.1]}})
    assert refused.value.key == "study.vary"


def test_a_families_study_of_a_problem_that_fixes_no_cell_is_refused():
    data = hanging_cell()
    data["fix"] = {}
    with pytest.raises(ProblemError) as refused:
        parse_problem(data)
    assert refused.value.key == "fix" and "cell" in refused.value.message


@pytest.fixture(scope="module")
def found(tmp_path_factory):
    folder = tmp_path_factory.mktemp("families") / "out"
    gait = hanging_cell()
    del gait["study"]  # a gait problem, asked at its cell from Python with a budget of its own
    budget = Families(seeds=2, seed=3, max_charts=12, polish=1, iterations=20)
    results = baslip.families(parse_problem(gait), out=folder, study=budget, jobs=1, progress=False)
    return parse_problem(hanging_cell(seeds=2, seed=3, max_charts=12, polish=1, iterations=20)), results, folder


def test_each_piece_of_the_answer_is_what_the_atlas_files_hold(found):
    _, results, folder = found
    answer = results.record["answer"]
    verified = [c for c in read_points(folder / "atlas.csv") if c["status"] == "converged"]
    assert answer["pieces"], "no gait found at the thesis's hanging cell"
    assert sum(p["charts"] for p in answer["pieces"]) == len(verified)
    for piece in answer["pieces"]:
        mine = [c for c in verified if c["piece"] == piece["piece"]]
        assert piece["least_radius"] == min(c["spectral_radius"] for c in mine)
        stable_area = sum(c["area"] for c in mine if c["stable"] is True)
        assert piece["stable_share"] == pytest.approx(stable_area / sum(c["area"] for c in mine), abs=1e-12)


def test_the_best_gait_is_verified_independently_and_no_less_stable_than_any_chart(found):
    problem, results, _ = found
    answer = results.record["answer"]
    independent = solver_for(problem).verify_map
    least_chart = min(p["least_radius"] for p in answer["pieces"])
    assert answer["best"]
    for gait in answer["best"]:
        X = np.array([gait[n] for n in APEX.names])
        u = np.array([gait[n] for n in problem.hip_law.controls.names])
        assert eps(independent.stride(X, u, problem.params).apex, X) <= 1e-10
        assert gait["theta_h"] < 0  # hanging, as asked
        if gait["meaning"] == "any":
            assert gait["spectral_radius"] <= least_chart * (1 + 1e-6)


def test_the_search_it_reports_is_the_one_the_files_hold(found):
    problem, results, folder = found
    searched = results.record["answer"]["searched"]
    spec = fixed_point_spec(problem)
    assert set(searched["region"]) == {n for n in spec.design if n not in spec.fixed}
    assert searched["region"]["Kp"] == [-100, 100]
    assert (searched["seeds"], searched["max_charts"]) == (2, 12)
    assert searched["charts"] == len(read_points(folder / "atlas.csv")) <= 12
    assert sum(searched["stopped"].values()) == len(read_points(folder / "atlas_boundary.csv"))
    text = results.summary()
    assert "most stable" in text and "searched: 2 seeds (the problem's own start, then gains Kp, Kd drawn" in text


def test_at_a_body_of_the_thesis_s_groups_at_another_size_the_answer_is_the_thesis_body_s():
    """The search is measured in the body's own units (atlas charts, drawn gains, descent
    steps, the equations' rows), so the same question at a similar body, the cell carried
    to it, finds the same gaits: the same charts, the same radii."""
    answers = []
    for size in (Params(), Params(m=50.0, rho0=1.0, g=9.81), Params(m=0.3, rho0=0.05, g=9.81)):
        body = body_with(groups(Params()), size=size)
        cell = carried({"z": 0.4, "ydot": 0.5}, Params(), body)
        gait = {**hanging_cell(), "params": vars(body), "fix": {**cell, "theta2_dot_des": 0.0}, "bounds": {}}
        del gait["study"]
        budget = Families(seeds=3, seed=3, max_charts=20, polish=1)
        answers.append(baslip.families(parse_problem(gait), study=budget, jobs=1, progress=False).record["answer"])
    thesis = answers[0]
    for answer in answers[1:]:
        assert [p["charts"] for p in answer["pieces"]] == [p["charts"] for p in thesis["pieces"]]
        for piece, same in zip(answer["pieces"], thesis["pieces"]):
            assert piece["least_radius"] == pytest.approx(same["least_radius"], rel=1e-8)
        assert answer["best"][0]["spectral_radius"] == pytest.approx(thesis["best"][0]["spectral_radius"], rel=1e-6)


def test_where_the_leg_cannot_reach_the_ground_steeply_enough_the_answer_names_the_binding_limits(tmp_path):
    # The human body at 3 m/s with its apex 0.95 m up, the trunk upright (the hip at least
    # 0.087 m above the CoM) and the leg within 20 deg of vertical (0.94 m tall at least):
    # the foot cannot clear the ground at the apex, so no gait exists.
    problem = parse_problem({"name": "families_none", "params": HUMAN, "posture": "upright",
                             "fix": {"ydot": 3.0, "z": 0.95, "theta2_dot_des": 0.0},
                             "bounds": {"theta_h": ["60 deg", "120 deg"], "theta_td": ["-20 deg", "20 deg"]},
                             "study": {"kind": "families", "seeds": 1, "max_charts": 5, "polish": 0}})
    answer = baslip.run(problem, out=tmp_path / "none", progress=False).record["answer"]
    assert answer["pieces"] == [] and answer["best"] == []
    diagnosis = answer["none_found"]["diagnosis"]
    assert "theta_td" in [limit["name"] for limit in diagnosis["binding"]]
    assert any("widen bounds.theta_td" in text for text in diagnosis["suggestions"])
    assert "no gait found" in answer["lines"][0] and "theta_td" in answer["lines"][1]
