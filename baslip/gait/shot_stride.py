"""One shot stride of the periodic-stride NLP (:mod:`baslip.gait.shooting`): its
constraints, each row with a name and a unit, so that a failed solve can say which
limits bind (:mod:`baslip.gait.diagnosis`)."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from baslip.engine.kernels import StanceFlow
from baslip.engine.returnmap import PHASES
from baslip.model.dynamics import (
    APEX,
    FLIGHT,
    STANCE,
    apex_to_flight,
    touchdown_guard_rate,
)
from baslip.model.hiplaw import HipLaw

#: The names of the NLP's rows that :mod:`baslip.gait.diagnosis` explains.
FOOT_AT_APEX = "foot clearance at apex"
LIFTOFF_RISE = "CoM's vertical speed at liftoff"
#: What :func:`baslip.engine.kernels.stance_clearances` keeps above zero, in its order.
CLEARANCES = ("CoM height", "hip height", "leg length above its collapse floor")


@dataclass(frozen=True)
class RowValues:
    """The NLP's constraint rows and bounded variables at one point: ``g`` with its
    limits ``lbg``, ``ubg`` and a label per row, and ``w`` with ``lbx``, ``ubx`` and a label
    per variable (an empty name for the shooting nodes). SI units and radians."""

    rows: tuple[RowLabel, ...]
    g: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    variables: tuple[RowLabel, ...]
    w: np.ndarray
    lbx: np.ndarray
    ubx: np.ndarray


@dataclass(frozen=True)
class RowLabel:
    """What one row of the NLP's constraints is: its name and SI unit (empty for a
    dimensionless row)."""

    name: str
    unit: str


def row_labels(name: str | tuple[str, ...], unit: str | tuple[str, ...], rows: int) -> list[RowLabel]:
    """A label per row: the names (and units) given, or one name numbered when it covers
    several rows."""
    names = name if isinstance(name, tuple) else tuple(name if rows == 1 else f"{name} [{i}]" for i in range(rows))
    units = unit if isinstance(unit, tuple) else (unit,) * rows
    return [RowLabel(n, u) for n, u in zip(names, units, strict=True)]


#: The unit of each stance state coordinate (:data:`baslip.model.dynamics.STANCE`).
STANCE_UNITS = ("m", "rad", "rad", "m/s", "rad/s", "rad/s")


def node_names(what: str, nodes: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Row names and units of the continuity of ``nodes`` stance nodes, every state
    coordinate of each."""
    names = tuple(f"{what} at node {k + 1} in {n}" for k in range(nodes) for n in STANCE.names)
    return names, STANCE_UNITS * nodes


def named(constrain, prefix: str):
    """``constrain`` with ``prefix`` before every row's name (the stride of an orbit's row)."""
    if not prefix:
        return constrain

    def prefixed(expr, lo, hi, name, unit: str | tuple[str, ...] = ""):
        named = tuple(prefix + n for n in name) if isinstance(name, tuple) else prefix + name
        return constrain(expr, lo, hi, named, unit)

    return prefixed


def shoot_stride(stance: StanceFlow, interval: ca.Function, margin: float, X, u, p, T, comp_nodes,
                  decomp_nodes, constrain):
    """Constrain one shot stride from apex ``X`` through ``constrain(expr, lo, hi, name,
    unit)``, guard rates by the transversality ``margin`` [SI]; return its next apex and the residuals r whose sum of squares is its tau^2 integral
    [N^2 m^2 s] by the trapezoidal rule over the nodes."""
    n = comp_nodes.size2()  # the nodes of each stance phase
    t_descent, t_compression, t_decompression, t_ascent = (T[i] for i in range(len(PHASES)))
    theta = ca.repmat(ca.vertcat(u, p), 1, n)
    physics = stance.physics
    apex_flight = apex_to_flight(X)
    # Descent: the foot stays above ground until it crosses zero, falling.
    for fraction in (0.0, 0.25, 0.5, 0.75):
        constrain(physics.guard("touchdown", physics.flight(apex_flight, fraction * t_descent, u, p), u, p), 0, ca.inf,
                  FOOT_AT_APEX if fraction == 0.0 else f"foot clearance at {fraction:.0%} of the descent", "m")
    at_touchdown = physics.flight(apex_flight, t_descent, u, p)
    constrain(physics.guard("touchdown", at_touchdown, u, p), 0, 0, "foot height at touchdown", "m")
    constrain(touchdown_guard_rate(at_touchdown, p), -ca.inf, -margin, "foot's vertical speed at touchdown", "m/s")
    x_td = physics.reset("touchdown", at_touchdown, u, p)

    starts_c = ca.horzcat(x_td, comp_nodes[:, :-1])
    ends_c = interval.map(n)(starts_c, ca.repmat(t_compression / n, 1, n), theta)
    constrain(comp_nodes - ends_c, 0, 0, *node_names("continuity of compression", n))
    bottom = comp_nodes[:, -1]
    constrain(physics.guard("bottom", bottom, u, p), 0, 0, "rhodot at the bottom", "m/s")
    rho_accel = STANCE.get(stance.rhs(bottom, ca.vertcat(u, p)), "rhodot")
    constrain(rho_accel, margin, ca.inf, "leg's lengthening acceleration at the bottom", "m/s^2")
    # The leg shortens from touchdown (transversally) until the bottom.
    constrain(physics.guard("bottom", x_td, u, p), -ca.inf, -margin, "rhodot at touchdown", "m/s")
    constrain(physics.guard("bottom", comp_nodes[:, :-1], u, p), -ca.inf, 0, tuple(f"rhodot at compression node {i + 1}" for i in range(n - 1)), "m/s")

    starts_d = ca.horzcat(bottom, decomp_nodes[:, :-1])
    ends_d = interval.map(n)(starts_d, ca.repmat(t_decompression / n, 1, n), theta)
    constrain(decomp_nodes - ends_d, 0, 0, *node_names("continuity of decompression", n))
    x_lo = decomp_nodes[:, -1]
    constrain(physics.guard("liftoff", x_lo, u, p), 0, 0, "rho - rho0 at liftoff", "m")
    constrain(STANCE.get(x_lo, "rhodot"), margin, ca.inf, "rhodot at liftoff", "m/s")
    # The leg stays compressed until liftoff.
    constrain(physics.guard("liftoff", starts_d[:, 1:], u, p), -ca.inf, 0, tuple(f"rho - rho0 at decompression node {i + 1}" for i in range(n - 1)), "m")
    # CoM, hip and leg clear of the ground at the nodes (smooth constraints; the
    # compiled map checks every stage point when it polishes and re-simulates).
    for phase, nodes in (("compression", comp_nodes), ("decompression", decomp_nodes)):
        for k in range(n):
            constrain(physics.clearances(nodes[:, k], u, p), 0, ca.inf,
                      tuple(f"{what} at {phase} node {k + 1}" for what in CLEARANCES), "m")

    at_liftoff = physics.reset("liftoff", x_lo, u, p)
    constrain(FLIGHT.get(at_liftoff, "zdot"), margin, ca.inf, LIFTOFF_RISE, "m/s")
    at_apex = physics.flight(at_liftoff, t_ascent, u, p)
    constrain(FLIGHT.get(at_apex, "zdot"), 0, 0, "zdot at the apex", "m/s")  # apex guard
    apex_next = ca.vertcat(*(FLIGHT.get(at_apex, name) for name in APEX.names))
    law = stance.law
    effort = ca.vertcat(effort_residuals(law, ca.horzcat(x_td, comp_nodes), u, p, t_compression / n),
                        effort_residuals(law, ca.horzcat(bottom, decomp_nodes), u, p, t_decompression / n))
    return apex_next, effort


def effort_residuals(law: HipLaw, states, u, p, h):
    """r with sum(r^2) = the trapezoidal tau^2 integral over states h apart."""
    tau = law.torque(states, u, p)
    weights = ca.DM.ones(1, states.size2())
    weights[0], weights[-1] = 0.5, 0.5
    return ca.vec(tau * ca.sqrt(h * weights))
