"""Specification of baslip.gait.diagnosis: what a failed solve's last iterate says.

* A limit met at the last iterate is named as binding with its value and limit; when none
  is, the nearest (within 1 mm of foot clearance at human scale) are named as near.
* A foot that only just clears the ground at apex suggests the height at which it clears
  with a flatter leg, angles in degrees.
* A free quantity on its bound (relative to the bound's size) is listed; a fixed one or
  one inside its bounds is not.

(The end-to-end case, the human body at z = 1.05 m and 3 m/s, is in test_fixedpoint.py.)
"""

import math

import numpy as np

from baslip.gait.diagnosis import diagnose, limits_on_bounds
from baslip.gait.shooting import FixedPointSpec
from baslip.gait.shot_stride import FOOT_AT_APEX, RowLabel, RowValues
from baslip.model.dynamics import Params
from baslip.model.hiplaw import VPP

HUMAN = Params(m=80.0, I=4.58, k=20000.0, rho0=1.0, d=0.1, g=9.81)
SPEC = FixedPointSpec(HUMAN, fixed={"z": 1.05, "ydot": 3.0, "r_vpp": 0.1}, guess={}, law=VPP)


def rows_with_foot_clearance(clearance: float) -> RowValues:
    """An NLP point of SPEC with the foot ``clearance`` [m] above the ground at apex, the
    periodicity of ydot missed by 0.01 m/s, and the design upright with theta_td where
    that clearance puts it."""
    theta_td = math.acos((1.05 - 0.1 - clearance) / 1.0)
    w = np.array([1.05, math.pi / 2, 3.0, 0.0, 0.1, theta_td])
    rows = (RowLabel(FOOT_AT_APEX, "m"), RowLabel("periodicity of ydot", "m/s"))
    variables = tuple(RowLabel(name, unit) for name, unit in
                      (("z", "m"), ("theta_h", "rad"), ("ydot", "m/s"), ("theta_h_dot", "rad/s"), ("r_vpp", "m"),
                       ("theta_td", "rad")))
    fixed = np.array([1.05, -np.inf, 3.0, -np.inf, 0.1, -1.5]), np.array([1.05, np.inf, 3.0, np.inf, 0.1, 1.5])
    return RowValues(rows, np.array([clearance, 0.01]), np.array([0.0, 0.0]), np.array([np.inf, 0.0]),
                     variables, w, *fixed)


def test_a_foot_on_the_clearance_limit_binds_and_the_suggestion_gives_the_height_in_degrees():
    diagnosis = diagnose(rows_with_foot_clearance(5e-6), SPEC)
    assert [limit.name for limit in diagnosis.binding] == [FOOT_AT_APEX] and diagnosis.near == ()
    assert [limit.name for limit in diagnosis.violated] == ["periodicity of ydot"]
    [suggestion] = diagnosis.suggestions
    least = math.degrees(math.acos(0.95))  # 18.19 deg
    needed = 0.1 + math.cos(math.radians(least - 1.0))  # the apex that clears a leg 1 deg flatter
    assert f"keeps theta_td above {least:.2f} deg" in suggestion
    assert f"raise z (z > {needed:.4g} m lets theta_td go to {least - 1:.2f} deg)" in suggestion
    assert "binding  foot clearance at apex = 5e-06 m (limit 0 m)" in "\n".join(diagnosis.lines())


def test_a_limit_a_fraction_of_a_millimetre_away_is_near_when_none_binds():
    near = diagnose(rows_with_foot_clearance(6e-4), SPEC)
    assert near.binding == () and [limit.name for limit in near.near] == [FOOT_AT_APEX]
    assert near.suggestions and "raise z" in near.suggestions[0]
    clear = diagnose(rows_with_foot_clearance(0.01), SPEC)  # 1 cm: nothing near
    assert clear.binding == () and clear.near == ()
    assert clear.suggestions[0].startswith("no limit binds and periodicity of ydot stays off")


def test_a_free_quantity_on_its_bound_is_listed_relative_to_the_bounds_size():
    spec = FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5, "Kd": 1.0}, guess={},
                          bounds={"theta2_des": (-2 * math.pi, 1.0)})
    X = np.array([0.4, -math.pi / 2, 0.5, 0.0])
    on = limits_on_bounds(spec, X, np.array([1000.0 - 1e-4, 1.0, -2 * math.pi, 0.0, 0.1]))
    assert [(limit.name, limit.bound) for limit in on] == [("Kp", 1000.0), ("theta2_des", -2 * math.pi)]
    assert on[1].text() == "theta2_des = -360 deg (limit -360 deg)"
    inside = limits_on_bounds(spec, X, np.array([999.0, 1.0, -6.0, 0.0, 0.1]))
    assert inside == ()
