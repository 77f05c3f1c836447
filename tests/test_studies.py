"""Specification of baslip.studies: resumable, parallel sweeps with CSV and JSON output.

A study writes one CSV row per finished point, appended as it finishes; rerunning skips
the rows already there, and a row cut short by a kill is dropped and redone.
"""

import csv
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from baslip.gait.fixedpoint import SolverReport
from baslip.problem.reader import Problem, ProblemError, load_problem, parse_problem
from baslip.problem.study import Sweep
from baslip.status import Status
from baslip.studies.adaptive import bisected_factor
from baslip.studies.registry import StaleFolder, run_study
from baslip.studies.runner import ResumableCsv
from baslip.studies.sweep import (
    RESULT_COLUMNS,
    WARM_STARTS,
    handed_on,
    interpolated_radius,
    radius_grid,
    solved_from,
    sweep_tasks,
)

GRID = """\
name: tiny_grid
guess: {theta_h: "-90 deg", theta_h_dot: 0.16, Kp: -0.75, Kd: 1.5, theta2_des: "-3 deg", theta2_dot_des: 1.4, theta_td: "6.6 deg"}
bounds: {theta_h: ["-100 deg", "-80 deg"]}
study:
  kind: sweep
  vary: {ydot: [0.4, 0.5, 0.1], z: [0.4, 0.45, 0.05]}
"""


def test_sweep_tasks_come_in_snake_order():
    problem = parse_problem({"study": {"kind": "sweep", "vary": {"ydot": [0.1, 0.3, 0.1], "z": [0.3, 0.4, 0.05]}}})
    assert isinstance(problem.study, Sweep)
    order = [(t["sweep_ydot"], t["sweep_z"]) for t in sweep_tasks(problem.study)]
    assert order == [(0.1, 0.3), (0.1, 0.35), (0.1, 0.4), (0.2, 0.4), (0.2, 0.35), (0.2, 0.3),
                     (0.3, 0.3), (0.3, 0.35), (0.3, 0.4)]


@pytest.mark.parametrize(
    "study, key",
    [
        ({"kind": "orbit"}, "study.kind"),
        ({"kind": "sweep", "vary": {"speed": [0, 1, 0.1]}}, "study.vary.speed"),
        ({"kind": "sweep", "vary": {"ydot": [1, 0, 0.1]}}, "study.vary.ydot"),
        ({"kind": "sweep", "vary": {"ydot": [0, 1, 0.1]}, "extra": 1}, "study.extra"),
        ({"kind": "random", "region": "grid", "count": 0}, "study.count"),
        ({"kind": "basin", "source": "g", "grid": {"z": [0.3, 0.4, 0.1], "ydot": [0.1, 0.2, 0.1]},
          "stable_at": {"ydot": 0.5, "z": 0.4}, "unstable_at": {"ydot": 0.5, "z": 0.3}}, "study.grid"),
    ],
)
def test_bad_study_sections_name_the_key(study, key):
    with pytest.raises(ProblemError) as err:
        parse_problem({"study": study})
    assert err.value.key == key


def test_resumable_csv_drops_a_row_cut_short(tmp_path):
    path = tmp_path / "points.csv"
    table = ResumableCsv(path, ["a", "b"], ["a"])
    table.append({"a": 0.1, "b": 1.0})
    with open(path, "a") as handle:
        handle.write("0.2,2.")  # a kill in mid-row
    reopened = ResumableCsv(path, ["a", "b"], ["a"])
    assert reopened.done() == {("0.1",)}
    assert path.read_text() == "a,b\n0.1,1.0\n"


def test_interpolated_radius_marks_the_region():
    rows = [{"sweep_ydot": y, "sweep_z": z, "status": "converged", "spectral_radius": r}
            for (y, z, r) in [(0.1, 0.3, 0.5), (0.2, 0.3, 1.5), (0.1, 0.4, 0.5), (0.2, 0.4, 1.5)]]
    a, b, radius = radius_grid(rows, ("ydot", "z"))
    assert interpolated_radius(a, b, radius, 0.15, 0.35) == pytest.approx(1.0)
    assert interpolated_radius(a, b, radius, 0.12, 0.35) < 1.0
    assert math.isnan(interpolated_radius(a, b, radius, 0.25, 0.35))


@pytest.fixture(scope="module")
def tiny_grid(tmp_path_factory):
    """A 2 x 2 grid run once in full; the tests below interrupt and resume copies of it."""
    folder = tmp_path_factory.mktemp("studies")
    problem_path = folder / "tiny_grid.yaml"
    problem_path.write_text(GRID)
    out = folder / "results" / "tiny_grid"
    problem = load_problem(problem_path)
    # The workers are given the problem itself: with its file gone meanwhile, they still
    # solve every point of the problem the run recorded.
    hidden = problem_path.rename(folder / "elsewhere.yaml")
    summary = run_study(problem, out, quiet=True)
    hidden.rename(problem_path)
    return problem_path, out, summary


def test_small_grid_end_to_end(tiny_grid):
    _, out, summary = tiny_grid
    assert summary["points"] == 4 and summary["complete"]
    assert summary["solved"] + summary["not_verified"] + summary["failed"] == 4
    with open(out / "points.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["sweep_ydot", "sweep_z", *RESULT_COLUMNS]
    for row in rows:
        assert row["status"] in ("converged", "not_verified", "failed")
        if row["status"] == "converged":
            assert float(row["residual"]) <= 1e-10
            assert float(row["ydot"]) == float(row["sweep_ydot"]) and float(row["z"]) == float(row["sweep_z"])
            assert row["stable"] == ("true" if float(row["spectral_radius"]) < 1 - 1e-6 else "false")
    record = json.loads((out / "result.json").read_text())
    for key in ("name", "kind", "points", "solved", "failed", "stable", "wall_time_s", "complete"):
        assert key in record
    assert (out / "spectral_radius_map.png").stat().st_size > 0
    assert (out / "theta_h_map.png").stat().st_size > 0


def test_rerunning_a_finished_study_solves_nothing(tiny_grid):
    problem_path, out, _ = tiny_grid
    again = run_study(load_problem(problem_path), out, quiet=True)
    assert again["done_in_this_run"] == 0 and again["done_before_this_run"] == 4
    assert len((out / "points.csv").read_text().splitlines()) == 5


def test_an_interrupted_study_resumes_where_it_stopped(tiny_grid):
    problem_path, out, _ = tiny_grid
    lines = (out / "points.csv").read_text().splitlines(keepends=True)
    # As if killed while writing the third row: two rows kept, the third cut short, and
    # result.json as the run's claim of the folder left it (its code not yet recorded).
    (out / "points.csv").write_text("".join(lines[:3]) + lines[3][:20])
    finished = json.loads((out / "result.json").read_text())
    claim = {"name": finished["name"], "kind": finished["kind"], "complete": False,
             "provenance": {**finished["provenance"], "code": {}}}
    (out / "result.json").write_text(json.dumps(claim))
    resumed = run_study(load_problem(problem_path), out, quiet=True)
    assert resumed["done_before_this_run"] == 2 and resumed["done_in_this_run"] == 2
    # The stopped run's code is not known: listed as null, not as having loaded nothing.
    stopped = {"versions": finished["provenance"]["versions"], "code": None}
    assert resumed["provenance"]["earlier_runs"] == [stopped, *finished["provenance"].get("earlier_runs", [])]
    assert resumed["provenance"]["code"]  # this run's own, recorded
    keys = [tuple(line.split(",")[:2]) for line in (out / "points.csv").read_text().splitlines()[1:]]
    assert len(keys) == len(set(keys)) == 4


def test_a_random_study_needs_its_region(tmp_path):
    problem_path = tmp_path / "r.yaml"
    problem_path.write_text("name: r\nstudy: {kind: random, region: nowhere, count: 3}\n")
    from baslip.cli.solve import main

    assert main([str(problem_path), "--out", str(tmp_path / "results" / "r")]) == 2
    assert not (tmp_path / "results").exists()  # nothing written


def test_csv_cells_are_plain_numbers():
    import numpy as np

    from baslip.studies.runner import format_value

    assert format_value(np.float64(0.25)) == "0.25" and format_value(np.int64(3)) == "3"
    assert format_value(np.bool_(True)) == "true" and format_value(None) == ""


def test_basin_study_on_a_finished_grid(tiny_grid):
    problem_path, out, _ = tiny_grid
    basin_path = problem_path.parent / "tiny_basin.yaml"
    basin_path.write_text(
        "name: tiny_basin\nstudy: {kind: basin, source: tiny_grid, stable_at: {ydot: 0.4, z: 0.4},"
        " unstable_at: {ydot: 0.4, z: 0.45}, grid: {ydot: [0.4, 0.5, 0.1], z: [0.4, 0.45, 0.05]},"
        " strides: 3, tolerance: 1.0e-3}\n"
    )
    basin_out = out.parent / "tiny_basin"
    summary = run_study(load_problem(basin_path), basin_out, quiet=True)
    stable = sum(1 for r in csv.DictReader(open(out / "points.csv")) if r["stable"] == "true")
    assert summary["stable_points"] == stable and summary["simulations"] == 4 * stable
    with open(basin_out / "basin.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["point", "sweep_ydot", "sweep_z", "outcome", "strides_run", "final_eps"]
    assert {r["outcome"] for r in rows} <= {"converged", "fell", "bounded"}
    assert json.loads((basin_out / "result.json").read_text())["complete"]


def one_at_a_time(recovered) -> tuple[float | None, set[float]]:
    """The largest recovered factor as a search asking one factor at a time finds it
    (doubling from 1 to 64, then 4 bisection steps), and the factors it asks."""
    asked = set()

    def ask(s):
        asked.add(s)
        return recovered(s)

    if not ask(1.0):
        return None, asked
    low, high = 1.0, 2.0
    while high <= 64.0 and ask(high):
        low, high = high, 2 * high
    if high <= 64.0:
        for _ in range(4):
            middle = (low + high) / 2
            low, high = (middle, high) if ask(middle) else (low, middle)
    return low, asked


@pytest.mark.parametrize("threshold", [0.5, 1.0, 3.3, 4.25, 4.2, 31.0, 64.0, 100.0])
def test_the_doublings_at_once_find_what_one_probe_at_a_time_finds(threshold):
    """The doublings of the largest recovered perturbation are probed at once, up to the
    first not recovered; the search asks the factors the one-at-a-time search asks, and
    gives its answer."""
    asked = set()

    def doublings_at(factors):
        answers = [s <= threshold for s in factors]
        if False in answers:
            answers = answers[: answers.index(False) + 1]
        asked.update(factors[: len(answers)])
        return answers

    def recovered(s):
        asked.add(s)
        return s <= threshold

    found = bisected_factor(doublings_at, recovered)
    factor, needed = one_at_a_time(lambda s: s <= threshold)
    assert found["factor"] == factor and asked == needed


def adaptive_problem(tmp_path, strides: int, frozen: int, criterion: str = "thesis") -> Path:
    text = (Path(__file__).resolve().parents[1] / "problems" / "adaptive_upright.yaml").read_text()
    text = text.replace("strides: 2048", f"strides: {strides}").replace("frozen_strides: 1000", f"frozen_strides: {frozen}")
    text = text.replace("probe_strides: 200", "probe_strides: 4").replace("criterion: thesis", f"criterion: {criterion}")
    problem_path = tmp_path / "adaptive.yaml"
    problem_path.write_text(text)
    return problem_path


@pytest.mark.parametrize("criterion", ["thesis", "tracking"])
def test_adaptive_study_resolves_the_control_each_stride(tmp_path, criterion):
    """From the perturbed upright gait, u is re-solved at every apex: the controls change,
    the least-squares residual is recorded (not zero: dr/du has rank 3), tracking pulls
    the apex back towards the gait, and the frozen control falls."""
    problem_path = adaptive_problem(tmp_path, 3, 200, criterion)
    out = tmp_path / "results" / "adaptive_upright"
    summary = run_study(load_problem(problem_path), out, quiet=True)
    assert summary["adaptive_strides"] == 3 and 0 < summary["max_eps"] < 1e-2
    assert summary["eps_to_gait"]["first"] > 5e-3  # it starts off the gait
    if criterion == "tracking":
        assert summary["eps_to_gait"]["last"] < summary["eps_to_gait"]["first"] / 5
    assert summary["frozen_strides_before_fall"] is not None  # an unstable gait falls once frozen
    assert summary["largest_recovered"]["factor"] >= 1
    with open(out / "strides.csv") as handle:
        controls = [r["Kp"] for r in csv.DictReader(handle) if r["phase"] == "adaptive"]
    assert len(set(controls)) == 3  # the control really changes from stride to stride
    with open(out / "strides.csv") as handle:
        phases = [r["phase"] for r in csv.DictReader(handle)]
    assert phases[:3] == ["adaptive"] * 3 and phases[-1] == "fall"
    again = run_study(load_problem(problem_path), out, quiet=True)
    assert again["adaptive_strides"] == 3 and len(open(out / "strides.csv").read().splitlines()) == len(phases) + 1


def test_a_resumed_adaptive_run_continues_from_the_apex_after_its_last_row(tmp_path):
    """Cut after three adaptive strides, the resumed run re-solves the control at the
    fourth apex (not the third again) and matches an uninterrupted run row for row."""
    problem_path = adaptive_problem(tmp_path, 6, 50)
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    run_study(load_problem(problem_path), whole, quiet=True)
    run_study(load_problem(problem_path), cut, quiet=True)
    lines = (cut / "strides.csv").read_text().splitlines(keepends=True)
    (cut / "strides.csv").write_text("".join(lines[:4]))  # header and three adaptive rows
    run_study(load_problem(problem_path), cut, quiet=True)

    def rows(folder):
        with open(folder / "strides.csv", newline="") as handle:
            return [{k: v for k, v in r.items() if k != "solve_time_s"} for r in csv.DictReader(handle)]

    assert [r["n"] for r in rows(cut) if r["phase"] == "adaptive"] == ["0", "1", "2", "3", "4", "5"]
    assert rows(cut) == rows(whole)


def test_one_quantity_sweeps_walk_outwards_from_the_start():
    from baslip.studies.sweep import sweep_lanes

    problem = parse_problem({"study": {"kind": "sweep", "vary": {"ydot": [0.0, 1.0, 0.25]}}})
    lanes = sweep_lanes(problem.study, {"ydot": 0.5})
    assert [[t["sweep_ydot"] for t in lane] for lane in lanes] == [[0.5, 0.75, 1.0], [0.25, 0.0]]


def test_an_optimal_study_descends_from_every_start(tmp_path):
    """One cell, three starts, two descent steps each (then the compass search, of up to
    600 trials, on the compiled engine: in CasADi's virtual machine it took 4.5 min): each
    row is its start's verified end point, never less stable than the gait it started
    from, and result.json names the least radius."""
    text = (Path(__file__).resolve().parents[1] / "problems" / "optimal_downward.yaml").read_text()
    text = text.replace("vary: {ydot: [0.3, 0.7, 0.2], z: [0.35, 0.45, 0.05]}", "vary: {ydot: [0.5, 0.5, 0.1], z: [0.4, 0.4, 0.1]}")
    assert "starts: 12" in text and "iterations: 150" in text
    text = text.replace("starts: 12", "starts: 3").replace("iterations: 150", "iterations: 2")
    problem_path = tmp_path / "optimal.yaml"
    problem_path.write_text(text)
    out = tmp_path / "results" / "optimal"
    summary = run_study(load_problem(problem_path), out, quiet=True)
    assert summary["complete"] and summary["points"] == 3
    with open(out / "points.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["start"] for r in rows] == ["0", "1", "2"]
    solved = [r for r in rows if r["status"] == "converged"]
    assert solved, "no start gave a fixed point"
    for row in solved:
        assert float(row["residual"]) <= 1e-10
        if row["start_radius"]:
            assert float(row["spectral_radius"]) <= float(row["start_radius"]) * (1 + 1e-9)
        assert float(row["trunk_min_deg"]) <= float(row["theta_h"]) * 180 / math.pi <= float(row["trunk_max_deg"])
    least = min(float(r["spectral_radius"]) for r in solved)
    assert summary["least"]["spectral_radius"] == pytest.approx(least)
    assert (out / "best_gaits_trunk.png").stat().st_size > 0


VPP_PARAMS = "params: {m: 1.0, I: 0.0033, k: 1000.0, rho0: 0.2, d: 0.04, g: 9.81}\nhip_law: vpp\n"


def test_basin_and_random_studies_run_under_vpp_from_a_vpp_sweep_and_refuse_another_laws(tmp_path):
    """A (ydot, z) sweep of thesis-scale VPP gaits at a low apex, where the VPP atlas finds
    stable ones; from it, a basin study (each stable gait, started at its own apex,
    converges at once) and a random sample inside its stable region; a PD study cannot
    read it."""
    from baslip.cli.solve import main

    results = tmp_path / "results"
    sweep = tmp_path / "vpp_grid.yaml"
    sweep.write_text("name: vpp_grid\n" + VPP_PARAMS + "fix: {r_vpp: 0.03}\n"
                     "guess: {theta_h: \"90 deg\", theta_h_dot: -0.3, theta_td: \"25 deg\"}\n"
                     "study: {kind: sweep, vary: {ydot: [2.25, 2.75, 0.25], z: [0.235, 0.255, 0.01]}}\n")
    run_study(load_problem(sweep), results / "vpp_grid", quiet=True)
    with open(results / "vpp_grid" / "points.csv") as handle:
        stable = [r for r in csv.DictReader(handle) if r["stable"] == "true"]
    assert stable
    basin = tmp_path / "vpp_basin.yaml"
    basin.write_text("name: vpp_basin\n" + VPP_PARAMS + "study: {kind: basin, source: vpp_grid, "
                     "stable_at: {ydot: 2.5, z: 0.245}, unstable_at: {ydot: 2.5, z: 0.245}, "
                     "grid: {ydot: [2.25, 2.75, 0.25], z: [0.235, 0.255, 0.01]}, strides: 20, tolerance: 1.0e-6}\n")
    summary = run_study(load_problem(basin), results / "vpp_basin", quiet=True)
    assert summary["stable_points"] == len(stable) and summary["simulations"] == 9 * len(stable)
    with open(results / "vpp_basin" / "basin.csv") as handle:
        runs = {(int(r["point"]), float(r["sweep_ydot"]), float(r["sweep_z"])): r for r in csv.DictReader(handle)}
    for k, point in enumerate(stable):
        own = runs[(k, float(point["sweep_ydot"]), float(point["sweep_z"]))]
        assert own["outcome"] == "converged" and own["strides_run"] == "1"
    sample = tmp_path / "vpp_sample.yaml"
    sample.write_text("name: vpp_sample\n" + VPP_PARAMS + "fix: {r_vpp: 0.03}\n"
                      "guess: {theta_h: \"90 deg\", theta_h_dot: -0.3, theta_td: \"25 deg\"}\n"
                      "study: {kind: random, region: vpp_grid, count: 2, seed: 1}\n")
    drawn = run_study(load_problem(sample), results / "vpp_sample", quiet=True)
    assert drawn["complete"] and drawn["solved"] == 2
    pd_basin = tmp_path / "pd_basin.yaml"
    pd_basin.write_text(basin.read_text().replace("hip_law: vpp\n", "").replace("vpp_basin", "pd_basin"))
    assert main([str(pd_basin), "--out", str(results / "pd_basin")]) == 2
    assert not (results / "pd_basin").exists()


def test_an_adaptive_study_under_vpp_resolves_the_pivot_and_touchdown_angle_and_falls_once_frozen(tmp_path):
    """The thesis-scale VPP gait (unstable, radius 4.6) under sec. 4.7's per-stride
    re-solve, tracking: both VPP controls change every stride, the runner keeps hopping
    and comes back towards the gait, and falls once the last control is held."""
    import yaml

    data = yaml.safe_load((Path(__file__).resolve().parents[1] / "problems" / "vpp.yaml").read_text())
    data["guess"]["r_vpp"] = data["fix"].pop("r_vpp")  # re-solved too, not held
    data["study"] = {"kind": "adaptive", "strides": 12, "frozen_strides": 300, "criterion": "tracking",
                     "perturbation": {"theta_h_dot": 0.05}, "probe_strides": 4}
    problem_path = tmp_path / "adaptive_vpp.yaml"
    problem_path.write_text(yaml.safe_dump(data))
    out = tmp_path / "adaptive_vpp"
    summary = run_study(load_problem(problem_path), out, quiet=True)
    assert summary["adaptive_strides"] == 12 and summary["adaptive_failure"] is None
    # Towards the gait's family, not X* itself: the symmetry direction is out of reach.
    assert summary["eps_to_gait"]["last"] < summary["eps_to_gait"]["first"] / 3
    assert summary["frozen_strides_before_fall"] is not None
    with open(out / "strides.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert "r_vpp" in rows[0] and "Kp" not in rows[0]
    adaptive = [r for r in rows if r["phase"] == "adaptive"]
    assert len({r["r_vpp"] for r in adaptive}) == 12 and len({r["theta_td"] for r in adaptive}) == 12
    assert (out / "adaptive_controls.png").stat().st_size > 0


def test_a_controllers_study_compares_four_controllers_on_the_same_starts_box_by_box(tmp_path, monkeypatch):
    """In CasADi's virtual machine, so that nothing is compiled: two boxes of the hanging
    gait, four perturbed starts each for the batched controllers, three for the horizon
    and two for the one-stride re-solve (the first of the same draws). The LQR weights
    are given (lqr_scale), so that no pilot sample runs in the virtual machine; the
    feedback stabilises the linearised loop. Another seed is another problem; more
    re-solved starts grow the folder in place."""
    monkeypatch.setenv("BASLIP_NO_COMPILE", "1")
    text = (Path(__file__).resolve().parents[1] / "problems" / "controllers_downward.yaml").read_text()
    text = (re.sub(r"solve_samples: \{horizon: \d+, resolve: \d+\}", "solve_samples: {horizon: 3, resolve: 2}", text)
            .replace("samples: 4000", "samples: 4")
            .replace("boxes: [1, 2, 4, 8, 16]", "boxes: [1, 4]").replace("strides: 100", "strides: 6")
            + "  lqr_scale: {z: 0.01, theta_h: 0.1, ydot: 0.1, theta_h_dot: 1.0}\n")
    assert "{horizon: 3, resolve: 2}" in text and "boxes: [1, 4]" in text  # the shipped file still reads so
    problem_path = tmp_path / "controllers.yaml"
    problem_path.write_text(text)
    out = tmp_path / "results" / "controllers"
    summary = run_study(load_problem(problem_path), out, quiet=True)
    assert summary["complete"] and summary["feedback"]["kind"] == "lqr" and "lqr_scale" in summary["feedback"]["reason"]
    assert summary["feedback"]["closed_loop_radius"] < 1
    with open(out / "controllers.csv") as handle:
        rows = list(csv.DictReader(handle))
    counts = {}
    for r in rows:
        counts[(r["controller"], float(r["box"]))] = counts.get((r["controller"], float(r["box"])), 0) + 1
    starts_of = {"constant": 4, "feedback": 4, "horizon": 3, "resolve": 2}
    assert counts == {(c, b): starts_of[c] for c in starts_of for b in (1.0, 4.0)}
    assert all(float(r["ms_per_stride"]) == float(f"{float(r['ms_per_stride']):.3g}") > 0 for r in rows)  # a measurement's digits
    starts = {}
    for r in rows:  # the same perturbed start for every controller, 4 times larger in the larger box
        starts.setdefault((float(r["box"]), r["sample"]), set()).add(
            tuple(float(r[f"d_{n}"]) for n in ("z", "theta_h", "ydot", "theta_h_dot")))
    assert all(len(s) == 1 for s in starts.values())
    widths = _controllers_section(text)["perturbation"]
    for (box, _), (start,) in starts.items():
        assert all(abs(d) <= box * widths[n] for d, n in zip(start, ("z", "theta_h", "ydot", "theta_h_dot")))
    assert set(summary["controllers"]) == set(summary["basins"]) == {"constant", "feedback", "horizon", "resolve"}
    for basin in summary["basins"].values():
        for b in basin["per_box"]:
            assert b["ci95"][0] <= b["returned_fraction"] <= b["ci95"][1]
    assert (out / "controllers.png").stat().st_size > 0 and (out / "basins.png").stat().st_size > 0

    # Another seed is another problem: refused over these rows, and a fresh run redraws them.
    reseeded = load_problem(problem_path).replace(study={**_controllers_section(text), "seed": 2})
    with pytest.raises(StaleFolder, match="different problem"):
        run_study(reseeded, out, quiet=True)
    again = run_study(reseeded, out, quiet=True, fresh=True)
    assert again["done_before_this_run"] == 0 and again["done_in_this_run"] == len(rows)
    with open(out / "controllers.csv") as handle:
        redrawn = list(csv.DictReader(handle))
    assert sorted(r["d_z"] for r in redrawn) != sorted(r["d_z"] for r in rows)

    # More re-solved starts only add tasks: the folder is resumed, its rows are kept to the
    # bit, and the run it extends is named in the provenance. Fewer starts, or more starts
    # with any other change, are another problem.
    def solving(counts: dict, **changes) -> Problem:
        return load_problem(problem_path).replace(study={**_controllers_section(text), "seed": 2,
                                                         "solve_samples": counts, **changes})

    with pytest.raises(StaleFolder, match="changed: study.solve_samples"):
        run_study(solving({"horizon": 3, "resolve": 1}), out, quiet=True)
    with pytest.raises(StaleFolder, match="changed: study.solve_samples, study.strides"):
        run_study(solving({"horizon": 3, "resolve": 3}, strides=5), out, quiet=True)
    grown = run_study(solving({"horizon": 3, "resolve": 3}), out, quiet=True)
    assert grown["complete"] and grown["done_before_this_run"] == len(redrawn) and grown["done_in_this_run"] == 2
    with open(out / "controllers.csv") as handle:
        extended = {(r["controller"], r["box"], r["sample"]): r for r in csv.DictReader(handle)}
    assert len(extended) == len(redrawn) + 2
    assert {key for key in extended if key[0] == "resolve"} == {("resolve", box, k) for box in ("1.0", "4.0") for k in "012"}
    assert all(extended[(r["controller"], r["box"], r["sample"])] == r for r in redrawn)
    (earlier,) = grown["provenance"]["earlier_runs"]
    assert earlier["problem_hash"] == again["provenance"]["problem_hash"] != grown["provenance"]["problem_hash"]
    assert dict(earlier["study"]["solve_samples"]) == {"horizon": 3, "resolve": 2}
    assert earlier["wall_time_s"] == again["wall_time_s"]
    rerun = run_study(solving({"horizon": 3, "resolve": 3}), out, quiet=True)  # finished: no solve, the record kept
    assert rerun["done_in_this_run"] == 0 and rerun["provenance"]["earlier_runs"] == grown["provenance"]["earlier_runs"]


def test_the_pivot_feedback_moves_the_vpp_pivot_alone_and_brings_back_starts_the_constant_law_loses(tmp_path):
    """Sharbafi's scheme on the thesis-scale VPP gait (unstable under its constant law,
    radius 4.6): the gain's touchdown-angle row is zero, its closed loop is the eigenvalues
    of A + B_r K_r with the pivot's column alone, and it brings back perturbed starts that
    all fall under the constant law. The LQR weights are given, so that no pilot runs."""
    from baslip.analysis.feedback import closed_loop_multipliers
    from baslip.gait.from_problem import solve_start, solver_for

    text = (Path(__file__).resolve().parents[1] / "problems" / "controllers_vpp.yaml").read_text()
    text = (re.sub(r"solve_samples: \{horizon: \d+, resolve: \d+\}", "solve_samples: 1", text)
            .replace("samples: 4000", "samples: 6")
            .replace("boxes: [1, 2, 4, 8, 16]", "boxes: [1]").replace("strides: 100", "strides: 40")
            .replace("controllers: [constant, feedback, pivot, horizon, resolve]", "controllers: [constant, pivot]")
            + "  lqr_scale: {z: 0.01, theta_h: 0.01, ydot: 0.01, theta_h_dot: 0.1}\n")
    assert "solve_samples: 1 " in text and "controllers: [constant, pivot]" in text  # the shipped file still reads so
    problem_path = tmp_path / "pivot.yaml"
    problem_path.write_text(text)
    problem = load_problem(problem_path)
    summary = run_study(problem, tmp_path / "pivot", quiet=True)
    pivot = summary["pivot"]
    assert pivot["rows"] == ["r_vpp", "theta_td"] and pivot["K"][1] == [0.0, 0.0, 0.0, 0.0]
    assert min(abs(k) for k in pivot["K"][0]) > 0
    solver = solver_for(problem)
    gait = solve_start(problem, solver)
    A, B = solver.jacobian_map.jacobians(gait.X, gait.u, problem.params)
    K = np.array(pivot["K"])
    expected = np.sort_complex(closed_loop_multipliers(A, B[:, :1], K[:1]))
    assert np.allclose(np.sort_complex(np.array([complex(*m) for m in pivot["closed_loop_multipliers"]])), expected)
    assert summary["gait"]["spectral_radius"] > 4 and pivot["closed_loop_radius"] < 1
    with open(tmp_path / "pivot" / "controllers.csv") as handle:
        rows = list(csv.DictReader(handle))
    outcomes = {(r["controller"], r["sample"]): r["outcome"] for r in rows}
    assert all(outcomes[("constant", str(k))] == "fell" for k in range(6))
    returned = [k for k in range(6) if outcomes[("pivot", str(k))] in ("converged", "settled")]
    assert returned  # with these given weights 2 of the 6 (the tool's weights do better, see results/)


def test_the_wilson_interval_holds_its_share_and_narrows_with_samples():
    from baslip.numerics.intervals import wilson_interval

    for samples in (10, 1000, 4000, 20000):  # all or none of the starts: the ends are exact
        assert wilson_interval(0, samples)[0] == 0.0 and wilson_interval(samples, samples)[1] == 1.0
    lo, hi = wilson_interval(3, 40)
    assert wilson_interval(37, 40) == pytest.approx((1 - hi, 1 - lo), abs=1e-15)  # symmetric in k -> n - k
    # None of n: the upper end is z^2 / (n + z^2) (0.2775 for n = 10), and all of n mirrors it.
    assert wilson_interval(0, 10)[1] == pytest.approx(1.96**2 / (10 + 1.96**2), abs=1e-12)
    assert wilson_interval(10, 10)[0] == pytest.approx(10 / (10 + 1.96**2), abs=1e-12)
    lo, hi = wilson_interval(45, 100)
    assert lo < 0.45 < hi and hi - lo == pytest.approx(0.19, abs=0.01)  # about 2 x 1.96 sqrt(p q / n)
    narrow, wide = wilson_interval(450, 1000), wilson_interval(45, 100)
    assert narrow[1] - narrow[0] < (wide[1] - wide[0]) / 3


def _controllers_section(text: str) -> dict:
    """The study section of a controllers problem's text, as plain data."""
    import yaml

    return yaml.safe_load(text)["study"]


def test_every_study_kind_is_registered_and_fresh_clears_its_tables():
    from baslip.files.runs import RUN_FILES
    from baslip.problem.study import STUDY_KINDS
    from baslip.studies.registry import DATA_FILES, KINDS

    assert set(KINDS) == set(STUDY_KINDS)
    assert set(DATA_FILES) <= set(RUN_FILES) and "controllers.csv" in DATA_FILES


@dataclass(frozen=True)
class Answer:
    """A stand-in for a fixed-point result: the start it came from, its status and time."""

    w0: float | None
    status: Status
    solver: SolverReport

    @property
    def converged(self) -> bool:
        return self.status == Status.CONVERGED


class ScriptedSolver:
    """Answers each start with the status ``outcomes`` gives it (1 s a solve)."""

    def __init__(self, outcomes: dict):
        self.outcomes, self.starts = outcomes, []

    def solve(self, spec, name, w0=None):
        start = None if w0 is None else float(w0[0])
        self.starts.append(start)
        return Answer(start, self.outcomes[start], SolverReport("Solve_Succeeded", 10, 1.0))


def test_a_lane_hands_on_its_latest_converged_points_newest_first():
    warm: list = []
    for state in ([1.0], None, [2.0], [3.0], None, [4.0]):
        warm = handed_on(warm, state)
    assert [w[0] for w in warm] == [4.0, 3.0, 2.0][:WARM_STARTS]


def test_an_unverified_answer_is_solved_again_from_the_warm_starts_before_it():
    """Where IPOPT's answer from the latest warm start is not verified, the point is solved
    from the ones before until one is verified, and the answer carries every try's time;
    a failed solve is not tried again (IPOPT gave up, at up to seconds a try)."""
    warm = [np.array([3.0]), np.array([2.0]), np.array([1.0])]
    solver = ScriptedSolver({3.0: Status.NOT_VERIFIED, 2.0: Status.NOT_VERIFIED, 1.0: Status.CONVERGED})
    answer = solved_from(solver, None, "lane", warm)
    assert answer.converged and answer.w0 == 1.0 and answer.solver.time_s == 3.0 and solver.starts == [3.0, 2.0, 1.0]
    never = ScriptedSolver({3.0: Status.NOT_VERIFIED, 2.0: Status.FAILED, 1.0: Status.NOT_VERIFIED})
    kept = solved_from(never, None, "lane", warm)
    assert kept.w0 == 3.0 and kept.status == Status.NOT_VERIFIED and kept.solver.time_s == 3.0
    failed = ScriptedSolver({3.0: Status.FAILED})
    assert solved_from(failed, None, "lane", warm).status == Status.FAILED and failed.starts == [3.0]
    fresh = ScriptedSolver({None: Status.CONVERGED})
    assert solved_from(fresh, None, "lane", []).converged and fresh.starts == [None]
