"""A third hip law: the trunk held on a virtual constraint by input-output linearisation.

The law of the hybrid-zero-dynamics view (Poulakakis and Grizzle 2009), on the thesis's
model. In stance the hip torque drives the output

    y = theta_h - (trunk_angle + trunk_slope * theta1)

(the trunk angle theta_h = theta1 + theta2 - pi/2 [rad] against a desired one that is an
affine function of the leg angle theta1 [rad]) along the critically damped error dynamics

    y'' = -omega^2 y - 2 omega y',

which the torque makes exact: y'' is affine in the torque through the stance equations
M(q) q'' = f(q, q') + (0, 0, tau) of :mod:`baslip.model.dynamics`, and the torque is the
one value that gives the asked y''. A stance that lands on the constraint (y = y' = 0)
stays on it; one that lands off it returns as (y0 + (y0' + omega y0) t) exp(-omega t).
``omega`` [1/s] is the gain the linearisation needs because touchdown does not land on
the constraint: the limit of large ``omega`` is the hybrid zero dynamics.

The law is a description's (:mod:`baslip.model.catalogue.ba_slip`), run by the generic
engine; the compiled engine's laws are :data:`baslip.model.hiplaw.HIP_LAWS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca

from baslip.model.dynamics import CONFIGURATION, STANCE, stance_equations
from baslip.model.hiplaw import HipLaw
from baslip.model.layout import Layout

#: The hip torque's input direction in the stance coordinates (rho, theta1, theta2).
TORQUE_DIRECTION = ca.DM([0.0, 0.0, 1.0])


@dataclass(frozen=True, eq=False)
class VirtualConstraintLaw(HipLaw):
    """The trunk on a desired angle that is affine in the leg angle, by input-output
    linearisation (see the module's docstring).

    Attributes
    ----------
    name, controls, units, nominal, bounds, defaults, drawn
        As for :class:`~baslip.model.hiplaw.HipLaw`; :data:`VIRTUAL_CONSTRAINT` holds this
        law's: trunk_angle [rad] (the desired trunk angle at a vertical leg), trunk_slope
        [rad/rad] (its rate in the leg angle), omega [1/s] (the error's natural
        frequency) and theta_td [rad].
    """

    def output(self, x, u):
        """(y [rad], y' [rad/s]): the trunk's distance from its constraint, and its rate.

        Parameters
        ----------
        x : casadi.SX or casadi.DM
            Stance state, 6 x 1: rho [m], theta1, theta2 [rad], rhodot [m/s], theta1_dot,
            theta2_dot [rad/s].
        u : casadi.SX, casadi.DM or array_like
            The law's controls (trunk_angle, trunk_slope, omega, theta_td).
        """
        c = self.controls.unpack(u)
        theta1, theta2 = STANCE.get(x, "theta1"), STANCE.get(x, "theta2")
        rate = self._output_gradient(c) @ x[CONFIGURATION.size:]
        return theta1 + theta2 - math.pi / 2 - (c["trunk_angle"] + c["trunk_slope"] * theta1), rate

    def torque(self, x, u, p):
        """The hip torque [N m] that gives y'' = -omega^2 y - 2 omega y' exactly.

        Parameters
        ----------
        x : casadi.SX or casadi.DM
            Stance state, 6 x 1 (one column).
        u : casadi.SX, casadi.DM or array_like
            The law's controls (trunk_angle [rad], trunk_slope, omega [1/s], theta_td [rad]).
        p : casadi.SX or casadi.DM
            The parameter vector (m, I, k, rho0, d, g).
        """
        c = self.controls.unpack(u)
        q, qdot = x[:CONFIGURATION.size], x[CONFIGURATION.size:]
        mass, free_force = stance_equations(q, qdot, 0, p)
        gradient = self._output_gradient(c)
        # The output is linear in q, so y'' = gradient . q'': no curvature term.
        free_acceleration = gradient @ ca.solve(mass, free_force)
        per_torque = gradient @ ca.solve(mass, TORQUE_DIRECTION)
        y, rate = self.output(x, u)
        wanted = -c["omega"] ** 2 * y - 2 * c["omega"] * rate
        return (wanted - free_acceleration) / per_torque

    @staticmethod
    def _output_gradient(c):
        """dy/dq along (rho, theta1, theta2): theta_h = theta1 + theta2 - pi/2."""
        return ca.horzcat(0, 1 - c["trunk_slope"], 1)


VIRTUAL_CONSTRAINT = VirtualConstraintLaw(
    name="virtual_constraint",
    controls=Layout(("trunk_angle", "trunk_slope", "omega", "theta_td")),
    units={"trunk_angle": "rad", "trunk_slope": "", "omega": "1/s", "theta_td": "rad"},
    nominal={"trunk_angle": 0.1, "trunk_slope": 0.1, "omega": 10.0, "theta_td": 0.1},
    bounds={"trunk_angle": (-2 * math.pi, 2 * math.pi), "trunk_slope": (-10.0, 10.0), "omega": (0.1, 1000.0),
            "theta_td": (-1.5, 1.5)},
    defaults={"trunk_angle": math.pi / 2, "trunk_slope": 0.0, "omega": 30.0, "theta_td": 0.1},
    drawn=("trunk_slope", "omega"),
)
