"""Specification of baslip.analysis.horizon: the receding-horizon re-solve.

* Two strides reach what one cannot: at the upright gait (dr/du of practical rank 3) the
  best one-stride control leaves a residual, the two-stride plan brings X_2 onto the gait.
* The plan's first control is applied and the runner converges.
* The plan's descent follows the curved valley of the miss (geodesic acceleration, its
  damping by Nielsen's rule): from an apex of the 1x box the plan reaches the gait, and
  the runner is back in two strides.
* The search has two starts (the last plan's tail, the feedback's plan); when the descent
  from the nearer one ends short of the gait, the other is searched too and the better end
  kept. On a family of gaits the tail is searched first and its end kept unless the
  other's reaches the gait; the runner settles onto the family.
* A plan that already reaches the gait costs value strides only.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from baslip import Params
from baslip.analysis.feedback import CONTROL_SCALE, ResolvedControl, lqr_gain, run_closed_loop
from baslip.analysis.horizon import HORIZON_EPS, Damping, RecedingHorizon
from baslip.engine.outcome import Tolerances
from baslip.engine.returnmap import ReturnMap
from baslip.model.hiplaw import VPP

ROOT = Path(__file__).resolve().parents[1]
#: An apex offset in the 1x box of results/controllers_upright (m, rad, m/s, rad/s).
UPRIGHT_START = np.array([2.7392e-04, -4.60427e-03, -9.18053e-03, -4.834724e-02])
#: Sample 24 of the 1x box of results/controllers_vpp: an apex offset from the
#: thesis-scale VPP gait (m, rad, m/s, rad/s).
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


def test_the_plan_follows_the_curved_valley_of_the_miss_back_to_the_gait(tight_map):
    """At the shipped upright gait (largest multiplier 63), from an apex of the controllers
    study's 1x box, under its tuned feedback's start: the first apex's plan reaches the
    gait (damped steps alone stopped at eps 0.12 there) and the runner is back in two
    strides, as a two-stride plan promises (it took five)."""
    X, u = gait("upward")
    K = np.array(json.loads((ROOT / "results" / "controllers_upright" / "result.json").read_text())["feedback"]["K"])
    run = run_closed_loop(tight_map, Params(), RecedingHorizon(tight_map, Params(), X, u, horizon=2, K=K),
                          X + UPRIGHT_START, X, 30)
    assert run.residuals[0] <= HORIZON_EPS
    assert run.outcome == "converged" and run.strides_to_converge == 2


def test_the_damping_follows_nielsens_rule():
    """A step that gains what its linear model predicted cuts the damping to a third, one
    that gains half of it keeps it; failures in a row raise it 2, 4, 8 times, and a success
    starts the raises again from 2."""
    damping = Damping(1.0)
    damping.succeeded(1.0)
    assert damping.value == pytest.approx(1 / 3)
    damping.succeeded(0.5)
    assert damping.value == pytest.approx(1 / 3)
    for factor in (2, 4, 8):
        before = damping.value
        damping.failed()
        assert damping.value == pytest.approx(factor * before)
    damping.succeeded(0.5)
    before = damping.value
    damping.failed()
    assert damping.value == pytest.approx(2 * before)


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


class ScriptedSearch(RecedingHorizon):
    """The search's choice of starts alone: the starts' misses and the descents' ends are
    given (start "tail" is the last plan's tail, "feedback" the feedback's plan)."""

    def __init__(self, rmap, misses: dict, ends: dict, family: bool):
        X, u = gait("upward")
        super().__init__(rmap, Params(), X, u, horizon=2, fixed=(3,), K=np.zeros((5, 4)), family=family)
        self.plans = {"tail": self.plan.copy(), "feedback": self.plan + 1.0}
        self.misses, self.ends, self.descended = misses, ends, []

    def _name(self, plan) -> str:
        return next(name for name, known in self.plans.items() if np.array_equal(plan, known))

    def _feedback_plan(self, X):
        return self.plans["feedback"].copy()

    def _miss(self, X, plan):
        return self.misses[self._name(plan)], np.zeros(4)

    def _descend(self, X, start, miss):
        name = self._name(start)
        self.descended.append(name)
        return self.plans[name] + 10 * (name == "feedback"), self.ends[name]


def test_the_nearer_start_is_searched_first_and_the_other_only_when_it_ends_short(tight_map):
    short = ScriptedSearch(tight_map, {"tail": 1e-3, "feedback": 1e-4}, {"tail": 1e-12, "feedback": 1e-5}, False)
    control, reached = short.control(short.X_star)
    assert short.descended == ["feedback", "tail"] and reached == 1e-12
    assert np.array_equal(control, short.plans["tail"][0])  # the better end is kept
    enough = ScriptedSearch(tight_map, {"tail": 1e-3, "feedback": 1e-4}, {"tail": 1e-12, "feedback": 1e-11}, False)
    assert enough.control(enough.X_star)[1] == 1e-11 and enough.descended == ["feedback"]


def test_on_a_family_of_gaits_the_tail_is_searched_first_and_kept_unless_the_other_reaches_the_gait(tight_map):
    kept = ScriptedSearch(tight_map, {"tail": 1e-3, "feedback": 1e-4}, {"tail": 1e-6, "feedback": 1e-8}, True)
    control, reached = kept.control(kept.X_star)
    assert kept.descended == ["tail", "feedback"] and reached == 1e-6
    assert np.array_equal(control, kept.plans["tail"][0])
    replaced = ScriptedSearch(tight_map, {"tail": 1e-3, "feedback": 1e-4}, {"tail": 1e-6, "feedback": 1e-11}, True)
    assert replaced.control(replaced.X_star)[1] == 1e-11


def test_on_a_family_of_gaits_the_runner_settles_onto_the_family(vpp_gait):
    """At the thesis-scale VPP gait (a neutral multiplier: a family of symmetric gaits),
    from sample 24 of the controllers study's 1x box, no plan removes the miss along the
    family, but the runner settles onto a neighbouring gait of it within a few strides."""
    X, _, _, vpp_map = vpp_gait
    run = run_closed_loop(vpp_map, Params(), vpp_horizon(vpp_gait, family=True), X + SAMPLE_24, X, 100, settle=True)
    assert run.outcome == "settled" and len(run.controls) <= 6


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
