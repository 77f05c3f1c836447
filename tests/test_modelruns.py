"""Runs of a described model's problem, from the command line and from Python: the gait,
its branch or atlas, the files written whole, and bad input refused with nothing written."""

import csv
import json
import shutil
from pathlib import Path

import pytest

import baslip
from baslip.cli.main import main
from baslip.errors import RunError
from baslip.problem.model_file import load_any_problem
from baslip.studies.modelruns import run_model_problem

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def problems(tmp_path):
    """A copy of the shipped problems and their models, as a user has them."""
    assert main(["problems", "--copy", str(tmp_path / "problems")]) == 0
    return tmp_path / "problems"


def test_the_hoppers_branch_is_written_with_every_point_verified(problems, tmp_path, capsys):
    out = tmp_path / "hopper"
    assert main(["solve", str(problems / "hopper.yaml"), "--out", str(out)]) == 0
    assert "hopper: model hopper" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["branch.csv", "branch.png", "result.json"]
    record = json.loads((out / "result.json").read_text())
    assert record["gait"]["verification"] <= 1e-10 and record["branch"]["verified"] == record["branch"]["points"]
    rows = list(csv.DictReader((out / "branch.csv").open()))
    assert float(rows[0]["ydot"]) == pytest.approx(3.0) and float(rows[-1]["ydot"]) == pytest.approx(7.0)


def test_the_hoppers_atlas_finds_its_stable_fast_gaits(problems, tmp_path):
    run = baslip.run(problems / "hopper_atlas.yaml", tmp_path / "atlas", progress=False)
    assert run.record["atlas"]["stable"] >= 1 and run.record["atlas"]["complete"]
    assert all(c.verification <= 1e-10 for c in run.charts)
    stable = [c.values["ydot"] for c in run.charts if c.spectral_radius < 1]
    assert min(stable) > 8.0  # only the fast hops are stable (the slow ones are not)
    assert (tmp_path / "atlas" / "charts.csv").is_file() and (tmp_path / "atlas" / "atlas.png").is_file()


def test_a_run_without_a_folder_writes_nothing(problems):
    run = run_model_problem(load_any_problem(problems / "slip_attack.yaml"))
    assert run.files == () and set(run.record["branch"]["special"]) == {"period_doubling", "fold"}


def test_a_bad_problem_is_one_line_exit_2_and_nothing_written(problems, tmp_path, capsys):
    bad = problems / "bad.yaml"
    bad.write_text((problems / "hopper.yaml").read_text().replace("HOPPER", "HOPPR"))
    assert main(["solve", str(bad), "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "model: HOPPR in hopper.py is nothing, not a baslip Model" in err
    assert not (tmp_path / "bad").exists()


def test_no_gait_is_exit_1_with_the_reason_and_nothing_written(problems, tmp_path, capsys):
    hopeless = problems / "hopeless.yaml"
    hopeless.write_text("model: slip\nfix: {z: 0.3, theta_td: '80 deg'}\nguess: {ydot: 5.0}\n")
    assert main(["solve", str(hopeless), "--out", str(tmp_path / "none")]) == 1
    assert "the stride from the guess fails: fell: mass hit the ground" in capsys.readouterr().err
    assert not (tmp_path / "none").exists()


def test_a_scheduler_is_refused_for_a_described_model(problems, capsys):
    assert main(["solve", str(problems / "hopper.yaml"), "--scheduler", "local"]) == 2
    assert "runs in this process" in capsys.readouterr().err


def test_run_model_refuses_a_ba_slip_problem():
    with pytest.raises(baslip.ProblemKindError, match="is a BA-SLIP problem"):
        baslip.run_model(ROOT / "problems" / "downward.yaml")


def test_the_model_file_moves_with_its_problem(problems, tmp_path):
    """A problem names its model file relative to its own folder, wherever that is."""
    moved = tmp_path / "elsewhere"
    shutil.copytree(problems, moved)
    (moved / "models" / "hopper.py").write_text((moved / "models" / "hopper.py").read_text().replace(
        'name="hopper"', 'name="moved hopper"'))
    assert load_any_problem(moved / "hopper.yaml").spec.model.name == "moved hopper"


def test_a_solver_failure_is_a_run_error_not_a_result(problems):
    """No SLIP gait lands at 80 deg from the vertical from a 0.3 m apex: neither the guess
    nor the reference carried there gives one, and the error says both."""
    path = problems / "hopeless.yaml"
    path.write_text("model: slip\nfix: {z: 0.3, theta_td: '80 deg'}\nguess: {ydot: 5.0}\n")
    with pytest.raises(RunError, match=r"no gait from the guess \(.*\), nor from the model's reference gait"):
        baslip.run_model(path, progress=False)


def test_a_controllers_study_measures_each_controllers_basin(problems, tmp_path):
    small = problems / "small_controllers.yaml"
    small.write_text((problems / "hopper_controllers.yaml").read_text().replace("grid: 9", "grid: 3").replace(
        "strides: 30", "strides: 40"))
    run = baslip.run_model(small, tmp_path / "basins", progress=False)
    shares = {c["name"]: c for c in run.record["controllers"]["controllers"]}
    assert set(shares) == {"constant", "deadbeat", "lqr"} and shares["constant"]["returned"] == 1
    assert shares["deadbeat"]["returned"] > 1 and shares["deadbeat"]["interval"][0] < shares["deadbeat"]["share"]
    rows = run.rows()
    assert len(rows) == 27 and {r["controller"] for r in rows} == set(shares)
    for name, share in shares.items():  # those that fell ran fewer strides than the study's
        assert share["fell"] == sum(not r["returned"] and r["strides"] < 40 for r in rows if r["controller"] == name)
    assert sorted(p.name for p in (tmp_path / "basins").iterdir()) == ["basins.csv", "basins.png", "result.json"]


def test_a_sweep_solves_each_point_from_its_neighbour_and_verifies_it(problems, tmp_path):
    small = problems / "small_sweep.yaml"
    small.write_text((problems / "hopper_sweep.yaml").read_text().replace("count: 5", "count: 2").replace(
        "count: 9", "count: 3"))
    run = baslip.run_model(small, tmp_path / "sweep", progress=False)
    rows = run.rows()
    assert len(rows) == 6 and all(r["status"] == "verified" and r["verification"] <= 1e-10 for r in rows)
    assert [(r["z"], r["ydot"]) for r in rows] == [(0.96, 3.0), (0.96, 7.0), (0.96, 11.0), (1.12, 11.0), (1.12, 7.0),
                                                   (1.12, 3.0)]
    assert run.record["sweep"]["stable"] == sum(r["stable"] for r in rows)


def test_a_runs_figures_are_named_by_their_files(problems):
    run = baslip.run_model(problems / "slip_band.yaml", progress=False)
    assert sorted(run.plot()) == ["branch", "curve"]


def test_where_the_guess_gives_no_gait_the_reference_gait_is_carried_there(problems):
    lost = problems / "lost.yaml"
    lost.write_text("model: models/hopper.py:HOPPER\nfix: {z: 1.0, ydot: 5.0}\nguess: {theta_td: -0.5, push: 0.01}\n")
    run = baslip.run_model(lost, progress=False)
    assert run.gait.verification <= 1e-10
    assert run.record["gait"]["start"].startswith("the model's reference gait, carried to the problem (the guess")
