"""Specification of baslip.viz.colours: a radius just below 1 looks stable and one just above
looks unstable, the bar is symmetric about 1, and a near-constant angle does not fill the
whole colour range."""

import numpy as np
import pytest

from baslip.viz.colours import MIN_ANGLE_SPAN_DEG, colour_limits, radius_colours


def test_radii_either_side_of_one_get_plainly_different_colours():
    colours, norm = radius_colours([0.3, 0.97, 1.03, 40.0])
    assert norm.vmin * norm.vmax == pytest.approx(1.0) and norm.vmax == pytest.approx(40.0)
    below, above = colours(norm(0.97)), colours(norm(1.03))
    assert below[2] > below[0] + 0.2 and above[0] > above[2] + 0.2  # blue, then red
    assert min(below[:3]) < 0.9 and min(above[:3]) < 0.9  # neither is white
    _, narrow = radius_colours([0.98, 1.01])
    assert narrow.vmin == pytest.approx(0.5) and narrow.vmax == pytest.approx(2.0)


def test_an_angle_map_spans_at_least_its_least_span():
    nearly_constant = np.array([[90.0, 90.1], [90.25, np.nan]])
    limits = colour_limits("theta_h", nearly_constant)
    assert limits["vmax"] - limits["vmin"] == pytest.approx(MIN_ANGLE_SPAN_DEG)
    assert limits["vmin"] < 90.0 < 90.25 < limits["vmax"]
    assert colour_limits("theta_h", np.array([60.0, 120.0])) == {}
    assert colour_limits("z", np.array([0.4, 0.4001])) == {}
