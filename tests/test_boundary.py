"""Specification of baslip.studies.boundary and of random samples inside a traced
stability boundary."""

import numpy as np

from baslip.problem.study import RandomSample
from baslip.studies.boundary import boundary_segments, crossings, inside
from baslip.studies.sweep import random_tasks


def band_rows(flags=(True, True)):
    """Two curves, z = 0.38 and z = 0.46 over ydot in [0, 1.2]: a band of stable gaits."""
    rows = []
    for number, (z, flag) in enumerate(zip((0.38, 0.46), flags)):
        rows += [{"curve": number, "z": z, "ydot": ydot, "stability_boundary": flag} for ydot in np.linspace(0, 1.2, 7)]
    return rows


def test_only_segments_that_bound_stable_gaits_count():
    assert len(boundary_segments(band_rows(), ("ydot", "z"))) == 12
    assert len(boundary_segments(band_rows((True, False)), ("ydot", "z"))) == 6


def test_inside_means_an_even_number_of_crossings_from_a_stable_point():
    segments = boundary_segments(band_rows(), ("ydot", "z"))
    reference = (0.5, 0.42)
    assert inside((0.9, 0.40), reference, segments)
    assert not inside((0.9, 0.50), reference, segments)  # across the upper curve
    assert not inside((0.2, 0.30), reference, segments)  # across the lower one
    assert crossings(np.array([0.5, 0.3]), np.array([0.5, 0.5]), segments) == 2


def grid_rows():
    """A 3 x 5 (ydot, z) grid whose middle row z = 0.42 is stable."""
    rows = []
    for ydot in (0.2, 0.6, 1.0):
        for z in (0.34, 0.38, 0.42, 0.46, 0.5):
            rows.append({"sweep_ydot": ydot, "sweep_z": z, "ydot": ydot, "z": z, "status": "converged",
                         "stable": z == 0.42, "spectral_radius": 0.9 if z == 0.42 else 1.1,
                         "theta_h": -1.57, "theta_h_dot": 0.16, "Kp": -0.75, "Kd": 1.5, "theta2_des": -0.05,
                         "theta2_dot_des": 1.4, "theta_td": 0.11})
    return rows


def test_random_draws_inside_a_traced_boundary_are_inside_it_and_solved_as_the_grid_is():
    segments = boundary_segments(band_rows(), ("ydot", "z"))
    tasks = random_tasks(RandomSample(region="grid", count=40, seed=3), grid_rows(), ("ydot", "z"), segments)
    assert len(tasks) == 40
    assert all(0.38 < t["sweep_z"] < 0.46 for t in tasks)
    assert all("guess" not in t for t in tasks)  # nearest the problem's guess, like the grid
    # Without the boundary, the interpolated radius decides, and each draw gets a guess.
    interpolated = random_tasks(RandomSample(region="grid", count=40, seed=3), grid_rows(), ("ydot", "z"))
    assert all("guess" in t for t in interpolated)
    assert all(0.38 < t["sweep_z"] < 0.46 for t in interpolated)
