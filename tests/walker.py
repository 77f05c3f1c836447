"""A bipedal spring-mass walker (Geyer, Seyfarth and Blickhan 2006) as a model description, for
testing that nothing in the generic layers assumes a flight phase or one stance a stride:
a point mass on two massless spring legs, a step of single support (polar coordinates about
the stance foot), double support (Cartesian, the front foot `gap` ahead of the rear one)
and single support on the other leg, from one mid-stance (the stance leg vertical) to the
next. Energy is conserved.
"""
import math

import casadi as ca

from baslip.model.description import Fall, Invariant, Mode, Model, Quantity, Section, Transition

PARAMS = (Quantity("m", "kg", 80.0, 0, 1e4, (1, 0, 0)), Quantity("k", "N/m", 20000.0, 0, 1e8, (1, 0, -2)),
          Quantity("l0", "m", 1.0, 0, 10, (0, 1, 0)), Quantity("g", "m/s^2", 9.81, 0, 100, (0, 1, -2)))

def single(s, p, u):
    kin = p.m / 2 * (s.rhodot**2 + s.rho**2 * s.theta_dot**2)
    return kin - p.m * p.g * s.rho * ca.cos(s.theta) - p.k / 2 * (s.rho - p.l0) ** 2

def double(s, p, u):
    l1 = ca.sqrt(s.x**2 + s.z**2)
    l2 = ca.sqrt((s.x - s.gap) ** 2 + s.z**2)
    f1, f2 = p.k * (p.l0 - l1) / p.m, p.k * (p.l0 - l2) / p.m
    return {"x": s.x_dot, "z": s.z_dot, "gap": s.gap_dot,
            "x_dot": f1 * s.x / l1 + f2 * (s.x - s.gap) / l2,
            "z_dot": f1 * s.z / l1 + f2 * s.z / l2 - p.g, "gap_dot": 0}

def touchdown(s, p, u):  # the CoM falls to the height the swing leg reaches at its angle
    return s.rho * ca.cos(s.theta) - p.l0 * ca.cos(u.theta_td)

def to_double(s, p, u):
    sn, cs = ca.sin(s.theta), ca.cos(s.theta)
    x, z = -s.rho * sn, s.rho * cs
    return {"x": x, "z": z, "gap": x + p.l0 * ca.sin(u.theta_td),
            "x_dot": -s.rhodot * sn - s.rho * s.theta_dot * cs, "z_dot": s.rhodot * cs - s.rho * s.theta_dot * sn,
            "gap_dot": 0}

def rear_liftoff(s, p, u):
    return ca.sqrt(s.x**2 + s.z**2) - p.l0

def to_single(s, p, u):
    dx = s.x - s.gap
    rho = ca.sqrt(dx**2 + s.z**2)
    theta = ca.atan2(-dx, s.z)
    rhodot = (dx * s.x_dot + s.z * s.z_dot) / rho
    theta_dot = (-s.x_dot * s.z + dx * s.z_dot) / rho**2
    return {"rho": rho, "theta": theta, "rhodot": rhodot, "theta_dot": theta_dot}

def energy(s, p, u):
    return p.m / 2 * (s.rhodot**2 + s.rho**2 * s.theta_dot**2) + p.m * p.g * s.rho * ca.cos(s.theta) + p.k / 2 * (s.rho - p.l0) ** 2

WALKER = Model(
    name="walker", parameters=PARAMS,
    modes=(Mode("single", ("rho", "theta"), ("rhodot", "theta_dot"), lagrangian=single),
           Mode("double", ("x", "z", "gap"), ("x_dot", "z_dot", "gap_dot"), dynamics=double)),
    order=("single", "double", "single"),
    transitions=(Transition("single", "double", touchdown, -1, to_double, "touchdown"),
                 Transition("double", "single", rear_liftoff, +1, to_single, "liftoff")),
    section=Section("single", lambda s, p, u: s.theta, -1, ("rho", "rhodot", "theta_dot"), pinned={"theta": 0.0},
                    units={"rho": "m", "rhodot": "m/s", "theta_dot": "rad/s"}),
    controls=(Quantity("theta_td", "rad", math.radians(21.0), -1.2, 1.2),),
    falls=(Fall("mass hit the ground", "single", lambda s, p, u: ca.cos(s.theta)),
           Fall("mass hit the ground", "double", lambda s, p, u: s.z)),
    invariants=(Invariant("energy", energy, unit="J", dimension=(1, 2, -2)),),
)
