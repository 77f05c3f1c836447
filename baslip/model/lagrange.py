"""Equations of motion from a Lagrangian, by CasADi's automatic differentiation.

For coordinates q with rates qdot, a Lagrangian L(q, qdot) and generalized forces Q,

    M(q, qdot) qddot = Q + dL/dq - (d/dq dL/dqdot) qdot,    M = d^2 L / dqdot^2,

solved symbolically. Nothing is transcribed: a model gives L, and this derives the rest.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca

from baslip.model.description import ModelError


def check_rates(lagrangian: ca.SX, rates: ca.SX, rate_names: Sequence[str], key: str) -> None:
    """Refuse a Lagrangian that does not depend on some coordinate's rate (a zero row of M:
    no equation of motion for that coordinate), naming the rate."""
    jacobian = ca.jacobian(lagrangian, rates)
    for i, name in enumerate(rate_names):
        if not ca.depends_on(jacobian[i], rates):
            raise ModelError(key, f"the Lagrangian does not depend on the rate {name!r} quadratically, "
                                  "so that coordinate has no equation of motion (is it in the kinetic energy?)")


def accelerations(lagrangian: ca.SX, q: ca.SX, rates: ca.SX, forces: ca.SX) -> ca.SX:
    """qddot of the Euler-Lagrange equations with generalized forces ``forces``.

    Parameters
    ----------
    lagrangian : SX
        L(q, qdot) [J], scalar.
    q, rates : SX
        Columns of the coordinates and their rates.
    forces : SX
        Column of the generalized forces (N or N m by coordinate).
    """
    dl_drates = ca.gradient(lagrangian, rates)
    mass = ca.jacobian(dl_drates, rates)
    right = ca.gradient(lagrangian, q) - ca.jtimes(dl_drates, q, rates) + forces
    return ca.solve(mass, right)
