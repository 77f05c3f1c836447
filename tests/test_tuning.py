"""Specification of baslip.analysis.tuning: the feedback a gait gets.

* Deadbeat is offered only where its controls stay within their bounds over the box.
* Every LQR candidate stabilises the linearised closed loop; the pilot's best is kept.
* At a VPP gait the structural multiplier 1 is unreachable: it stays 1 under any gain,
  and the closed-loop radius leaves it out.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from baslip import Params
from baslip.analysis.feedback import CONTROL_SCALE, closed_loop_multipliers, control_scale
from baslip.analysis.tuning import choose_feedback, lqr_candidates, saturates, transverse_radius

ROOT = Path(__file__).resolve().parents[1]
WIDTHS = np.array([1e-3, 1e-2, 1e-2, 5e-2])


def linearised(tight_map, name):
    record = json.loads((ROOT / "results" / name / "result.json").read_text())
    X, u = np.array(list(record["apex"].values())), np.array(list(record["control"].values()))
    return (X, u, *tight_map.jacobians(X, u, Params()))


def test_deadbeat_is_chosen_where_its_controls_stay_in_bounds_and_refused_where_not(tight_map):
    X, u, A, B = linearised(tight_map, "downward")
    wide = (u - 1e3, u + 1e3)
    chosen = choose_feedback(A, B, u, *wide, WIDTHS, CONTROL_SCALE)
    assert chosen.kind == "deadbeat" and chosen.closed_loop_radius < 1e-6
    assert not saturates(chosen.K, u, *wide, WIDTHS)
    tight = (u - 1e-4 * CONTROL_SCALE, u + 1e-4 * CONTROL_SCALE)  # a tenth of a per mille of each control
    assert saturates(chosen.K, u, *tight, WIDTHS)
    refused = choose_feedback(A, B, u, *tight, WIDTHS, CONTROL_SCALE)
    assert refused.kind == "lqr" and "leave their bounds" in refused.reason


def test_every_lqr_candidate_stabilises_and_the_pilots_best_is_kept(tight_map):
    X, u, A, B = linearised(tight_map, "upward")
    candidates = lqr_candidates(A, B, CONTROL_SCALE)
    assert len(candidates) >= 10
    for _, K, radius in candidates:
        assert radius == pytest.approx(np.max(np.abs(closed_loop_multipliers(A, B, K)))) and radius < 1
    favourite = candidates[len(candidates) // 2][0]
    chosen = choose_feedback(A, B, u, u - 1e3, u + 1e3, WIDTHS, CONTROL_SCALE,
                             pilot=lambda K: float(any(np.array_equal(K, c[1]) for c in candidates if c[0] == favourite)))
    assert chosen.weights == favourite and chosen.pilot_share == 1.0


def test_a_vpp_gaits_symmetry_multiplier_stays_at_one_under_any_gain():
    from baslip import ReturnMap, Tolerances
    from baslip.gait.from_problem import solve_problem
    from baslip.problem.reader import load_problem

    gait = solve_problem(load_problem(ROOT / "problems" / "vpp.yaml"))
    A, B = ReturnMap(Tolerances(1e-12, 1e-12), law=gait.law).jacobians(gait.X, gait.u, gait.params)
    for K in np.random.default_rng(3).normal(size=(5, 2, 4)):
        assert np.min(np.abs(closed_loop_multipliers(A, B, K) - 1.0)) <= 1e-7
    scale = control_scale(gait.law)
    candidates = lqr_candidates(A, B, scale, neutral=1)
    assert candidates and all(radius < 1 for *_, radius in candidates)
    assert transverse_radius(A, B, candidates[0][1], neutral=0) == pytest.approx(1.0, abs=1e-7)


def test_deadbeat_within_bounds_still_loses_to_an_lqr_that_brings_back_more_of_the_pilot(tight_map):
    from baslip.analysis.feedback import deadbeat_gain

    X, u, A, B = linearised(tight_map, "downward")
    deadbeat = deadbeat_gain(A, B, CONTROL_SCALE)
    chosen = choose_feedback(A, B, u, u - 1e3, u + 1e3, WIDTHS, CONTROL_SCALE,
                             pilot=lambda K: 0.0 if np.array_equal(K, deadbeat) else 0.5)
    assert chosen.kind == "lqr" and chosen.pilot_share == 0.5 and "0% of the pilot" in chosen.reason
