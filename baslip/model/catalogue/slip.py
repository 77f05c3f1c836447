"""The spring-loaded inverted pendulum (SLIP) as a model description.

A point mass ``m`` on a massless linear spring leg (stiffness ``k``, rest length ``l0``)
that lands at the angle ``theta_td`` from the vertical and leaves the ground when the leg
is back at its rest length: the running model of Seyfarth et al. (2002), J. Biomech.
35:649-655. A stride runs apex, flight, stance, flight, apex; the return map is on the
apex (zdot = 0, falling) in the height ``z`` and the speed ``ydot``, the horizontal
position ``y`` being cyclic. Energy is conserved, so one multiplier is 1 by structure.

Stance coordinates are the leg length ``rho`` and the leg angle ``theta`` from the
vertical (positive puts the foot ahead of the mass when running towards +y), with the
foot at the origin: the mass is at ``rho * (-sin theta, cos theta)``.
"""

from __future__ import annotations

import math

import casadi as ca

from baslip.model.description import ControlLaw, Fall, Invariant, Mode, Model, Quantity, Section, Transition

PARAMETERS = (
    Quantity("m", "kg", 80.0, 0.0, 1e4, (1, 0, 0)),
    Quantity("k", "N/m", 20000.0, 0.0, 1e8, (1, 0, -2)),
    Quantity("l0", "m", 1.0, 0.0, 10.0, (0, 1, 0)),
    Quantity("g", "m/s^2", 9.81, 0.0, 100.0, (0, 1, -2)),
)
TOUCHDOWN_ANGLE = Quantity("theta_td", "rad", math.radians(22.0), -math.pi / 2, math.pi / 2)


def flight_lagrangian(s, p, u):
    """Kinetic minus potential energy of the mass in flight [J]."""
    return p.m / 2 * (s.ydot**2 + s.zdot**2) - p.m * p.g * s.z


def stance_lagrangian(s, p, u):
    """Kinetic minus potential (gravity and spring) energy in stance [J]."""
    kinetic = p.m / 2 * (s.rhodot**2 + s.rho**2 * s.theta_dot**2)
    return kinetic - p.m * p.g * s.rho * ca.cos(s.theta) - p.k / 2 * (s.rho - p.l0) ** 2


def touchdown_guard(s, p, u):
    """Foot height [m] with the leg held at ``theta_td``: zero at touchdown."""
    return s.z - p.l0 * ca.cos(u.theta_td)


def touchdown_map(s, p, u):
    """Flight velocity to the leg's rates, the leg at rest length and ``theta_td``."""
    sin_t, cos_t = ca.sin(u.theta_td), ca.cos(u.theta_td)
    return {"rho": p.l0, "theta": u.theta_td,
            "rhodot": -s.ydot * sin_t + s.zdot * cos_t,
            "theta_dot": (-s.ydot * cos_t - s.zdot * sin_t) / p.l0}


def liftoff_guard(s, p, u):
    """Leg extension past its rest length [m]: zero at liftoff."""
    return s.rho - p.l0


def liftoff_map(s, p, u):
    """The leg's state to the mass's flight state (``y`` measured from the foot)."""
    sin_t, cos_t = ca.sin(s.theta), ca.cos(s.theta)
    return {"y": -s.rho * sin_t, "z": s.rho * cos_t,
            "ydot": -s.rhodot * sin_t - s.rho * s.theta_dot * cos_t,
            "zdot": s.rhodot * cos_t - s.rho * s.theta_dot * sin_t}


def apex_guard(s, p, u):
    """Vertical speed [m/s]: it falls through zero at the apex."""
    return s.zdot


def energy(s, p, u):
    """The system energy [J] on the section."""
    return p.m / 2 * (s.ydot**2 + s.zdot**2) + p.m * p.g * s.z


SLIP = Model(
    name="slip",
    description="point mass on a massless spring leg (Seyfarth et al. 2002)",
    parameters=PARAMETERS,
    modes=(
        Mode("flight", ("y", "z"), ("ydot", "zdot"), lagrangian=flight_lagrangian),
        Mode("stance", ("rho", "theta"), ("rhodot", "theta_dot"), lagrangian=stance_lagrangian),
    ),
    order=("flight", "stance", "flight"),
    transitions=(
        Transition("flight", "stance", touchdown_guard, -1, touchdown_map, "touchdown"),
        Transition("stance", "flight", liftoff_guard, +1, liftoff_map, "liftoff"),
    ),
    section=Section("flight", apex_guard, -1, ("z", "ydot"), cyclic=("y",), pinned={"zdot": 0.0},
                    units={"z": "m", "ydot": "m/s"}, dimensions={"z": (0, 1, 0), "ydot": (0, 1, -1)}),
    laws=(ControlLaw("passive"),),
    controls=(TOUCHDOWN_ANGLE,),
    falls=(Fall("leg collapsed", "stance", lambda s, p, u: s.rho),
           Fall("mass hit the ground", "stance", lambda s, p, u: ca.cos(s.theta))),
    invariants=(Invariant("energy", energy, unit="J", dimension=(1, 2, -2)),),
    # Seyfarth et al.'s runner at 68 deg from the ground and 5 m/s at 1 m (tests/test_modelsolver.py).
    reference={"z": 0.9402671443757314, "ydot": 5.115853655779078, "theta_td": math.radians(22.0)},
)
