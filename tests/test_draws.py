"""Specification of the gains drawn over their bounds (:mod:`baslip.gait.draws`): repeatable
from their seed, inside the bounds, and spread over every order of magnitude (small and
large gains alike), not only the large ones."""

from pathlib import Path

import numpy as np

from baslip.gait.draws import random_start
from baslip.gait.from_problem import fixed_point_spec
from baslip.problem.reader import load_problem

ROOT = Path(__file__).resolve().parents[1]


def test_random_starts_span_the_gain_range_repeatably():
    spec = fixed_point_spec(load_problem(ROOT / "problems" / "optimal_upright.yaml"))
    draws = [random_start(spec, np.random.default_rng([7, k])) for k in range(400)]
    assert draws[3] == random_start(spec, np.random.default_rng([7, 3]))
    kp = np.array([d["Kp"] for d in draws])
    lo, hi = spec.bounds_of("Kp")
    assert np.all((lo <= kp) & (kp <= hi))
    magnitudes = np.abs(kp)
    assert np.mean(magnitudes < 1) > 0.15 and np.mean(magnitudes > 10) > 0.15  # small and large gains


def test_a_fixed_gain_is_not_drawn():
    spec = fixed_point_spec(load_problem(ROOT / "problems" / "atlas_human_pd.yaml"))
    assert set(random_start(spec, np.random.default_rng(1))) == {"Kp", "Kd"}
    vpp = fixed_point_spec(load_problem(ROOT / "problems" / "robot_vpp.yaml"))
    assert random_start(vpp, np.random.default_rng(1)) == {}  # r_vpp is fixed there
