"""A one-legged hopper with leg damping, written as a baslip model description.

A point mass on a massless leg: a spring and a damper in parallel. The leg lands at the
angle ``theta_td`` from the vertical and pushes by lengthening its spring's rest length
by ``push`` at the bottom of stance, which gives back what the damper takes. It leaves
the ground when the leg force falls to zero. The guide "Writing a model"
(docs/guides/models.md) builds it line by line; problems/hopper.yaml runs it.
"""

import casadi as ca

from baslip.model.description import ControlLaw, Fall, Mode, Model, Quantity, Section, Transition


def flight(s, p, u):
    return p.m / 2 * (s.ydot**2 + s.zdot**2) - p.m * p.g * s.z


def stance(rest_length):
    def lagrangian(s, p, u):
        kinetic = p.m / 2 * (s.rhodot**2 + s.rho**2 * s.theta_dot**2)
        return kinetic - p.m * p.g * s.rho * ca.cos(s.theta) - p.k / 2 * (s.rho - rest_length(p, u)) ** 2
    return lagrangian


def damping(s, p, u):
    return {"rho": -p.c * s.rhodot}


def landing(s, p, u):
    sin_t, cos_t = ca.sin(u.theta_td), ca.cos(u.theta_td)
    return {"rho": p.l0, "theta": u.theta_td, "rhodot": -s.ydot * sin_t + s.zdot * cos_t,
            "theta_dot": (-s.ydot * cos_t - s.zdot * sin_t) / p.l0}


def takeoff(s, p, u):
    sin_t, cos_t = ca.sin(s.theta), ca.cos(s.theta)
    return {"y": -s.rho * sin_t, "z": s.rho * cos_t, "ydot": -s.rhodot * sin_t - s.rho * s.theta_dot * cos_t,
            "zdot": s.rhodot * cos_t - s.rho * s.theta_dot * sin_t}


def leg_force(s, p, u):
    return p.k * (p.l0 + u.push - s.rho) - p.c * s.rhodot


STANCE = ("rho", "theta"), ("rhodot", "theta_dot")
HOPPER = Model(
    name="hopper",
    description="point mass on a damped spring leg that pushes at the bottom",
    parameters=(Quantity("m", "kg", 80.0, 0.0, 1e4, (1, 0, 0)), Quantity("k", "N/m", 20000.0, 0.0, 1e8, (1, 0, -2)),
                Quantity("c", "N s/m", 100.0, 0.0, 1e6, (1, 0, -1)), Quantity("l0", "m", 1.0, 0.0, 10.0, (0, 1, 0)),
                Quantity("g", "m/s^2", 9.81, 0.0, 100.0, (0, 1, -2))),
    modes=(Mode("flight", ("y", "z"), ("ydot", "zdot"), lagrangian=flight),
           Mode("compression", *STANCE, lagrangian=stance(lambda p, u: p.l0), forces=damping),
           Mode("decompression", *STANCE, lagrangian=stance(lambda p, u: p.l0 + u.push), forces=damping)),
    order=("flight", "compression", "decompression", "flight"),
    transitions=(Transition("flight", "compression", lambda s, p, u: s.z - p.l0 * ca.cos(u.theta_td), -1, landing,
                            "touchdown"),
                 Transition("compression", "decompression", lambda s, p, u: s.rhodot, +1, None, "bottom"),
                 Transition("decompression", "flight", leg_force, -1, takeoff, "liftoff")),
    section=Section("flight", lambda s, p, u: s.zdot, -1, ("z", "ydot"), cyclic=("y",), pinned={"zdot": 0.0},
                    units={"z": "m", "ydot": "m/s"}, dimensions={"z": (0, 1, 0), "ydot": (0, 1, -1)}),
    controls=(Quantity("theta_td", "rad", 0.38, -1.2, 1.2), Quantity("push", "m", 0.01, -0.2, 0.2, (0, 1, 0))),
    laws=(ControlLaw("push at the bottom"),),
    falls=(Fall("mass hit the ground", "compression", lambda s, p, u: ca.cos(s.theta)),),
    reference={"z": 1.0, "ydot": 5.0, "theta_td": 0.390127, "push": 0.022457},  # a hop at 5 m/s
)
