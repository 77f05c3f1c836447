"""Specification of baslip.analysis.horizon: the receding-horizon re-solve.

* Two strides reach what one cannot: at the upright gait (dr/du of practical rank 3) the
  best one-stride control leaves a residual, the two-stride plan brings X_2 onto the gait.
* The plan's first control is applied and the runner converges.
"""

import json
from pathlib import Path

import numpy as np

from baslip import Params
from baslip.analysis.feedback import CONTROL_SCALE, ResolvedControl, lqr_gain, run_closed_loop
from baslip.analysis.horizon import HORIZON_EPS, RecedingHorizon

ROOT = Path(__file__).resolve().parents[1]


def gait(name):
    record = json.loads((ROOT / "results" / name / "result.json").read_text())
    return np.array(list(record["apex"].values())), np.array(list(record["control"].values()))


def test_two_strides_reach_the_direction_that_one_stride_cannot(tight_map):
    X, u = gait("upward")
    start = X + np.array([1e-5, 1e-4, 1e-4, 1e-3])
    one = ResolvedControl(tight_map, Params(), X, u, "tracking", fixed=(3,))
    assert one.control(start)[1] > 1e-7  # the least-squares floor of one stride
    two = RecedingHorizon(tight_map, Params(), X, u, horizon=2, fixed=(3,))
    assert two.control(start)[1] <= HORIZON_EPS


def test_the_horizon_brings_a_perturbed_upright_runner_back(tight_map):
    X, u = gait("upward")
    A, B = tight_map.jacobians(X, u, Params())
    K = lqr_gain(A, B, np.diag(1 / np.array([0.01, 0.1, 0.1, 1.0]) ** 2), np.diag(1 / CONTROL_SCALE**2))
    controller = RecedingHorizon(tight_map, Params(), X, u, horizon=2, fixed=(3,), K=K)
    run = run_closed_loop(tight_map, Params(), controller, X + np.array([1e-4, 1e-3, 1e-3, 1e-2]), X, 30)
    assert run.outcome == "converged" and run.strides_to_converge <= 6
