"""Specification of baslip.gait.describe: the summary a solve prints for people.

* Angles and rates are in degrees and deg/s (data files keep radians).
* Multipliers are listed by modulus, largest first (the files keep the solver's order).
"""

import dataclasses
import math
import re

import pytest

from baslip.gait.describe import summary_text
from baslip.gait.from_problem import solve_problem
from baslip.problem.reader import load_problem


@pytest.fixture(scope="module")
def downward():
    return solve_problem(load_problem("downward"))


def test_the_summary_gives_angles_and_rates_in_degrees(downward):
    text = summary_text(downward)
    assert re.findall(r"\brad\b(?!/s)|rad/s", text.replace("N m/rad", "").replace("N m s/rad", "")) == []
    shown = float(re.search(r"theta_h_dot = (\S+) deg/s", text).group(1))
    assert shown == pytest.approx(math.degrees(downward.apex["theta_h_dot"]), abs=1e-4)
    shown = float(re.search(r"theta2_dot_des = (\S+) deg/s", text).group(1))
    assert shown == pytest.approx(math.degrees(downward.control["theta2_dot_des"]), abs=1e-4)


def test_the_summary_lists_multipliers_by_modulus_largest_first(downward):
    stability = downward.stability
    shuffled = dataclasses.replace(stability, multipliers=stability.multipliers[::-1])
    text = summary_text(dataclasses.replace(downward, stability=shuffled))
    listed = re.search(r"multipliers (.*)", text).group(1).split(", ")
    moduli = [abs(complex(item.split()[0])) for item in listed]
    assert moduli == sorted(moduli, reverse=True) and len(moduli) == 4
