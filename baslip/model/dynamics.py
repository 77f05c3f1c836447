"""The BA-SLIP model: parameters, the stance Lagrangian, phase dynamics, maps, guards, energy.

Conventions (see the design notes and thesis ch. 3):

* ``hip = foot + rho * (-sin th1, cos th1)`` and ``CoM = hip + d * (cos th_h, sin th_h)``
  with ``th_h = th1 + th2 - pi/2``. Positive ``th1`` puts the foot ahead of the hip when
  running towards +y; ``th_h = +pi/2`` is upright, ``-pi/2`` hangs down.
* Stance coordinates ``q = (rho, theta1, theta2)`` with the foot at the origin.
* Flight state ``(y, z, theta_h, ydot, zdot, theta_h_dot)`` of the CoM and trunk.
* Apex state ``X = (z, theta_h, ydot, theta_h_dot)`` (``zdot = 0``, ``y`` cyclic).

All quantities are SI (m, kg, s, N) and radians. The stance equations are *derived* from
the Lagrangian with CasADi's automatic differentiation, not transcribed from the thesis.
This module knows nothing of control laws, files or optimisers.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from functools import cache, wraps

import casadi as ca
import numpy as np

from baslip.errors import ProblemError
from baslip.model.layout import Layout
from baslip.model.ranges import parameter_fault


def _sx_function(*sizes: int):
    """Evaluate an expression builder through an SX Function derived once on fresh symbols.

    Derivatives inside the builder need purely symbolic arguments, and a linear solve must
    stay symbolic (SX) so that MX problems can be expanded. The wrapped builder accepts
    numbers, SX or MX of the given column sizes.
    """

    def decorate(builder):
        @cache
        def function() -> ca.Function:
            args = [ca.SX.sym(f"arg{i}", n) for i, n in enumerate(sizes)]
            return ca.Function(builder.__name__.lstrip("_"), args, [builder(*args)])

        @wraps(builder)
        def call(*args):
            return function()(*args)

        call.function = function
        return call

    return decorate

PARAMS = Layout(("m", "I", "k", "rho0", "d", "g"))
STANCE = Layout(("rho", "theta1", "theta2", "rhodot", "theta1_dot", "theta2_dot"))
#: The stance configuration q: the first half of STANCE, whose second half holds the rates
#: of these entries (qdot, named here by the coordinate each is the rate of).
CONFIGURATION = Layout(("rho", "theta1", "theta2"))
FLIGHT = Layout(("y", "z", "theta_h", "ydot", "zdot", "theta_h_dot"))
APEX = Layout(("z", "theta_h", "ydot", "theta_h_dot"))


@dataclass(frozen=True)
class Params:
    """Physical parameters of the runner.

    ``rho0`` and ``d`` are the thesis's values; ``m``, ``I``, ``k`` and ``g`` are our
    documented choice (the thesis does not print them).

    Attributes
    ----------
    m : float
        Trunk mass [kg] (the leg is massless).
    I : float
        Trunk moment of inertia about its CoM [kg m^2].
    k : float
        Leg stiffness [N/m].
    rho0 : float
        Leg rest length [m].
    d : float
        Hip-to-CoM distance [m].
    g : float
        Gravity [m/s^2].

    Raises
    ------
    ProblemError
        A value that is not a finite number in its physical range
        (:data:`baslip.model.ranges.PARAM_RANGES`), named ``params.<name>`` with the
        problem reader's message.
    """

    m: float = 1.0
    I: float = 0.0033  # noqa: E741 - the trunk's moment of inertia, as in the thesis
    k: float = 1000.0
    rho0: float = 0.2
    d: float = 0.04
    g: float = 9.81

    def __post_init__(self):
        for name in PARAMS.names:
            fault = parameter_fault(name, getattr(self, name))
            if fault is not None:
                raise ProblemError(f"params.{name}", fault)

    def vector(self) -> np.ndarray:
        """The parameters in :data:`PARAMS` order (called for every stride: no asdict)."""
        return np.array([self.m, self.I, self.k, self.rho0, self.d, self.g], dtype=float)

    def to_dict(self) -> dict[str, float]:
        """The parameters as plain floats by name (m, I, k, rho0, d, g), SI units."""
        return {k: float(v) for k, v in asdict(self).items()}

    def with_(self, **changes: float) -> Params:
        """A copy with some parameters changed, e.g. ``Params().with_(k=2000.0)``.

        Parameters
        ----------
        **changes : float
            New values by parameter name, SI units, checked as when built.
        """
        return replace(self, **changes)


# --- kinematics ---------------------------------------------------------------------------


def body_angle(theta1, theta2):
    """Trunk angle from the horizontal [rad], eq. 3.18."""
    return theta1 + theta2 - np.pi / 2


def stance_hip_position(q):
    """Hip position [m] relative to the foot during stance."""
    rho, theta1 = STANCE.get(q, "rho"), STANCE.get(q, "theta1")
    return ca.vertcat(-rho * ca.sin(theta1), rho * ca.cos(theta1))


def stance_com_position(q, p):
    """CoM position [m] relative to the foot during stance, eq. 3.16."""
    th_h = body_angle(STANCE.get(q, "theta1"), STANCE.get(q, "theta2"))
    d = PARAMS.get(p, "d")
    return stance_hip_position(q) + d * ca.vertcat(ca.cos(th_h), ca.sin(th_h))


def stance_pose(q, p):
    """(y, z, theta_h) of the trunk as a function of the stance coordinates."""
    th_h = body_angle(STANCE.get(q, "theta1"), STANCE.get(q, "theta2"))
    return ca.vertcat(stance_com_position(q, p), th_h)


def _coordinates(x):
    """Split a stance state into configuration q and velocity qdot."""
    n = CONFIGURATION.size
    return x[:n], x[n : 2 * n]


# --- Lagrangian mechanics of stance -------------------------------------------------------


@_sx_function(3, 3, 6)
def stance_kinetic_energy(q, qdot, p):
    """T = m/2 |v_CoM|^2 + I/2 theta_h_dot^2 [J]."""
    v_com = ca.mtimes(stance_velocity_jacobian(q, p)[:2, :], qdot)
    # theta_h = theta1 + theta2 - pi/2
    theta_h_dot = CONFIGURATION.get(qdot, "theta1") + CONFIGURATION.get(qdot, "theta2")
    m, inertia = PARAMS.get(p, "m"), PARAMS.get(p, "I")
    return 0.5 * m * ca.dot(v_com, v_com) + 0.5 * inertia * theta_h_dot**2


def stance_potential_energy(q, p):
    """V = m g z_CoM + k/2 (rho - rho0)^2 [J]."""
    m, g, k, rho0 = (PARAMS.get(p, n) for n in ("m", "g", "k", "rho0"))
    z_com = stance_com_position(q, p)[1]
    return m * g * z_com + 0.5 * k * (STANCE.get(q, "rho") - rho0) ** 2


@_sx_function(3, 6)
def stance_velocity_jacobian(q, p):
    """J(q) with (ydot, zdot, theta_h_dot) = J(q) qdot, eqs. 3.19-3.21; det J = rho."""
    return ca.jacobian(stance_pose(q, p), q)


@_sx_function(3, 3, 1, 6)
def _euler_lagrange(q, qdot, tau, p):
    """[M | f] with M qddot = f, derived from L = T - V (eq. 3.25).

    M = d2L/dqdot2 and f = dL/dq - d/dq(dL/dqdot) qdot + Q, with generalised force
    Q = (0, 0, tau): the hip torque does virtual work only through theta2.
    """
    lagrangian = stance_kinetic_energy(q, qdot, p) - stance_potential_energy(q, p)
    momentum = ca.gradient(lagrangian, qdot)
    mass = ca.jacobian(momentum, qdot)
    momentum_rate_from_q = ca.jtimes(momentum, q, qdot)
    generalised_force = ca.vertcat(0, 0, tau)
    rhs = ca.gradient(lagrangian, q) - momentum_rate_from_q + generalised_force
    return ca.horzcat(mass, rhs)


def stance_equations(q, qdot, tau, p):
    """Mass matrix M(q) [kg, kg m, kg m^2] and right-hand side f, with M qddot = f."""
    mass_and_rhs = _euler_lagrange(q, qdot, tau, p)
    return mass_and_rhs[:, :3], mass_and_rhs[:, 3]


@_sx_function(6, 1, 6)
def stance_dynamics(x, tau, p):
    """Time derivative of the stance state for hip torque ``tau`` [N m]."""
    q, qdot = _coordinates(x)
    mass, rhs = stance_equations(q, qdot, tau, p)
    return ca.vertcat(qdot, ca.solve(mass, rhs))


# --- energy -------------------------------------------------------------------------------


def stance_energy(x, p):
    """Total mechanical energy [J] of a stance state (foot at z = 0)."""
    q, qdot = _coordinates(x)
    return stance_kinetic_energy(q, qdot, p) + stance_potential_energy(q, p)


def flight_energy(xf, p):
    """Total mechanical energy [J] of a flight state (spring at rest, massless leg)."""
    f = FLIGHT.unpack(xf)
    m, inertia, g = PARAMS.get(p, "m"), PARAMS.get(p, "I"), PARAMS.get(p, "g")
    return (
        0.5 * m * (f["ydot"] ** 2 + f["zdot"] ** 2)
        + 0.5 * inertia * f["theta_h_dot"] ** 2
        + m * g * f["z"]
    )


def apex_energy(apex, p):
    """Total mechanical energy [J] at apex, where zdot = 0."""
    return flight_energy(apex_to_flight(apex), p)


# --- flight -------------------------------------------------------------------------------


def apex_to_flight(apex, y=0.0):
    """Flight state at an apex (zdot = 0), with horizontal position ``y``."""
    a = APEX.unpack(apex)
    return ca.vertcat(y, a["z"], a["theta_h"], a["ydot"], 0, a["theta_h_dot"])


def ballistic_flight(xf, t, p):
    """Flight state ``t`` seconds after ``xf``: ballistic CoM, constant spin (eq. 3.13)."""
    f = FLIGHT.unpack(xf)
    g = PARAMS.get(p, "g")
    return ca.vertcat(
        f["y"] + f["ydot"] * t,
        f["z"] + f["zdot"] * t - 0.5 * g * t**2,
        f["theta_h"] + f["theta_h_dot"] * t,
        f["ydot"],
        f["zdot"] - g * t,
        f["theta_h_dot"],
    )


def flight_to_apex(xf, p):
    """Apex state reached from a rising flight state (closed form: t = zdot / g)."""
    f = FLIGHT.unpack(xf)
    rise_time = f["zdot"] / PARAMS.get(p, "g")
    top = ballistic_flight(xf, rise_time, p)
    return ca.vertcat(FLIGHT.get(top, "z"), FLIGHT.get(top, "theta_h"), f["ydot"], f["theta_h_dot"])


def descent_foot_height(t, z, theta_h, theta_h_dot, theta_td, d, rho0, g):
    """Foot height [m] ``t`` seconds after an apex, numerically (numpy, vectorised in t).

    The same quantity as :func:`touchdown_guard` along the descent, for bracketing the
    touchdown and checking an apex before any symbolic work.
    """
    t = np.asarray(t, dtype=float)
    return z - 0.5 * g * t**2 - d * np.sin(theta_h + theta_h_dot * t) - rho0 * np.cos(theta_td)


def flight_hip_position(xf, p):
    """Hip position [m] in flight."""
    f = FLIGHT.unpack(xf)
    d = PARAMS.get(p, "d")
    return ca.vertcat(f["y"] - d * ca.cos(f["theta_h"]), f["z"] - d * ca.sin(f["theta_h"]))


def flight_foot_position(xf, theta_td, p):
    """Foot position [m] in flight with the massless leg held at ``theta_td`` at rest length."""
    rho0 = PARAMS.get(p, "rho0")
    return flight_hip_position(xf, p) - rho0 * ca.vertcat(-ca.sin(theta_td), ca.cos(theta_td))


# --- guards (each crosses zero in a set direction at its event) ----------------------------


def touchdown_guard(xf, theta_td, p):
    """Foot height [m]; touchdown when it falls through zero during descent."""
    return flight_foot_position(xf, theta_td, p)[1]


def touchdown_guard_rate(xf, p):
    """Time derivative of the foot height [m/s] in flight (negative at a valid touchdown)."""
    f = FLIGHT.unpack(xf)
    return f["zdot"] - PARAMS.get(p, "d") * ca.cos(f["theta_h"]) * f["theta_h_dot"]


def bottom_guard(x):
    """rhodot [m/s]; bottom when it rises through zero (compression -> decompression)."""
    return STANCE.get(x, "rhodot")


def liftoff_guard(x, p):
    """rho - rho0 [m]; liftoff when it rises through zero (spring force vanishes)."""
    return STANCE.get(x, "rho") - PARAMS.get(p, "rho0")


def apex_guard(xf):
    """zdot [m/s]; apex when it falls through zero during ascent."""
    return FLIGHT.get(xf, "zdot")


# --- touchdown and liftoff maps -----------------------------------------------------------


@_sx_function(6, 1, 6)
def touchdown_map(xf, theta_td, p):
    """Stance state at touchdown from the flight state there.

    The leg is massless, so there is no impact: rho = rho0, theta1 = theta_td,
    theta2 = theta_h + pi/2 - theta_td, and qdot solves J(q) qdot = (ydot, zdot, theta_h_dot).
    """
    f = FLIGHT.unpack(xf)
    q = ca.vertcat(PARAMS.get(p, "rho0"), theta_td, f["theta_h"] + np.pi / 2 - theta_td)
    velocity = ca.vertcat(f["ydot"], f["zdot"], f["theta_h_dot"])
    qdot = ca.solve(stance_velocity_jacobian(q, p), velocity)
    return ca.vertcat(q, qdot)


@_sx_function(6, 6)
def liftoff_map(x, p):
    """Flight state at liftoff (y relative to the foot) from the stance state there.

    Eqs. 3.16-3.21 read forwards.
    """
    q, qdot = _coordinates(x)
    pose = stance_pose(q, p)
    velocity = ca.mtimes(stance_velocity_jacobian(q, p), qdot)
    return ca.vertcat(pose, velocity)


@dataclass(frozen=True)
class Model:
    """CasADi Functions of the model, built once and reused (all inputs numeric or MX).

    Inputs are named by their layouts; ``p`` is a :data:`PARAMS` vector.
    """

    mass_matrix: ca.Function  # (q[3], p) -> M[3x3]   [kg, kg m, kg m^2]
    stance_dynamics: ca.Function  # (x[6], tau, p) -> xdot[6]
    stance_energy: ca.Function  # (x[6], p) -> E [J]
    flight_energy: ca.Function  # (xf[6], p) -> E [J]
    apex_energy: ca.Function  # (X[4], p) -> E [J]
    touchdown_map: ca.Function  # (xf[6], theta_td, p) -> x[6]
    liftoff_map: ca.Function  # (x[6], p) -> xf[6]
    touchdown_guard: ca.Function  # (xf[6], theta_td, p) -> foot height [m]


def build_model() -> Model:
    """Derive the model symbolically once and wrap each piece as a CasADi Function."""
    x = STANCE.sym("x")
    xf = FLIGHT.sym("xf")
    apex = APEX.sym("X")
    p = PARAMS.sym("p")
    tau = ca.SX.sym("tau")
    theta_td = ca.SX.sym("theta_td")
    q, qdot = _coordinates(x)
    mass, _ = stance_equations(q, qdot, tau, p)
    return Model(
        mass_matrix=ca.Function("mass_matrix", [q, p], [mass], ["q", "p"], ["M"]),
        stance_dynamics=ca.Function(
            "stance_dynamics", [x, tau, p], [stance_dynamics(x, tau, p)], ["x", "tau", "p"], ["xdot"]
        ),
        stance_energy=ca.Function("stance_energy", [x, p], [stance_energy(x, p)], ["x", "p"], ["E"]),
        flight_energy=ca.Function("flight_energy", [xf, p], [flight_energy(xf, p)], ["xf", "p"], ["E"]),
        apex_energy=ca.Function("apex_energy", [apex, p], [apex_energy(apex, p)], ["X", "p"], ["E"]),
        touchdown_map=ca.Function(
            "touchdown_map", [xf, theta_td, p], [touchdown_map(xf, theta_td, p)],
            ["xf", "theta_td", "p"], ["x"],
        ),
        liftoff_map=ca.Function("liftoff_map", [x, p], [liftoff_map(x, p)], ["x", "p"], ["xf"]),
        touchdown_guard=ca.Function(
            "touchdown_guard", [xf, theta_td, p], [touchdown_guard(xf, theta_td, p)],
            ["xf", "theta_td", "p"], ["h"],
        ),
    )
