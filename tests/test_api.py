"""Specification of baslip.api: ``baslip.run`` runs every kind of problem from Python.

* A gait, a study, a branch and a curve run from a problem built in Python (no YAML
  file, no subprocess) give the rows the command line writes for the same problem.
* Without ``out`` nothing is written, and the result holds its tables in memory; with
  ``out`` the folder holds exactly the command line's files.
* ``solve_problem`` refuses a problem that holds a study or a continuation, naming
  ``baslip.run`` (a ``baslip.ProblemKindError``); bad input to ``run`` is an ``InputError`` raised before any solve.
* ``families`` asks at a gait problem's cell: a problem holding another study or a
  continuation, or a budget that is no ``Families``, is refused before anything runs.
* A gait's ``animate()`` is one type, with or without IPython: it saves as a GIF and shows
  itself in a notebook as that GIF, embedded (nothing fetched from the web).
"""

import contextlib
import csv
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

import baslip
from baslip.cli.solve import main
from baslip.errors import InputError, ProblemKindError
from baslip.gait.fixedpoint import FixedPointResult
from baslip.results import RunResults

SLIP = {
    "params": {"m": 80.0, "I": 10.0, "k": 20000.0, "rho0": 1.0, "d": 0.0, "g": 9.81},
    "fix": {"energy": 1784.8, "theta_td": "21 deg", "theta_h": "90 deg", "theta_h_dot": 0.0,
            "Kp": 0.0, "Kd": 0.0, "theta2_des": 0.0, "theta2_dot_des": 0.0},
    "guess": {"z": 0.94, "ydot": 5.1},
}
SWEEP = {
    "name": "small_sweep",
    "params": {"m": 1.0, "I": 0.0033, "k": 1000.0, "rho0": 0.2, "d": 0.04, "g": 9.81},
    "guess": {"theta_h": "-90 deg", "theta_h_dot": 0.16, "Kp": -0.75, "Kd": 1.5, "theta2_des": "-3 deg",
              "theta2_dot_des": 1.4, "theta_td": "6.6 deg"},
    "bounds": {"theta_h": ["-100 deg", "-80 deg"]},
    "study": {"kind": "sweep", "vary": {"ydot": [0.4, 0.5, 0.1], "z": [0.4, 0.45, 0.05]}},
}
BRANCH = {"name": "small_branch", **SLIP,
          "continuation": {"parameter": "theta_td", "range": ["21 deg", "22 deg"], "step": 0.05, "direction": 1}}
CURVE = {"name": "small_curve", **SLIP,
         "continuation": {"parameter": "theta_td", "range": ["20 deg", "25 deg"], "step": 0.05, "direction": 1,
                          "second": "energy", "second_range": [1784.8, 1790.0], "follow": ["period_doubling"]}}


def command_line(tmp_path: Path, data: dict) -> Path:
    """Run ``data`` as a problem file through ``baslip solve`` in this process; its folder."""
    path = tmp_path / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "cli"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main([str(path), "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    return out


def without_timing(csv_text: str) -> list[dict]:
    """The rows of CSV text, less the wall-clock column a sweep records per point."""
    return [{k: v for k, v in row.items() if k != "time_s"} for row in csv.DictReader(io.StringIO(csv_text))]


def files_in(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir() if not p.name.startswith(".")}


@pytest.mark.parametrize("data, table", [(SWEEP, "points"), (BRANCH, "branch"), (CURVE, "curve")])
def test_run_gives_the_rows_of_the_command_line(tmp_path, data, table):
    problem = baslip.parse_problem(data)
    result = baslip.run(problem, progress=False, jobs=1)
    assert isinstance(result, RunResults) and result.folder is None
    cli = command_line(tmp_path, data)
    assert without_timing(result.texts[table]) == without_timing((cli / f"{table}.csv").read_text())
    assert set(result.tables) == {p.stem for p in cli.glob("*.csv")}
    assert result.summary().startswith(data["name"] + ":")
    assert len(result.to_dataframe(table)) == len(result.rows(table)) > 0
    assert result.name in repr(result)


def test_run_without_out_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)  # let TMPDIR take effect here
    result = baslip.run(baslip.parse_problem(BRANCH), progress=False)
    assert isinstance(result, RunResults) and result.rows("branch")
    assert os.listdir(tmp_path) == ["tmp"] and os.listdir(scratch) == []


def test_run_with_out_writes_the_command_lines_files(tmp_path):
    out = tmp_path / "api"
    result = baslip.run(baslip.parse_problem(SWEEP), out=out, progress=False, jobs=1)
    assert isinstance(result, RunResults) and result.folder == out
    assert files_in(out) == files_in(command_line(tmp_path, SWEEP))
    assert result.to_dataframe()["status"].eq("converged").all()


def test_run_of_a_gait_is_the_verified_fixed_point(tmp_path):
    path = Path(baslip.problems_dir()) / "downward.yaml"
    result = baslip.run(path, out=tmp_path / "gait")
    assert isinstance(result, FixedPointResult) and result.status == baslip.Status.CONVERGED
    assert result.status.message.startswith("a fixed point")
    assert files_in(tmp_path / "gait") == {"result.json", "multipliers.csv"}
    assert result.residual <= 1e-10
    frame = result.to_dataframe()
    assert list(frame["z"]) == [result.apex["z"]]


def test_a_gaits_animation_saves_a_gif_and_shows_it_embedded(tmp_path):
    import base64

    result = baslip.run("downward")
    animation = result.animate(strides=1)
    saved = animation.save(tmp_path / "gait.gif").read_bytes()
    assert saved[:6] == b"GIF89a" and len(saved) > 10_000
    page = animation._repr_html_()
    assert page.startswith('<img src="data:image/gif;base64,') and "http" not in page
    embedded = base64.b64decode(page.split("base64,")[1].split('"')[0])
    assert embedded[:6] == b"GIF89a" and abs(len(embedded) - len(saved)) < 0.01 * len(saved)


def test_solve_problem_refuses_a_study_and_names_run():
    assert baslip.ProblemKindError is ProblemKindError  # the error it raises, importable from baslip
    with pytest.raises(ProblemKindError, match=r"baslip\.run") as caught:
        baslip.solve_problem(baslip.parse_problem(SWEEP))
    assert caught.value.key == "study"
    with pytest.raises(ProblemKindError, match="continuation"):
        baslip.solve_problem(baslip.parse_problem(BRANCH))


def test_families_asks_at_a_gait_problem_s_cell_and_refuses_another_study_or_a_budget_of_another_kind(tmp_path):
    with pytest.raises(ProblemKindError) as caught:
        baslip.families(baslip.parse_problem(SWEEP), progress=False)
    assert caught.value.key == "study" and "sweep" in str(caught.value)
    with pytest.raises(ProblemKindError, match="continuation"):
        baslip.families(baslip.parse_problem(BRANCH), progress=False)
    with pytest.raises(InputError) as caught:
        baslip.families(baslip.parse_problem(SLIP), study="quick", progress=False)  # type: ignore[arg-type]
    assert caught.value.key == "study"
    assert files_in(tmp_path) == set()


def test_bad_input_is_refused_before_anything_runs(tmp_path):
    study = {**SWEEP, "study": {"kind": "basin", "source": "no_such_sweep", "stable_at": {"ydot": 0.6, "z": 0.4},
                                "unstable_at": {"ydot": 0.5, "z": 0.5},
                                "grid": {"ydot": [0.4, 0.5, 0.1], "z": [0.4, 0.45, 0.05]}}}
    problem = baslip.parse_problem(study)
    with pytest.raises(InputError) as caught:
        baslip.run(problem, out=tmp_path / "basin", progress=False)
    assert caught.value.key == "study.source" and "does not exist" in str(caught.value)
    with pytest.raises(InputError, match="--scheduler"):
        baslip.run(baslip.parse_problem(BRANCH), scheduler="local", progress=False)
    assert not (tmp_path / "basin").exists() or files_in(tmp_path / "basin") == set()


def test_a_folder_holds_one_run_and_another_needs_fresh(tmp_path):
    out = tmp_path / "shared"
    baslip.run(baslip.problems_dir() / "downward.yaml", out=out)
    with pytest.raises(InputError, match="holds a gait run, not a sweep one") as caught:
        baslip.run(baslip.parse_problem(SWEEP), out=out, progress=False)
    assert "--fresh" in str(caught.value) and files_in(out) == {"result.json", "multipliers.csv"}
    baslip.run(baslip.parse_problem(SWEEP), out=out, progress=False, fresh=True, jobs=1)
    assert "multipliers.csv" not in files_in(out) and "points.csv" in files_in(out)


def test_a_branch_over_a_curve_run_of_another_problem_is_refused(tmp_path):
    out = tmp_path / "continuation"
    baslip.run(baslip.parse_problem(CURVE), out=out, progress=False)
    assert "curve.csv" in files_in(out)
    with pytest.raises(InputError, match="holds the continuation of another problem"):
        baslip.run(baslip.parse_problem(BRANCH), out=out, progress=False)
    result = baslip.run(baslip.parse_problem(BRANCH), out=out, progress=False, fresh=True)
    assert "curve.csv" not in files_in(out) and "curve" not in result.tables


def test_a_gait_run_from_python_loads_neither_the_studies_nor_matplotlib(tmp_path, heavy_modules_after):
    """``baslip.run`` of a single gait stays clear of the study modules and matplotlib, as
    the command's does (``test_solve.py``): they are imported only by the runs that use them."""
    statement = f"import baslip; result = type(baslip.run('problems/downward.yaml', {str(tmp_path / 'downward')!r})).__name__"
    assert heavy_modules_after(statement) == ("FixedPointResult", [])


def test_solve_problem_shows_progress_unless_asked_not_to_and_leaves_the_level_as_it_was():
    """A script calling solve_problem alone, with no logging set up, hears its progress (a
    first run's compiles, IPOPT's second try) on stderr, as ``baslip.run`` does; with
    ``progress=False`` nothing below a warning is shown while it runs, and the level is
    restored after."""
    script = (
        "import logging, baslip\n"
        "from baslip.diagnostics import logger\n"
        "from baslip.gait.fixedpoint import FixedPointSolver as solver\n"
        "shown = []\n"
        "probe = logger('baslip.probe')\n"
        "solve = solver.solve\n"
        "def solve_and_probe(self, *a, **k):\n"
        "    shown.append(probe.isEnabledFor(logging.INFO))\n"
        "    return solve(self, *a, **k)\n"
        "solver.solve = solve_and_probe\n"
        "problem = baslip.load_problem('downward')\n"
        "baslip.solve_problem(problem, progress=False)\n"
        "after_quiet = probe.isEnabledFor(logging.INFO)\n"
        "assert baslip.solve_problem(problem).status == 'converged'\n"
        "print(shown, after_quiet)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["[False,", "True]", "False"]
