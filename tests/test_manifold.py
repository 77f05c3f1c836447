"""Specification of baslip.manifold: the local dimension of the fixed-point manifold."""

import json
from pathlib import Path

import numpy as np
import pytest

from baslip import Params, ReturnMap, Tolerances
from baslip.manifold import RANK_TOLERANCE, manifold_dimension

ROOT = Path(__file__).resolve().parents[1]


def test_dimension_counts_the_null_space():
    """A synthetic map: r depends on X only through a contraction, and u enters through
    a rank-2 matrix. Then rank [A - I, B] = 4, dimension 5, and only 2 control directions."""
    A = np.diag([0.5, 0.2, -0.3, 0.1])
    B = np.zeros((4, 5))
    B[0, 0], B[1, 1] = 1.0, 2.0
    d = manifold_dimension(A, B)
    assert d.dimension == 5 and d.control_rank == 2 and d.apex_rank == 2


@pytest.mark.parametrize("name, control_rank", [("downward", 4), ("upward", 3)])
def test_shipped_gaits_sit_on_a_five_dimensional_manifold(name, control_rank):
    """At both shipped fixed points the manifold is 5-dimensional and its tangent space
    covers all four apex coordinates. At the downward gait dr/du has rank 4, so every
    nearby apex is a fixed point for some control. The upward gait has gains of about
    1e-4: there the set points theta2_des and theta2_dot_des barely act on the torque,
    and dr/du drops to rank 3 (its smallest singular value is about 1e-8)."""
    record = json.loads((ROOT / "results" / name / "result.json").read_text())
    X = np.array(list(record["apex"].values()))
    u = np.array(list(record["control"].values()))
    dr_dX, dr_du = ReturnMap(Tolerances(1e-10, 1e-10)).jacobians(X, u, Params(**record["params"]))
    d = manifold_dimension(dr_dX, dr_du)
    assert (d.dimension, d.apex_rank, d.ydot_z_rank, d.control_rank) == (5, 4, 2, control_rank)
    # The decision is clear-cut: the smallest kept singular value is far above the cut.
    assert d.singular_values[-1] > 100 * RANK_TOLERANCE * d.singular_values[0]
