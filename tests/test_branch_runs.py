"""Specification of baslip.studies.branch: continuation runs on the shipped problems.

* ``direction: both`` traces the branch on both sides of its start.
* A branch ends exactly on the end of its range and never writes a point beyond it.
* A turn of the path in an apex coordinate is a ``turning_point``; a ``fold`` needs a
  multiplier crossing +1.
* A branch that stops at a grazing orbit says so.
"""

import csv
import math

import pytest
from runs import run_problem


def run(tmp_path, name: str, **replacements) -> tuple[dict, list[dict]]:
    summary, out = run_problem(tmp_path, name, **replacements)
    with open(out / "branch.csv", newline="") as handle:
        return summary, list(csv.DictReader(handle))


def test_both_directions_cover_the_range_and_end_exactly_on_it(tmp_path):
    summary, rows = run(tmp_path, "continuation_downward_speed", **{"range: [0.05, 1.5]": "range: [0.4, 0.6]"})
    speeds = [float(r["ydot"]) for r in rows]
    assert min(speeds) == pytest.approx(0.4, abs=1e-12) and max(speeds) == pytest.approx(0.6, abs=1e-12)
    assert all(0.4 - 1e-12 <= s <= 0.6 + 1e-12 for s in speeds)
    assert speeds == sorted(speeds)  # the lower half reversed, then the upper half
    assert summary["branches"][0]["stop_reason"] == "lower end: end of range; upper end: end of range"


def test_a_turn_in_an_apex_coordinate_is_a_turning_point_not_a_fold(tmp_path):
    """The two-stride height branch turns back in z near 0.4692 m: no multiplier crosses
    +1 there, so it is a turning point."""
    summary, rows = run(tmp_path, "continuation_downward_height", **{"range: [0.3, 0.6]": "range: [0.4, 0.48]"})
    turning = [p for p in summary["special_points"] if p["type"] == "turning_point"]
    assert turning and not [p for p in summary["special_points"] if p["type"] == "fold"]
    assert turning[0]["z"] == pytest.approx(0.469194, abs=1e-5)


def test_a_fold_of_the_map_has_a_multiplier_at_one(tmp_path):
    """The SLIP band's upper edge (Seyfarth et al. 2002: 23.6945 deg) is a saddle-node:
    a multiplier crosses +1 there, so it stays a fold."""
    summary, rows = run(tmp_path, "continuation_slip_attack",
                        **{'range: ["20 deg", "25 deg"]': 'range: ["21 deg", "24.5 deg"]', "  switch: period_doubling\n": ""})
    folds = [p for p in summary["special_points"] if p["type"] == "fold"]
    assert len(folds) == 1 and math.degrees(folds[0]["theta_td"]) == pytest.approx(23.6945, abs=1e-3)
    nearest = min(abs(complex(*m) - 1) for m in folds[0]["multipliers"])
    assert nearest < 1e-3


def test_a_branch_ending_at_a_grazing_orbit_names_it(tmp_path):
    summary, _ = run(tmp_path, "continuation_slip_attack")
    doubled = [b for b in summary["branches"] if b["strides"] == 2]
    assert doubled and doubled[0]["stop_reason"].startswith("grazing: the apex of stride")
