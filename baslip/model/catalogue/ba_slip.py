"""The BA-SLIP as a model description, under each of its hip laws.

The physics is that of :mod:`baslip.model.dynamics` (the stance Lagrangian, ballistic
flight, the touchdown and liftoff maps, the guards) and :mod:`baslip.model.hiplaw` (each law's stance torque),
read through the description's named symbols: this module adds no physics of its own. A
stride is flight, compression, decompression, flight, on the apex section in
``(z, theta_h, ydot, theta_h_dot)`` with ``y`` cyclic; the bottom (``rhodot`` rising
through zero) separates compression from decompression and keeps the state.

The compiled engine (:mod:`baslip.engine.driver`), BA-SLIP's fast path for PD and VPP,
reads its stance flow, ballistic flight, guards, resets and falls from this description
(:mod:`baslip.engine.physics`); the catalogue's test holds the generic engine on this
description to its strides and Jacobians. The third law, the virtual constraint
(:mod:`baslip.model.virtual_constraint`), is the description's alone.
"""

from __future__ import annotations

import casadi as ca

from baslip.model.description import ControlLaw, Fall, Mode, Model, Quantity, Section, Transition
from baslip.model.dynamics import (
    APEX,
    CONFIGURATION,
    FLIGHT,
    PARAMS,
    STANCE,
    Params,
    ballistic_flight,
    liftoff_map,
    stance_com_position,
    stance_hip_position,
    stance_kinetic_energy,
    stance_potential_energy,
    touchdown_guard,
    touchdown_map,
)
from baslip.model.hiplaw import HIP_LAWS, HipLaw
from baslip.model.ranges import PARAM_RANGES, PARAM_UNITS
from baslip.model.virtual_constraint import VIRTUAL_CONSTRAINT

#: Exponents of (mass, length, time) of each parameter and control.
DIMENSIONS = {
    "m": (1, 0, 0), "I": (1, 2, 0), "k": (1, 0, -2), "rho0": (0, 1, 0), "d": (0, 1, 0), "g": (0, 1, -2),
    "Kp": (1, 2, -2), "Kd": (1, 2, -1), "theta2_des": (0, 0, 0), "theta2_dot_des": (0, 0, -1),
    "r_vpp": (0, 1, 0), "theta_td": (0, 0, 0), "trunk_angle": (0, 0, 0), "trunk_slope": (0, 0, 0), "omega": (0, 0, -1),
}
#: The leg collapses below this fraction of its rest length [-]: a fall (the engines read it here).
COLLAPSE_FRACTION = 0.05
STANCE_MODES = ("compression", "decompression")


def _vector(layout, names) -> ca.SX:
    return layout.pack({n: names[n] for n in layout.names})


def _stance(s):
    return _vector(STANCE, s)


def _params(p):
    return _vector(PARAMS, p)


def flight_lagrangian(s, p, u):
    """Kinetic minus potential energy of the trunk in flight [J] (the leg is massless)."""
    return (p.m / 2 * (s.ydot**2 + s.zdot**2) + p.I / 2 * s.theta_h_dot**2) - p.m * p.g * s.z


def stance_lagrangian(s, p, u):
    """L = T - V of stance (eq. 3.25), from :mod:`baslip.model.dynamics`."""
    x, params = _stance(s), _params(p)
    q, qdot = x[:CONFIGURATION.size], x[CONFIGURATION.size:]
    return stance_kinetic_energy(q, qdot, params) - stance_potential_energy(q, params)


def _torque(law: HipLaw):
    def forces(s, p, u):
        controls = law.controls.pack({n: u[n] for n in law.controls.names})
        return {"theta2": law.torque(_stance(s), controls, _params(p))}
    return forces


def _law(law: HipLaw) -> ControlLaw:
    controls = tuple(Quantity(n, law.units[n], law.defaults[n], *law.bounds[n], DIMENSIONS[n])
                     for n in law.controls.names if n != "theta_td")
    # A torque of positions only (VPP) makes the gaits upright at the apex time-symmetric,
    # a family at fixed controls: one multiplier 1 by structure.
    return ControlLaw(law.name, controls, {mode: _torque(law) for mode in STANCE_MODES},
                      families=1 if law.positional else 0)


def _ballistic_flight(s, p, u, t):
    """Flight ``t`` seconds on: ballistic CoM, constant spin (eq. 3.13)."""
    return dict(zip(FLIGHT.names, ca.vertsplit(ballistic_flight(_vector(FLIGHT, s), t, _params(p)))))


def _touchdown_guard(s, p, u):
    return touchdown_guard(_vector(FLIGHT, s), u.theta_td, _params(p))


def _touchdown_map(s, p, u):
    return touchdown_map(_vector(FLIGHT, s), u.theta_td, _params(p))


def _liftoff_map(s, p, u):
    return liftoff_map(_stance(s), _params(p))


def _parameters() -> tuple[Quantity, ...]:
    defaults = Params().to_dict()
    return tuple(Quantity(n, PARAM_UNITS[n], defaults[n], PARAM_RANGES[n][0], PARAM_RANGES[n][1], DIMENSIONS[n])
                 for n in PARAMS.names)


def _stance_falls() -> tuple[Fall, ...]:
    falls = []
    for mode in STANCE_MODES:
        falls += [
            Fall("hip touches the ground", mode, lambda s, p, u: stance_hip_position(_stance(s))[1]),
            Fall("CoM touches the ground", mode, lambda s, p, u: stance_com_position(_stance(s), _params(p))[1]),
            Fall("leg collapses", mode, lambda s, p, u: s.rho - COLLAPSE_FRACTION * p.rho0),
        ]
    return tuple(falls)


BA_SLIP = Model(
    name="ba-slip",
    description="rigid trunk on a massless spring leg with a hip motor (the thesis's model)",
    parameters=_parameters(),
    modes=(
        Mode("flight", FLIGHT.names[:3], FLIGHT.names[3:], lagrangian=flight_lagrangian, flow=_ballistic_flight),
        *(Mode(m, CONFIGURATION.names, STANCE.names[3:], lagrangian=stance_lagrangian) for m in STANCE_MODES),
    ),
    order=("flight", "compression", "decompression", "flight"),
    transitions=(
        Transition("flight", "compression", _touchdown_guard, -1, _touchdown_map, "touchdown"),
        Transition("compression", "decompression", lambda s, p, u: s.rhodot, +1, None, "bottom"),
        Transition("decompression", "flight", lambda s, p, u: s.rho - p.rho0, +1, _liftoff_map, "liftoff"),
    ),
    section=Section("flight", lambda s, p, u: s.zdot, -1, APEX.names, cyclic=("y",), pinned={"zdot": 0.0},
                    units={"z": "m", "theta_h": "rad", "ydot": "m/s", "theta_h_dot": "rad/s"}),
    laws=tuple(_law(law) for law in (*HIP_LAWS.values(), VIRTUAL_CONSTRAINT)),
    controls=(Quantity("theta_td", "rad", 0.1, -1.5, 1.5, DIMENSIONS["theta_td"]),),
    falls=(Fall("CoM touches the ground", "flight", lambda s, p, u: s.z), *_stance_falls()),
)
