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

from baslip.model.dynamics import APEX
from baslip.model.hiplaw import CONTROL
from baslip.model.quantities import DESIGN, NOMINAL

#: Singular values below this fraction of the largest count as zero: a *practical* rank.
#: Numerically the Jacobians are far better (two independent integrators' AD Jacobians
#: of dr/du agree to about 1e-12 of the largest singular value), so a ratio of 1e-9 is a
#: real direction. But moving the apex by 1e-4 (relative) along a direction of ratio below
#: 1e-7 needs a control change of more than 1e3 nominal units (Kp by 1000 N m/rad, Kd by
#: 100 N m s/rad): beyond the controls' physical range. Such a direction cannot be used.
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


#: The independent controls: the hip law's torque is c - Kp theta2 - Kd theta2_dot with
#: c = Kp theta2_des + Kd theta2_dot_des, so these four decide the motion. Nominal sizes
#: for scaling (c in N m).
INDEPENDENT_CONTROLS = ("Kp", "Kd", "c", "theta_td")
INDEPENDENT_SCALE = np.array([NOMINAL["Kp"], NOMINAL["Kd"], 0.1, NOMINAL["theta_td"]])


def independent_control_jacobian(dr_du: np.ndarray, u: np.ndarray, via: str | None = None) -> np.ndarray:
    """dr/d(Kp, Kd, c, theta_td) (4 x 4) from dr/du (4 x 5) at control ``u``.

    With r(u) = R(Kp, Kd, c(u), theta_td): dr/dtheta2_des = R_c Kp and dr/dtheta2_dot_des
    = R_c Kd give R_c (``via`` the gain of larger size unless given), and then
    R_Kp = dr/dKp - R_c theta2_des and R_Kd = dr/dKd - R_c theta2_dot_des.
    """
    index = {name: i for i, name in enumerate(CONTROL.names)}
    Kp, Kd = u[index["Kp"]], u[index["Kd"]]
    via = via or ("Kp" if abs(Kp) >= abs(Kd) else "Kd")
    if via == "Kp":
        R_c = dr_du[:, index["theta2_des"]] / Kp
    else:
        R_c = dr_du[:, index["theta2_dot_des"]] / Kd
    R_Kp = dr_du[:, index["Kp"]] - R_c * u[index["theta2_des"]]
    R_Kd = dr_du[:, index["Kd"]] - R_c * u[index["theta2_dot_des"]]
    return np.column_stack([R_Kp, R_Kd, R_c, dr_du[:, index["theta_td"]]])


def controllability(dr_du: np.ndarray, u: np.ndarray) -> dict:
    """Rank of dr/du and sigma_min/sigma_max, in the five controls (scaled by their
    nominal sizes) and in the four independent ones."""
    scale = np.array([NOMINAL[n] for n in CONTROL.names])
    s_u = np.linalg.svd(np.asarray(dr_du) * scale, compute_uv=False)
    s_v = np.linalg.svd(independent_control_jacobian(np.asarray(dr_du), np.asarray(u)) * INDEPENDENT_SCALE, compute_uv=False)
    return {
        "rank_controls": int(np.sum(s_u > RANK_TOLERANCE * s_u[0])),
        "ratio_controls": float(s_u[-1] / s_u[0]),
        "rank_independent": int(np.sum(s_v > RANK_TOLERANCE * s_v[0])),
        "ratio_independent": float(s_v[-1] / s_v[0]),
    }
