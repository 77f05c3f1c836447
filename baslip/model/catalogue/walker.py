"""The bipedal spring-mass walker as a model description.

A point mass ``m`` on two massless linear spring legs (stiffness ``k``, rest length
``l0``), the walking model of Geyer, Seyfarth and Blickhan (2006), Proc. R. Soc. B
273:2861-2867. A step is single support on the stance leg, double support once the
swing leg lands at the angle ``theta_td`` from the vertical, and single support on the
new leg once the old one is back at its rest length: no flight, and two stances a step.

Single support is in polar coordinates about the stance foot: the leg length ``rho``
and the leg angle ``theta`` from the vertical (positive puts the foot ahead of the mass
when walking towards +x), the mass at ``rho * (-sin theta, cos theta)``. Double support
is in Cartesian coordinates ``(x, z)`` of the mass from the rear foot, with ``gap`` the
distance to the front foot (constant while both feet stand). The section is mid-stance,
the stance leg vertical (``theta`` falling through zero), in ``(rho, rhodot,
theta_dot)``; the horizontal position is dropped by measuring from the stance foot.
Energy is conserved, so one multiplier is 1 by structure.
"""

from __future__ import annotations

import math

import casadi as ca

# The walker's body is the SLIP's (mass, leg stiffness, rest length, gravity), and its single
# support is the SLIP's stance on the stance leg.
from baslip.model.catalogue.slip import PARAMETERS, stance_lagrangian
from baslip.model.description import Fall, Invariant, Mode, Model, Quantity, Section, Transition

#: The swing leg's landing angle from the vertical; 21 deg is 69 deg from the ground.
TOUCHDOWN_ANGLE = Quantity("theta_td", "rad", math.radians(21.0), -1.2, 1.2)


def _leg_lengths(s):
    """Lengths [m] of the rear leg (foot at the origin) and the front leg (foot at ``gap``)."""
    return ca.sqrt(s.x**2 + s.z**2), ca.sqrt((s.x - s.gap) ** 2 + s.z**2)


def double_support_dynamics(s, p, u):
    """Rates of the double-support state: each spring pushes the mass along its leg."""
    rear, front = _leg_lengths(s)
    push_rear, push_front = p.k * (p.l0 - rear) / p.m, p.k * (p.l0 - front) / p.m  # [m/s^2 per unit direction]
    return {"x": s.x_dot, "z": s.z_dot, "gap": s.gap_dot,
            "x_dot": push_rear * s.x / rear + push_front * (s.x - s.gap) / front,
            "z_dot": push_rear * s.z / rear + push_front * s.z / front - p.g, "gap_dot": 0}


def touchdown_guard(s, p, u):
    """Height [m] of the mass above the swing foot held at ``theta_td``: zero at touchdown."""
    return s.rho * ca.cos(s.theta) - p.l0 * ca.cos(u.theta_td)


def touchdown_map(s, p, u):
    """The single-support state to double support, the swing foot landing ahead."""
    sin_t, cos_t = ca.sin(s.theta), ca.cos(s.theta)
    x = -s.rho * sin_t
    return {"x": x, "z": s.rho * cos_t, "gap": x + p.l0 * ca.sin(u.theta_td),
            "x_dot": -s.rhodot * sin_t - s.rho * s.theta_dot * cos_t,
            "z_dot": s.rhodot * cos_t - s.rho * s.theta_dot * sin_t, "gap_dot": 0}


def rear_liftoff_guard(s, p, u):
    """Rear leg extension past its rest length [m]: zero when the rear foot lifts off."""
    return _leg_lengths(s)[0] - p.l0


def liftoff_map(s, p, u):
    """The double-support state to single support on the front leg."""
    forward = s.x - s.gap  # the mass's horizontal position from the front foot [m]
    rho = ca.sqrt(forward**2 + s.z**2)
    return {"rho": rho, "theta": ca.atan2(-forward, s.z),
            "rhodot": (forward * s.x_dot + s.z * s.z_dot) / rho,
            "theta_dot": (-s.x_dot * s.z + forward * s.z_dot) / rho**2}


def mid_stance_guard(s, p, u):
    """The stance leg's angle from the vertical [rad]: it falls through zero at mid-stance."""
    return s.theta


def energy(s, p, u):
    """The system energy [J] on the section (one leg loaded, the other swinging)."""
    kinetic = p.m / 2 * (s.rhodot**2 + s.rho**2 * s.theta_dot**2)
    return kinetic + p.m * p.g * s.rho * ca.cos(s.theta) + p.k / 2 * (s.rho - p.l0) ** 2


WALKER = Model(
    name="walker",
    description="point mass on two massless spring legs (Geyer, Seyfarth and Blickhan 2006)",
    parameters=PARAMETERS,
    modes=(
        Mode("single", ("rho", "theta"), ("rhodot", "theta_dot"), lagrangian=stance_lagrangian),
        Mode("double", ("x", "z", "gap"), ("x_dot", "z_dot", "gap_dot"), dynamics=double_support_dynamics),
    ),
    order=("single", "double", "single"),
    transitions=(
        Transition("single", "double", touchdown_guard, -1, touchdown_map, "touchdown"),
        Transition("double", "single", rear_liftoff_guard, +1, liftoff_map, "liftoff"),
    ),
    section=Section("single", mid_stance_guard, -1, ("rho", "rhodot", "theta_dot"), pinned={"theta": 0.0},
                    units={"rho": "m", "rhodot": "m/s", "theta_dot": "rad/s"},
                    dimensions={"rho": (0, 1, 0), "rhodot": (0, 1, -1), "theta_dot": (0, 0, -1)}),
    controls=(TOUCHDOWN_ANGLE,),
    falls=(Fall("mass hit the ground", "single", lambda s, p, u: ca.cos(s.theta)),
           Fall("mass hit the ground", "double", lambda s, p, u: s.z)),
    invariants=(Invariant("energy", energy, unit="J", dimension=(1, 2, -2)),),
    # The symmetric walk at 820 J, 69 deg from the ground and 20 kN/m (tests/test_catalogue.py).
    reference={"rho": 0.9782346411268511, "rhodot": 0.0, "theta_dot": -1.114488234555546,
               "theta_td": math.radians(21.0)},
)
