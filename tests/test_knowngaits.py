"""Specification of the shipped gaits a start from the body alone begins at
(:mod:`baslip.gait.knowngaits`):

* the catalogue is the committed gaits of ``downward``, ``upward``, ``vpp`` and
  ``vpp_human``, carried to their normalised bodies: made again from their result.json
  files it is the same, value for value;
* every entry is a fixed point of the compiled map at its normalised body (eps <= 1e-10)
  and of the independent re-simulation (Rosenbrock, 1e-12);
* each has the posture of its trunk: ``downward`` hangs, the others stand upright.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.gait.fixedpoint import VERIFY_TOLERANCES
from baslip.gait.knowngaits import known_gait_from_result, known_gaits
from baslip.gait.polish import eps
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import HIP_LAWS

ROOT = Path(__file__).resolve().parents[1]
GAITS = known_gaits()


def test_the_catalogue_is_the_committed_gaits_carried_to_their_normalised_bodies():
    assert [g.name for g in GAITS] == ["downward", "upward", "vpp", "vpp_human"]
    for gait in GAITS:
        again = known_gait_from_result(json.loads((ROOT / "results" / gait.name / "result.json").read_text()))
        assert again.law == gait.law and again.groups == gait.groups
        assert dict(again.values) == pytest.approx(dict(gait.values), rel=1e-15, abs=1e-15)


@pytest.mark.parametrize("gait", GAITS, ids=[g.name for g in GAITS])
def test_every_entry_is_a_fixed_point_at_its_normalised_body(gait):
    law = HIP_LAWS[gait.law]
    X = np.array([gait.values[n] for n in APEX.names])
    u = np.array([gait.values[n] for n in law.controls.names])
    assert eps(ReturnMap(Tolerances(1e-12, 1e-12), law=law).stride(X, u, gait.body).apex, X) <= 1e-10
    assert eps(ReturnMap(VERIFY_TOLERANCES, "rosenbrock", law=law).stride(X, u, gait.body).apex, X) <= 1e-10


def test_each_entry_has_its_trunk_s_posture():
    assert {g.name: g.posture for g in GAITS} == {"downward": "hanging", "upward": "upright", "vpp": "upright",
                                                 "vpp_human": "upright"}
