"""The examples run as they are shipped, and leave their files where they say."""

import csv
import importlib.util
import json
import math
import re
import subprocess
import sys

import pytest
from runs import ROOT


def test_the_tour_runs_and_writes_only_into_its_folder(tmp_path):
    done = subprocess.run([sys.executable, str(ROOT / "examples" / "tour.py"), str(tmp_path)],
                          capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "<FixedPointResult downward: converged, stable" in done.stdout
    # The tour's branch finds the SLIP band's fold where the shipped continuation study does
    # (test_branch_runs checks that study's edges against an independent SLIP).
    [shown] = re.findall(r"fold at theta_td = (\S+) deg", done.stdout)
    [fold] = [p for p in json.loads((ROOT / "results" / "continuation_slip_attack" / "result.json").read_text())[
        "special_points"] if p["type"] == "fold"]
    assert float(shown) == pytest.approx(math.degrees(fold["theta_td"]), abs=1e-4)
    written = {p.name for p in tmp_path.iterdir()}
    assert written == {"downward_gait.png", "downward_trajectory.csv", "tour_sweep", "band_diagram.png"}


def test_the_atlas_cross_check_runs_the_stability_nlp_from_each_polished_gait(tmp_path):
    """examples/schur_from_atlas.py on one polished gait of the committed upright atlas (the
    first where the committed cross-check's end is verified within 1 % of the atlas's
    radius): the NLP's end is verified at the atlas's radius, and the row says so (the
    stability NLP in the virtual machine: no compile in the tests)."""
    # Imported here, not at collection: the solver's module sets up the compiled engine,
    # which test_backend and test_compile expect to find untouched.
    from baslip.gait.fixedpoint import FixedPointSolver

    spec = importlib.util.spec_from_file_location("schur_from_atlas", ROOT / "examples" / "schur_from_atlas.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    with open(ROOT / "results" / "schur_from_atlas" / "crosscheck.csv", newline="") as handle:
        close = next((r["ydot"], r["z"], r["meaning"]) for r in csv.DictReader(handle) if r["verified"] == "True"
                     and abs(float(r["verified_radius"]) / float(r["atlas_radius"]) - 1) < 1e-2)
    with open(ROOT / "results" / "atlas_upright" / "atlas_best.csv", newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if (r["sweep_ydot"], r["sweep_z"], r["meaning"]) == close]
    atlas = tmp_path / "atlas"
    atlas.mkdir()
    with open(atlas / "atlas_best.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    solver = FixedPointSolver()
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("BASLIP_NO_COMPILE", "1")
        solver.stable_nlp()
    [row], record = example.crosscheck(atlas, ROOT / "problems" / "atlas_upright.yaml", solver)
    assert row["verified"], row["reason"]
    assert row["verified_radius"] == pytest.approx(float(rows[0]["spectral_radius"]), rel=1e-2)
    assert row["nlp_bound"] == pytest.approx(row["verified_radius"], rel=1e-2)
    assert record["problem"]["name"] == "atlas_upright"


def test_walking_and_running_draws_both_committed_branches_in_one_titled_figure(tmp_path):
    """examples/walking_and_running.py on the committed walks and runs: one figure, titled,
    its axes labelled with units, a stable (solid) and an unstable (dashed) line for each
    branch, and the runs ending at a smaller landing angle than the walks begin."""
    spec = importlib.util.spec_from_file_location("walking_and_running", ROOT / "examples" / "walking_and_running.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    figure = module.figure(ROOT / "results")
    [ax] = figure.axes
    assert ax.get_title().startswith("Walking and running at 80 kg")
    assert ax.get_xlabel() == "theta_td [deg from the vertical]" and ax.get_yscale() == "log"
    assert len(ax.lines) == 5  # two per branch, and the line at radius 1
    runs_end = max(x for x in ax.lines[3].get_xdata() if x == x)  # the runs' unstable line, NaNs left out
    walks_begin = min(x for line in ax.lines[:2] for x in line.get_xdata() if x == x)
    assert runs_end < walks_begin
    written = module.main(str(ROOT / "results"), str(tmp_path))
    assert written.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
