"""Specification of the ``atlas`` study (:mod:`baslip.studies.atlas`) and of the gait
manifold it covers (:mod:`baslip.analysis.gaitatlas`):

* the atlas coordinates map back and forth exactly, and the equations' Jacobian in them
  agrees with central differences of the residual;
* every chart in atlas.csv is a fixed point: the compiled map gives eps <= 1e-12 and the
  independent re-simulation the eps in its ``residual`` column (<= 1e-10 for a verified one);
* neighbours are mutual, every boundary has a reason, and cells.csv counts what atlas.csv
  and atlas_boundary.csv hold;
* the polished gaits of atlas_best.csv are verified fixed points, descended from local
  minima of the radius on the chart graph and no less stable than those charts, with both
  meanings of upright read off their trunk range;
* a study killed after its first cell and run again writes the same atlas.csv;
* a cell says on stderr what it is doing: covering, verifying, polishing;
* a cell of a problem with no guess seeds from the body alone;
* under the VPP law, z's periodicity row (implied at its symmetric gaits) is left out, so
  the equations keep full rank, and every committed chart is a symmetric fixed point of
  the independent simulation in all four rows.
"""

import csv
import json
import logging
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from baslip.analysis.gaitatlas import GaitManifold
from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.errors import ProblemError
from baslip.gait.from_problem import fixed_point_spec, solve_problem, solver_for
from baslip.gait.polish import eps
from baslip.model.dynamics import APEX
from baslip.model.quantities import DESIGN
from baslip.problem.reader import load_problem, parse_problem
from baslip.studies.atlascell import CellAtlas

ROOT = Path(__file__).resolve().parents[1]


def small_atlas(tmp_path: Path) -> Path:
    """Two hanging-trunk cells, two seeds each, at most 25 charts a cell, the best chart
    of each meaning polished by a descent of at most 60 iterations."""
    data = yaml.safe_load((ROOT / "problems" / "atlas_downward.yaml").read_text())
    data["name"] = "atlas_small"
    data["study"].update(vary={"ydot": [0.5, 0.5, 0.1], "z": [0.4, 0.45, 0.05]}, seeds=2, max_charts=25, polish=1,
                         iterations=60)
    path = tmp_path / "atlas_small.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def run(problem: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "baslip.solve", str(problem), "--out", str(out), "--quiet",
                             "--jobs", "1"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    folder = tmp_path_factory.mktemp("atlas")
    problem = small_atlas(folder)
    process = run(problem, folder / "out")
    _, err = process.communicate(timeout=1800)
    assert process.returncode == 0, err
    return problem, folder / "out"


def table(path: Path) -> list[dict]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_atlas_coordinates_round_trip_and_the_jacobian_matches_differences():
    problem = load_problem(ROOT / "problems" / "downward.yaml")
    gait = solve_problem(problem)
    spec = replace(fixed_point_spec(problem), fixed={"ydot": 0.5, "z": 0.4, "theta2_dot_des": 0.0})
    rmap = ReturnMap(Tolerances(1e-12, 1e-12))
    manifold = GaitManifold(spec, rmap, rmap)
    design = np.concatenate([gait.X, gait.u])
    design[DESIGN.index("theta2_dot_des")] = 0.0
    w = manifold.to_atlas(design)
    assert manifold.dimension == 2 and len(w) == 6
    assert np.allclose(manifold.to_design(w), design, rtol=1e-15, atol=1e-15)
    jacobian = manifold.jacobian(w)
    h = 1e-6
    for i in range(len(w)):
        step = np.eye(len(w))[i] * h
        difference = (manifold.evaluate(w + step).residual - manifold.evaluate(w - step).residual) / (2 * h)
        assert np.allclose(jacobian[:, i], difference, rtol=1e-4, atol=1e-6)


def test_every_chart_is_a_fixed_point_verified_independently(finished):
    problem_path, out = finished
    problem = load_problem(problem_path)
    charts = table(out / "atlas.csv")
    assert len(charts) >= 30
    compiled = ReturnMap(Tolerances(1e-12, 1e-12))
    independent = solver_for(problem).verify_map
    for row in charts[::5]:
        X = np.array([float(row[n]) for n in APEX.names])
        u = np.array([float(row[n]) for n in DESIGN[APEX.size:]])
        assert eps(compiled.stride(X, u, problem.params).apex, X) <= 1e-12
        check = eps(independent.stride(X, u, problem.params).apex, X)
        assert check == pytest.approx(float(row["residual"]), rel=1e-6, abs=1e-15)
        assert (row["status"] == "converged") == (check <= 1e-10)
        assert float(row["theta_h_min"]) <= X[APEX.index("theta_h")] <= float(row["theta_h_max"])


def test_neighbours_are_mutual_boundaries_have_reasons_and_the_counts_agree(finished):
    _, out = finished
    charts, boundaries, cells = table(out / "atlas.csv"), table(out / "atlas_boundary.csv"), table(out / "cells.csv")
    assert len(cells) == 2
    for cell in cells:
        mine = [c for c in charts if c["sweep_z"] == cell["sweep_z"]]
        edges = [b for b in boundaries if b["sweep_z"] == cell["sweep_z"]]
        assert int(float(cell["charts"])) == len(mine) <= 25
        assert int(float(cell["boundaries"])) == len(edges) and all(b["reason"] for b in edges)
        assert int(float(cell["pieces"])) == len({c["piece"] for c in mine})
        near = {c["chart"]: set(filter(None, c["neighbours"].split(";"))) for c in mine}
        assert all(c in near[n] for c, ns in near.items() for n in ns)
        radii = [float(c["spectral_radius"]) for c in mine if c["status"] == "converged"]
        assert float(cell["least_radius"]) == min(radii)
        if cell["polished_radius"]:  # the descent from the best chart never ends above it
            assert float(cell["polished_radius"]) <= float(cell["least_radius"]) * (1 + 1e-9)
    record = json.loads((out / "result.json").read_text())
    assert record["complete"] and record["charts"] == len(charts) and (out / "atlas.png").exists()
    assert not (out / ".cells.csv.charts").exists()  # the charts log is gone once atlas.csv is written


def test_the_polished_gaits_are_verified_and_no_less_stable_than_their_charts(finished):
    problem_path, out = finished
    problem = load_problem(problem_path)
    best, cells, charts = table(out / "atlas_best.csv"), table(out / "cells.csv"), table(out / "atlas.csv")
    independent = solver_for(problem).verify_map
    assert best, "no cell polished a gait"
    for row in best:
        X = np.array([float(row[n]) for n in APEX.names])
        u = np.array([float(row[n]) for n in DESIGN[APEX.size:]])
        assert eps(independent.stride(X, u, problem.params).apex, X) <= 1e-10
        start = next(c for c in charts if c["sweep_z"] == row["sweep_z"] and c["chart"] == row["from_chart"])
        assert float(row["start_radius"]) == float(start["spectral_radius"])
        # It started from a local minimum of the radius among the verified charts of its meaning.
        alike = {c["chart"]: c for c in charts if c["sweep_z"] == row["sweep_z"] and c["status"] == "converged"
                 and (row["meaning"] == "any" or c[row["meaning"]] == "true")}
        around = [alike[n] for n in start["neighbours"].split(";") if n in alike]
        assert all(float(n["spectral_radius"]) >= float(start["spectral_radius"]) for n in around)
        assert float(row["spectral_radius"]) <= float(start["spectral_radius"]) * (1 + 1e-6)
        low, high = float(row["theta_h_min"]), float(row["theta_h_max"])
        assert low <= X[APEX.index("theta_h")] <= high
        assert (row["upright_throughout"] == "true") == (max(abs(low - np.pi / 2), abs(high - np.pi / 2)) <= np.pi / 4)
        cell = next(c for c in cells if c["sweep_z"] == row["sweep_z"])
        column = "polished_radius" if row["meaning"] == "any" else "polished_upright_throughout_radius"
        assert float(cell[column]) == float(row["spectral_radius"])


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="kills a run")
def test_a_run_killed_after_its_first_cell_resumes_to_the_same_atlas(finished, tmp_path):
    problem, reference = finished
    out = tmp_path / "killed"
    process = run(problem, out)
    deadline = time.monotonic() + 1200
    while time.monotonic() < deadline and process.poll() is None:
        if (out / "cells.csv").exists() and len((out / "cells.csv").read_text().splitlines()) >= 2:
            break
        time.sleep(0.05)
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert not (out / "atlas.csv").exists()  # killed between the cells
    again = run(problem, out)
    _, err = again.communicate(timeout=1800)
    assert again.returncode == 0, err
    strip = lambda rows: [{k: v for k, v in r.items() if k != "time_s"} for r in rows]  # noqa: E731
    assert table(out / "atlas.csv") == table(reference / "atlas.csv")
    assert strip(table(out / "cells.csv")) == strip(table(reference / "cells.csv"))


def test_a_cell_logs_what_it_is_doing_phase_by_phase(caplog):
    caplog.set_level(logging.INFO, logger="baslip")
    problem = load_problem(ROOT / "problems" / "atlas_downward.yaml")
    study = replace(problem.study, seeds=1, max_charts=6, polish=1, iterations=2)
    row = CellAtlas(problem, study, quiet=False).run({"sweep_ydot": 0.5, "sweep_z": 0.4})
    lines = [r.getMessage() for r in caplog.records if r.name == "baslip.studies.atlascell"]
    assert lines and all(line.startswith("atlas_downward: cell ydot = 0.5, z = 0.4: ") for line in lines)
    assert any(line.endswith(f"{row['charts']} charts covered; finishing their independent verification") for line in lines)
    assert any(line.endswith("polishing (any): descent 1 of 1") for line in lines)


def test_a_cell_of_a_problem_with_no_guess_seeds_from_the_body_alone(caplog):
    """The hanging atlas at 0.5 m/s, 0.4 m with its guess removed: the cell's first seed is
    the shipped gait carried there, and its charts are verified fixed points."""
    caplog.set_level(logging.INFO, logger="baslip")
    problem = load_problem(ROOT / "problems" / "atlas_downward.yaml").replace(guess={}, posture="hanging")
    study = replace(problem.study, seeds=1, max_charts=4, polish=0, iterations=2)
    row = CellAtlas(problem, study).run({"sweep_ydot": 0.5, "sweep_z": 0.4})
    assert "start: the shipped gait 'downward'" in caplog.text and "no start from the body alone" not in caplog.text
    assert row["seeds_failed"] == 0 and row["charts"] >= 2
    assert all(c["status"] == "converged" and c["theta_h"] < 0 for c in row["chart_rows"])


@pytest.mark.parametrize("change, key", [
    ({"seeds": 0}, "study.seeds"), ({"radius": 0.0}, "study.radius"), ({"radius": 20.0}, "study.radius"),
    ({"max_radius": 0.1}, "study.max_radius"), ({"max_charts": 0}, "study.max_charts"), ({"polish": -1}, "study.polish"),
    ({"max_spectral_radius": 0.9}, "study.max_spectral_radius"), ({"max_spectral_radius": "big"}, "study.max_spectral_radius"),
    ({"iterations": 0}, "study.iterations"), ({"iterations": "many"}, "study.iterations"),
    ({"plot": ["Kp"]}, "study.plot"), ({"plot": ["Kp", "speed"]}, "study.plot"), ({"plot": ["Kp", "Kp"]}, "study.plot"),
    ({"plot": ["Kp", "theta2_dot_des"]}, "study.plot"), ({"plot": ["Kp", "z"]}, "study.plot"),
])
def test_bad_atlas_keys_are_refused_naming_the_key(change, key):
    data = yaml.safe_load((ROOT / "problems" / "atlas_upright.yaml").read_text())
    data["study"].update(change)
    with pytest.raises(ProblemError) as error:
        parse_problem(data)
    assert getattr(error.value, "key", None) == key


def test_an_atlas_of_a_manifold_above_three_dimensions_is_refused():
    data = yaml.safe_load((ROOT / "problems" / "atlas_upright.yaml").read_text())
    data["fix"] = {}
    data["study"]["vary"] = {"z": [0.4, 0.4, 0.1]}
    with pytest.raises(ProblemError) as error:
        parse_problem(data)
    assert error.value.key == "study" and "dimension 4" in error.value.message


#: How far above the multi-start search's least radius a cell's atlas answer may end,
#: relative. Where the least radius lies on the curve where two multipliers coalesce (at
#: every hanging cell the polished gait's leading multipliers are a complex pair 1e-5 to
#: 2e-3 off the real axis, about to split into two real ones, or three of equal modulus),
#: the radius rises like a square root off that curve and is flat along it: two local
#: descents that end on the curve a few 1e-4 rad apart in a gain differ by about 1e-4 of
#: the radius, though both found the same valley floor (the committed atlas ends above
#: the search by 5e-6 to 2.2e-5 at three cells).
CUSP_MARGIN = 1e-3


@pytest.mark.parametrize("atlas, search", [("atlas_upright", "optimal_upright"),
                                           ("atlas_downward", "optimal_downward")])
def test_the_committed_atlas_never_does_worse_than_the_multistart_search_at_its_cells(atlas, search):
    """At every cell of a committed atlas, its least radius (a chart's, or a polished
    gait's) is at most the least the multi-start optimal search found there, within
    :data:`CUSP_MARGIN`; docs/guides/atlas.md, Measured."""
    searched = json.loads((ROOT / "results" / search / "result.json").read_text())["least_per_point"]
    least = {(p["ydot"], p["z"]): p["spectral_radius"] for p in searched}
    cells = table(ROOT / "results" / atlas / "cells.csv")
    assert len(cells) == len(least) == 9
    worse = {}
    for cell in cells:
        key = (float(cell["sweep_ydot"]), float(cell["sweep_z"]))
        found = min(float(cell[c]) for c in ("least_radius", "polished_radius", "polished_upright_throughout_radius")
                    if cell[c])
        if found > least[key] * (1 + CUSP_MARGIN):
            worse[key] = (found, least[key])
    assert worse == {}


@pytest.mark.parametrize("atlas", ["atlas_upright", "atlas_downward", "atlas_upright_capped"])
def test_the_committed_polished_gaits_are_fixed_points_of_the_independent_simulation(atlas):
    problem = load_problem(ROOT / "problems" / f"{atlas}.yaml")
    independent = solver_for(problem).verify_map
    best = table(ROOT / "results" / atlas / "atlas_best.csv")
    assert best
    for row in best:
        X = np.array([float(row[n]) for n in APEX.names])
        u = np.array([float(row[n]) for n in DESIGN[APEX.size:]])
        assert eps(independent.stride(X, u, problem.params).apex, X) <= 1e-10
        assert float(row["residual"]) <= 1e-10


def test_the_committed_capped_atlas_grows_from_no_chart_above_its_cap():
    """In atlas_upright_capped every ``cap`` edge leaves a chart more unstable than the
    cap, and every corrector stop a chart within it (steps are taken only from those); a
    cell is marked covered whole exactly where no edge of it is a corrector stop or the
    chart limit."""
    problem = load_problem(ROOT / "problems" / "atlas_upright_capped.yaml")
    cap = problem.study.max_spectral_radius
    folder = ROOT / "results" / "atlas_upright_capped"
    charts = table(folder / "atlas.csv")
    radius = {(r["sweep_ydot"], r["sweep_z"], r["chart"]): float(r["spectral_radius"]) for r in charts}
    edges = table(folder / "atlas_boundary.csv")
    assert {e["kind"] for e in edges} >= {"cap", "domain"}
    for edge in edges:
        above = radius[edge["sweep_ydot"], edge["sweep_z"], edge["chart"]] > cap
        assert above if edge["kind"] == "cap" else not (edge["kind"] == "corrector" and above), edge
    stopped = {(e["sweep_ydot"], e["sweep_z"]) for e in edges if e["kind"] in ("corrector", "limit")}
    for cell in table(folder / "cells.csv"):
        assert (cell["complete"] == "true") == ((cell["sweep_ydot"], cell["sweep_z"]) not in stopped)


def test_under_vpp_the_implied_z_row_is_left_out_and_the_rest_keep_full_rank():
    """At the thesis-scale VPP gait the four periodicity rows have rank 3 in the free
    quantities (one follows from the others at a symmetric gait); the manifold keeps the
    other three, of full rank, so at fixed speed and height the family is a curve; its
    Jacobian agrees with central differences of the residual."""
    problem = load_problem(ROOT / "problems" / "vpp.yaml")
    gait = solve_problem(problem)
    spec = replace(fixed_point_spec(problem), fixed={"ydot": 0.5, "z": 0.4})
    rmap = ReturnMap(Tolerances(1e-12, 1e-12), law=problem.hip_law)
    manifold = GaitManifold(spec, rmap, rmap)
    w = manifold.to_atlas(np.concatenate([gait.X, gait.u]))
    assert manifold.names == ("theta_h", "theta_h_dot", "r_vpp", "theta_td") and manifold.dimension == 1
    jacobian = manifold.jacobian(w)
    assert jacobian.shape == (3, 4) and np.linalg.matrix_rank(jacobian, tol=1e-8) == 3
    dr_dX, dr_du = rmap.jacobians(gait.X, gait.u, problem.params)
    full = np.hstack([dr_dX - np.eye(APEX.size), dr_du])[:, manifold.free]
    singular = np.linalg.svd(full, compute_uv=False)
    assert singular[-1] <= 1e-8 * singular[0]  # all four rows: rank 3
    h = 1e-6
    for i in range(len(w)):
        step = np.eye(len(w))[i] * h
        difference = (manifold.evaluate(w + step).residual - manifold.evaluate(w - step).residual) / (2 * h)
        assert np.allclose(jacobian[:, i], difference, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("atlas", ["atlas_vpp", "atlas_vpp_human"])
def test_the_committed_vpp_atlas_charts_are_symmetric_fixed_points_in_all_four_rows(atlas):
    problem = load_problem(ROOT / "problems" / f"{atlas}.yaml")
    controls = problem.hip_law.controls.names
    compiled = ReturnMap(Tolerances(1e-12, 1e-12), law=problem.hip_law)
    independent = solver_for(problem).verify_map
    charts = table(ROOT / "results" / atlas / "atlas.csv")
    assert len(charts) >= 1000 and all(row["status"] == "converged" for row in charts)
    for row in charts[::40]:
        X = np.array([float(row[n]) for n in APEX.names])
        u = np.array([float(row[n]) for n in controls])
        assert eps(compiled.stride(X, u, problem.params).apex, X) <= 1e-11  # z's row too
        check = eps(independent.stride(X, u, problem.params).apex, X)
        assert check <= 1e-10 and check == pytest.approx(float(row["residual"]), rel=1e-6, abs=1e-15)
        assert abs(X[APEX.index("theta_h")] - np.pi / 2) <= 1e-9  # the symmetric family


def test_an_atlas_under_vpp_counts_the_implied_row_and_takes_a_polish():
    data = yaml.safe_load((ROOT / "problems" / "atlas_vpp.yaml").read_text())
    data["fix"] = {"z": data["guess"].pop("z")}
    data["study"]["plot"] = ["r_vpp", "theta_td"]
    parse_problem(data)  # a curve at each speed: dimension 1
    data["fix"]["r_vpp"] = data["guess"].pop("r_vpp")
    with pytest.raises(ProblemError) as error:
        parse_problem(data)
    assert error.value.key == "study" and "dimension 0" in error.value.message
    data = yaml.safe_load((ROOT / "problems" / "atlas_vpp.yaml").read_text())
    data["study"]["polish"] = 2  # the stability descent runs under every law
    assert parse_problem(data).study.polish == 2


@pytest.mark.parametrize("atlas", ["atlas_upright", "atlas_downward", "atlas_upright_capped"])
def test_a_committed_atlas_keeps_its_problem_hash_whether_or_not_it_sets_a_cap(atlas):
    """``max_spectral_radius`` came after the first atlases were committed: unset, it is
    left out of the hash, so their folders still belong to their problem files."""
    from baslip.files.provenance import problem_hash

    committed = json.loads((ROOT / "results" / atlas / "result.json").read_text())["provenance"]["problem_hash"]
    assert problem_hash(load_problem(ROOT / "problems" / f"{atlas}.yaml")) == committed


class _SlowCell(CellAtlas):
    """A cell that takes 100 s of the fake clock, saying how many charts it has as it
    goes, through the cell's own paced ``say``."""

    def __init__(self, problem, study, quiet):
        self.problem, self.study, self.quiet = problem, study, quiet

    def run(self, task):
        from baslip import diagnostics

        say = self._progress({"ydot": task["sweep_ydot"]})
        for charts in range(1, 21):
            diagnostics.CLOCK.advance(5.0)
            say(f"{charts} charts from 1 seeds")
        return {"sweep_ydot": task["sweep_ydot"], "charts": 20}


def test_an_atlas_is_heard_from_every_10_s_with_its_cell_s_news_and_quiet_silences_it(monkeypatch, tmp_path,
                                                                                      fake_clock):
    """Two cells of 100 s each: the study's line comes at least every 10 s, with the
    latest of the cell's own lines (at most one every PROGRESS_EVERY_S); quiet says nothing."""
    from fakeclock import collect_in_thread

    from baslip.studies import atlascell
    from baslip.studies.atlas import atlas_worker
    from baslip.studies.progress import Progress
    from baslip.studies.runner import ResumableCsv

    monkeypatch.setattr(atlascell, "CellAtlas", _SlowCell)
    problem = load_problem(ROOT / "problems" / "atlas_downward.yaml")
    lane = [{"sweep_ydot": 0.5}, {"sweep_ydot": 0.6}]
    for shown in (True, False):
        clock = fake_clock(shown)
        table = ResumableCsv(tmp_path / f"cells_{shown}.csv", ["sweep_ydot", "charts"], ["sweep_ydot"])
        ran = collect_in_thread(atlas_worker, lane, (problem, not shown), Progress("atlas", 2, not shown), table)
        assert ran == (2, False, "") and clock.time == 200.0 and clock.running() == 0
        if not shown:
            assert clock.said == []
            continue
        said = clock.messages()
        cells = [line for line in said if line.startswith("atlas_downward: cell ydot = 0.5: ")]
        assert cells[:2] == ["atlas_downward: cell ydot = 0.5: 3 charts from 1 seeds",
                             "atlas_downward: cell ydot = 0.5: 6 charts from 1 seeds"]
        assert "atlas: 0/2 done, 18 s so far, tasks running" in said
        assert clock.longest_silence(0.0, 200.0) <= 10.0


def test_a_finished_atlas_whose_atlas_csv_lost_the_end_of_its_last_row_solves_that_cell_again(finished, tmp_path):
    """Issue 57: such a folder stopped the rerun with "internal error: ValueError: its line 61 has 20 cells"."""
    problem, reference = finished
    out = tmp_path / "torn"
    shutil.copytree(reference, out)
    text = (out / "atlas.csv").read_text()
    (out / "atlas.csv").write_text(text[: len(text) - 40])
    again = run(problem, out)
    _, err = again.communicate(timeout=1800)
    assert again.returncode == 0, err
    assert table(out / "atlas.csv") == table(reference / "atlas.csv")
    assert table(out / "atlas_best.csv") == table(reference / "atlas_best.csv")
    record = json.loads((out / "result.json").read_text())
    assert record["done_before_this_run"] == 1 and record["done_in_this_run"] == 1  # the last cell again
