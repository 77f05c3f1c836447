"""Local dimension of the fixed-point manifold (thesis sec. 4.6), from the SVD.

Near a fixed point (X*, u*) the fixed points solve F(X, u) = r(X, u) - X = 0: four
equations in the nine design quantities. With J = [dr/dX - I, dr/du] (4 x 9), the manifold
has local dimension 9 - rank J, and its tangent space is the null space of J. Projecting
that tangent space onto the apex state (or onto (ydot, z)) and taking its rank says how
many apex coordinates can be chosen freely: the fixed points near X* fill a set of that
dimension in apex space.

That projection's dimension is rank(dr/du) whenever J has full rank 4: it is the set of
dX with (A - I) dX in range(B), of dimension dim null(A - I) + dim(range(A - I) and
range(B)) = (4 - rank(A - I)) + (rank(A - I) + rank(B) - 4). It is computed so, because
projecting the numerical null space instead mixes in directions of the size of B's
smallest singular value and overcounts (it reported 4 at upright gaits where dr/du has
rank 3).

Not every direction of the manifold is a different gait. The hip law uses the set points
only through c = Kp theta2_des + Kd theta2_dot_des, so trading theta2_des against
theta2_dot_des at fixed c changes no motion: the distinct gaits form a set of one
dimension less (two less if Kp = Kd = 0 exactly, when c is 0 whatever the set points).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .control import CONTROL
from .model import APEX
from .quantities import DESIGN, NOMINAL

#: Singular values below this fraction of the largest count as zero. The Jacobians come
#: from AD through an integrator at rtol = atol = 1e-10, so entries carry about 1e-9 error.
RANK_TOLERANCE = 1e-7


@dataclass(frozen=True)
class ManifoldDimension:
    """Dimensions at one fixed point, and the singular values behind them."""

    dimension: int  # of the fixed-point manifold in (X, u)
    gait_dimension: int  # of the set of distinct gaits (motions): dimension less the c-fixed directions
    apex_rank: int  # rank of its tangent space projected onto X = (z, theta_h, ydot, theta_h_dot)
    ydot_z_rank: int  # ... projected onto (ydot, z)
    control_rank: int  # rank of dr/du: 4 means every nearby apex is a fixed point for some u
    singular_values: tuple[float, ...]


def _rank(matrix: np.ndarray) -> int:
    if matrix.size == 0:
        return 0
    s = np.linalg.svd(matrix, compute_uv=False)
    return int(np.sum(s > RANK_TOLERANCE * max(s[0], 1e-300)))


def manifold_dimension(dr_dX: np.ndarray, dr_du: np.ndarray, u: np.ndarray | None = None) -> ManifoldDimension:
    """Dimensions of the fixed-point manifold from the return map's Jacobians at a point
    with control ``u`` (needed only to tell whether both gains are exactly zero).

    Columns are scaled by the quantities' nominal sizes first, so that the rank decision
    does not depend on units.
    """
    scale = np.array([NOMINAL[name] for name in DESIGN])
    jac = np.hstack([np.asarray(dr_dX) - np.eye(APEX.size), np.asarray(dr_du)]) * scale
    _, s, vt = np.linalg.svd(jac)
    rank = int(np.sum(s > RANK_TOLERANCE * s[0]))
    tangent = vt[rank:].T * scale[:, None]  # null-space basis, back in physical units
    apex_rows = tangent[: APEX.size]
    ydot_z = apex_rows[[APEX.index("ydot"), APEX.index("z")]]
    control_rank = _rank(np.asarray(dr_du) * scale[APEX.size :])
    gains_zero = u is not None and u[CONTROL.index("Kp")] == 0 and u[CONTROL.index("Kd")] == 0
    return ManifoldDimension(
        dimension=len(DESIGN) - rank,
        gait_dimension=len(DESIGN) - rank - (2 if gains_zero else 1),
        apex_rank=control_rank if rank == APEX.size else _rank(apex_rows),
        ydot_z_rank=_rank(ydot_z),
        control_rank=control_rank,
        singular_values=tuple(float(v) for v in s),
    )
