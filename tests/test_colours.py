"""Specification of baslip.viz.colours: a radius just below 1 looks stable and one just above
looks unstable, the bar is symmetric about 1, and a near-constant angle does not fill the
whole colour range. A radius bar's tick labels never run together, and 1 is always one."""

import numpy as np
import pytest

from baslip.viz.colours import (
    MIN_ANGLE_SPAN_DEG,
    TICK_GAP_SHARE,
    colour_limits,
    radius_colours,
    spaced_radius_ticks,
)


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


@pytest.mark.parametrize("span", [2.0, 5.0, 10.0, 63.0, 1000.0])
def test_a_radius_bar_labels_1_and_ticks_far_enough_apart_to_read(span):
    ticks = spaced_radius_ticks(1 / span, span)
    gaps = np.diff(np.log10(ticks))
    assert 1.0 in ticks and len(ticks) >= 3
    assert np.all(gaps >= TICK_GAP_SHARE * 2 * np.log10(span) - 1e-12)
    assert min(ticks) >= 1 / span and max(ticks) <= span
