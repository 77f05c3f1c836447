"""Specification of baslip.studies.branch: continuation runs on the shipped problems.

* ``direction: both`` traces the branch on both sides of its start.
* A branch ends exactly on the end of its range and never writes a point beyond it.
* A turn of the path in an apex coordinate is a ``turning_point``; a ``fold`` needs a
  multiplier crossing +1. The SLIP band's edges lie where an independent SLIP has them.
* A branch that stops at a grazing orbit says so.
"""

import csv
import math

import pytest
from runs import run_problem
from slip import least_excess, slip_fixed_point


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
    """The two-stride height branch turns back in z inside [0.4, 0.48] m: no multiplier
    crosses +1 there, so it is a turning point, and it is an extreme of z along its
    branch (here the lowest), with points traced on both sides of it."""
    summary, rows = run(tmp_path, "continuation_downward_height", **{"range: [0.3, 0.6]": "range: [0.4, 0.48]"})
    turning = [p for p in summary["special_points"] if p["type"] == "turning_point"]
    assert turning and not [p for p in summary["special_points"] if p["type"] == "fold"]
    z = turning[0]["z"]
    heights = [float(r["z"]) for r in rows if int(r["branch"]) == turning[0]["branch"]]
    assert 0.4 < z < 0.48
    lowest, highest = min(heights) >= z - 1e-9, max(heights) <= z + 1e-9
    assert lowest != highest  # a minimum or a maximum of z, not a constant
    extreme = heights.index(min(heights) if lowest else max(heights))
    assert 0 < extreme < len(heights) - 1 and abs(heights[extreme] - z) < 1e-4


def test_the_slip_bands_edges_are_a_fold_and_a_period_doubling_where_an_independent_slip_has_them(tmp_path):
    """The SLIP band's upper edge in theta_td is a saddle-node: a multiplier crosses +1
    there, so it stays a fold. Both edges lie within 0.001 deg of where the independent
    SLIP (``tests/slip.py``) has them: its fixed points vanish across the fold, and its
    multiplier crosses -1 across the period doubling."""
    summary, rows = run(tmp_path, "continuation_slip_attack",
                        **{'range: ["20 deg", "25 deg"]': 'range: ["21 deg", "24.5 deg"]', "  switch: period_doubling\n": ""})
    folds = [p for p in summary["special_points"] if p["type"] == "fold"]
    assert len(folds) == 1
    nearest = min(abs(complex(*m) - 1) for m in folds[0]["multipliers"])
    assert nearest < 1e-3
    [doubling] = [p for p in summary["special_points"] if p["type"] == "period_doubling"]
    assert_edges_of_the_independent_slip(folds[0], doubling, margin_deg=1e-3)


def assert_edges_of_the_independent_slip(fold: dict, doubling: dict, margin_deg: float) -> None:
    """The independent SLIP has its fold and its period doubling within ``margin_deg`` of
    baslip's special points ``fold`` and ``doubling`` (theta_td in rad from the vertical,
    and the apex there)."""
    fold_deg, z = math.degrees(fold["theta_td"]), fold["apex"]["z"]
    # A larger theta_td is a flatter landing: past the fold no fixed point is left.
    assert least_excess(90.0 - (fold_deg - margin_deg), z - 0.05, z + 0.05) < 0.0
    assert least_excess(90.0 - (fold_deg + margin_deg), z - 0.05, z + 0.05) > 0.0
    doubling_deg, z = math.degrees(doubling["theta_td"]), doubling["apex"]["z"]
    steeper = slip_fixed_point(90.0 - (doubling_deg - margin_deg), z, h=1e-4)
    flatter = slip_fixed_point(90.0 - (doubling_deg + margin_deg), z, h=1e-4)
    assert steeper[1] < -1.0 < flatter[1]
    assert steeper[0] == pytest.approx(z, abs=1e-6) and flatter[0] == pytest.approx(z, abs=1e-6)


def test_a_branch_ending_at_a_grazing_orbit_names_it(tmp_path):
    summary, _ = run(tmp_path, "continuation_slip_attack")
    doubled = [b for b in summary["branches"] if b["strides"] == 2]
    assert doubled and doubled[0]["stop_reason"].startswith("grazing: the apex of stride")
