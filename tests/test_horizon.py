"""Specification of baslip.analysis.horizon: the receding-horizon re-solve.

* Two strides reach what one cannot: at the upright gait (dr/du of practical rank 3) the
  best one-stride control leaves a residual, the two-stride plan brings X_2 onto the gait.
* The plan's first control is applied and the runner converges.
* The search has two starts (the last plan's tail, the feedback's plan); when the descent
  from the nearer one ends short of the gait, the other is searched too and the better end
  kept. On a family of gaits the tail's end is kept unless the other reaches the gait.
* A plan that already reaches the gait costs value strides only.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from baslip import Params
from baslip.analysis.feedback import CONTROL_SCALE, ResolvedControl, lqr_gain, run_closed_loop
from baslip.analysis.horizon import HORIZON_EPS, RecedingHorizon
from baslip.engine.outcome import Tolerances
from baslip.engine.returnmap import ReturnMap
from baslip.model.hiplaw import VPP

ROOT = Path(__file__).resolve().parents[1]
#: Samples 0 and 24 of the 1x box of results/controllers_vpp: apex offsets from the
#: thesis-scale VPP gait (m, rad, m/s, rad/s).
FIRST_START = np.array([2.3643249401e-05, 0.009009273926519, -0.007116807745607, 0.044864944713724])
SAMPLE_24 = np.array([-0.000788157526585, 0.002663198920731, -0.002391514602269, 0.022529393807624])


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


@pytest.fixture(scope="module")
def vpp_gait():
    """The thesis-scale VPP gait (apex, control), its controller study's tuned feedback
    gain, and a map under the VPP law."""
    X, u = gait("vpp")
    K = np.array(json.loads((ROOT / "results" / "controllers_vpp" / "result.json").read_text())["feedback"]["K"])
    return X, u, K, ReturnMap(Tolerances(1e-12, 1e-12), law=VPP)


def vpp_horizon(vpp_gait, family: bool = False) -> RecedingHorizon:
    X, u, K, vpp_map = vpp_gait
    return RecedingHorizon(vpp_map, Params(), X, u, horizon=2, lower=np.array([-0.1, -np.inf]),
                           upper=np.array([0.2, np.inf]), K=K, family=family)


def test_when_the_nearer_start_ends_short_the_other_start_is_searched_too(vpp_gait):
    """At the thesis-scale VPP gait, from the first start of the controllers study's
    smallest box, the search from the feedback's plan (the nearer start) ends at a plan
    that never returns the runner; the search from the plan's tail brings it back."""
    X, _, _, vpp_map = vpp_gait
    run = run_closed_loop(vpp_map, Params(), vpp_horizon(vpp_gait), X + FIRST_START, X, 30)
    assert run.outcome == "converged"


def test_on_a_family_of_gaits_the_tail_is_kept_unless_the_other_start_reaches_the_gait(vpp_gait):
    """At the thesis-scale VPP gait (a neutral multiplier: a family of symmetric gaits),
    from sample 24 of the controllers study's 1x box, the end that misses less leaves the
    runner hopping near the gait without returning within 100 strides; continuing the last
    plan brings it back onto the family."""
    X, _, _, vpp_map = vpp_gait
    outcomes = [run_closed_loop(vpp_map, Params(), vpp_horizon(vpp_gait, family), X + SAMPLE_24, X, 100,
                                settle=True).outcome for family in (False, True)]
    assert outcomes[0] == "bounded" and outcomes[1] in ("converged", "settled")


class CountingMap(ReturnMap):
    """The 1e-12 map, counting the strides it differentiates."""

    def __init__(self):
        super().__init__(Tolerances(1e-12, 1e-12))
        self.linearised = 0

    def linearised_stride(self, X, u, params):
        self.linearised += 1
        return super().linearised_stride(X, u, params)


def test_a_plan_that_already_reaches_the_gait_costs_no_jacobian():
    """On the gait, the plan u*, u* brings X_N onto it: the apex's control is u*, found by
    value strides alone; one apex off the gait needs the plan's Jacobian."""
    X, u = gait("upward")
    counting = CountingMap()
    controller = RecedingHorizon(counting, Params(), X, u, horizon=2, fixed=(3,))
    control, miss = controller.control(X)
    assert miss <= HORIZON_EPS and np.array_equal(control, u) and counting.linearised == 0
    assert controller.control(X + np.array([1e-5, 1e-4, 1e-4, 1e-3]))[1] <= HORIZON_EPS
    assert counting.linearised >= 2
