"""Specification of baslip.analysis.manifold: the local dimension of the fixed-point manifold."""

import json
from pathlib import Path

import numpy as np
import pytest

from baslip import Params, ReturnMap, Tolerances
from baslip.analysis.manifold import RANK_TOLERANCE, manifold_dimension

ROOT = Path(__file__).resolve().parents[1]


def test_dimension_counts_the_null_space():
    """A synthetic map: r depends on X only through a contraction, and u enters through
    a rank-2 matrix. Then rank [A - I, B] = 4, dimension 5, and only 2 control directions."""
    A = np.diag([0.5, 0.2, -0.3, 0.1])
    B = np.zeros((4, 5))
    B[0, 0], B[1, 1] = 1.0, 2.0
    d = manifold_dimension(A, B)
    assert d.dimension == 5 and d.control_rank == 2 and d.apex_rank == 2


def test_with_a_multiplier_at_one_the_apex_rank_is_still_the_control_rank():
    """A has an exact multiplier 1 (A - I singular) and B has rank 2, with [A - I, B] of
    full rank: the apexes reachable as fixed points, {dX : (A - I) dX in range B}, form a
    plane (dX2 = dX3 = 0). The projection of a well-conditioned null space agrees."""
    A = np.diag([1.0, 0.5, 0.2, -0.3])
    B = np.zeros((4, 5))
    B[0, 0], B[1, 1] = 1.0, 1.0
    d = manifold_dimension(A, B)
    J = np.hstack([A - np.eye(4), B])
    tangent = np.linalg.svd(J)[2][4:].T
    assert d.apex_rank == d.control_rank == np.linalg.matrix_rank(tangent[:4]) == 2


@pytest.mark.parametrize("name, control_rank", [("downward", 4), ("upward", 3)])
def test_shipped_gaits_sit_on_a_five_dimensional_manifold(name, control_rank):
    """At both shipped fixed points the manifold is 5-dimensional, and 4-dimensional in
    distinct gaits. At the downward gait dr/du has rank 4, so every nearby apex is a fixed
    point for some control. The upward gait has gains of about 1e-4: there the set points
    theta2_des and theta2_dot_des barely act on the torque, dr/du drops to rank 3 (its
    smallest singular value is about 1e-8), and so do the apexes reachable as fixed
    points: not every nearby apex can be made periodic by choosing u."""
    record = json.loads((ROOT / "results" / name / "result.json").read_text())
    X = np.array(list(record["apex"].values()))
    u = np.array(list(record["control"].values()))
    dr_dX, dr_du = ReturnMap(Tolerances(1e-10, 1e-10)).jacobians(X, u, Params(**record["params"]))
    d = manifold_dimension(dr_dX, dr_du, u)
    assert (d.dimension, d.gait_dimension, d.apex_rank, d.ydot_z_rank, d.control_rank) == (5, 4, control_rank, 2, control_rank)
    # The decision is clear-cut: the smallest kept singular value is far above the cut.
    assert d.singular_values[-1] > 100 * RANK_TOLERANCE * d.singular_values[0]


def test_set_points_act_only_through_c(tight_map):
    """Trading theta2_des against theta2_dot_des at fixed c = Kp theta2_des + Kd
    theta2_dot_des changes no motion: the next apex agrees to round-off, for a finite step."""
    record = json.loads((ROOT / "results" / "downward" / "result.json").read_text())
    X = np.array(list(record["apex"].values()))
    u = np.array(list(record["control"].values()))
    Kp, Kd = u[0], u[1]
    moved = u + 0.2 * np.array([0.0, 0.0, Kd, -Kp, 0.0])
    assert np.linalg.norm(moved - u) > 0.1
    p = Params(**record["params"])
    assert np.allclose(tight_map(X, moved, p), tight_map(X, u, p), rtol=0, atol=1e-11)


def test_dr_dc_is_the_same_through_either_set_point(tight_map):
    """dr/dtheta2_des = Kp dr/dc and dr/dtheta2_dot_des = Kd dr/dc: dr/dc from either agrees
    to round-off, so the motion depends on the set points only through c."""
    from baslip.analysis.manifold import controllability, independent_control_jacobian

    record = json.loads((ROOT / "results" / "downward" / "result.json").read_text())
    X = np.array(list(record["apex"].values()))
    u = np.array(list(record["control"].values()))
    dr_du = tight_map.jacobians(X, u, Params())[1]
    via_kp = independent_control_jacobian(dr_du, u, via="Kp")
    via_kd = independent_control_jacobian(dr_du, u, via="Kd")
    assert np.allclose(via_kp, via_kd, rtol=1e-9, atol=1e-12 * np.abs(dr_du).max())
    found = controllability(dr_du, u)
    assert found["rank_controls"] == found["rank_independent"] == 4
