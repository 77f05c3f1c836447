"""Stance hip laws: what each one controls, in which units, and the torque it gives.

A hip law is an object (:class:`HipLaw`) with its control layout and its stance torque
``tau(x, u, p)`` [N m]. Every law ends its controls with ``theta_td`` [rad], the leg angle
from the vertical at which the massless leg is held in flight (so the leg angle at
touchdown): flight is the same under every law.

* :data:`PD` (``hip_law: pd``, the thesis's eq. 3.37), ``u = (Kp, Kd, theta2_des,
  theta2_dot_des, theta_td)``: ``Kp`` [N m/rad] and ``Kd`` [N m s/rad] are PD gains on the
  leg-trunk angle theta2, ``theta2_des`` [rad] and ``theta2_dot_des`` [rad/s] their set
  points.
* :data:`VPP` (``hip_law: vpp``, the virtual pivot point of Maus et al. 2010), ``u = (r_vpp,
  theta_td)``: the ground force points at the point ``r_vpp`` [m] from the CoM along the
  trunk axis, away from the hip (above the CoM for an upright trunk).

A third law is one more subclass and one more entry of :data:`HIP_LAWS`, here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from baslip.model.dynamics import CONFIGURATION, PARAMS, STANCE, stance_com_position
from baslip.model.layout import Layout


@dataclass(frozen=True, eq=False)
class HipLaw:
    """A stance hip-torque law: its name, its controls and their units, and the torque.

    Laws are compared and hashed by identity: there is one object per law.

    Attributes
    ----------
    name : str
        The law's name in problem files (``hip_law:``) and in compiled libraries' names.
    controls : Layout
        The control vector's entries, ``theta_td`` last.
    units, nominal, bounds, defaults : Mapping
        Per control: its SI unit, its scale (for distances and steps), its physical
        bounds and its default start value.
    drawn : tuple of str
        The controls a search draws over their whole bounds for each independent start
        (the optimal search's starts, the atlas's seeds): the law's gains.
    """

    name: str
    controls: Layout
    units: Mapping[str, str] = field(default_factory=dict)
    nominal: Mapping[str, float] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    defaults: Mapping[str, float] = field(default_factory=dict)
    drawn: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.controls.names[-1] != "theta_td":
            raise ValueError(f"hip law {self.name!r}: theta_td must be its last control, not {self.controls.names[-1]!r}")
        for table in (self.units, self.nominal, self.bounds, self.defaults):
            if set(table) != set(self.controls.names):
                raise ValueError(f"hip law {self.name!r}: a table names {sorted(table)}, not its controls")
        if not set(self.drawn) <= set(self.controls.names):
            raise ValueError(f"hip law {self.name!r}: it draws {list(self.drawn)}, not all of them its controls")

    def __reduce__(self):
        # One object per law, in worker processes too: a law travels as its name.
        return hip_law, (self.name,)

    def torque(self, x, u, p):
        """Hip torque [N m] on the trunk (on theta2) at stance state ``x``, control ``u``
        and parameters ``p``; columns of ``x`` give a row of torques.

        Parameters
        ----------
        x : casadi.SX, casadi.MX or casadi.DM
            Stance state, 6 x 1 or 6 x n: rho [m], theta1 [rad], theta2 [rad], rhodot [m/s],
            theta1_dot [rad/s], theta2_dot [rad/s].
        u : casadi.SX, casadi.MX or casadi.DM
            The law's control vector (SI units and radians).
        p : casadi.SX, casadi.MX or casadi.DM
            The parameter vector (m, I, k, rho0, d, g), as
            :meth:`baslip.model.dynamics.Params.vector` orders it.
        """
        raise NotImplementedError

    def torque_free(self, values: Mapping[str, float]) -> bool:
        """Whether controls ``values`` (a subset, e.g. a problem's fixed ones) make the
        torque zero in every stance state, so that energy is conserved.

        Parameters
        ----------
        values : Mapping of str to float
            Some of the law's controls by name, SI units and radians.
        """
        return False

    def spin_free(self, values: Mapping[str, float], params) -> bool:
        """Whether controls ``values`` (a subset) and ``params`` leave the trunk's spin
        unchanged through every stance: the ground force then has no moment about the
        CoM, so theta_h_dot maps to itself and theta_h to itself plus T theta_h_dot.

        Parameters
        ----------
        values : Mapping of str to float
            Some of the law's controls by name, SI units and radians.
        params : Params
            The model parameters (here: whether d [m] is zero).
        """
        return self.torque_free(values) and params.d == 0.0

    def step_rates(self, u, p) -> tuple[np.ndarray, np.ndarray]:
        """(hip stiffness [N m/rad], hip damping [N m s/rad]): upper estimates of
        |d tau / d theta2| and |d tau / d theta2_dot| for the integrator's first step size
        (the accuracy checks do not rely on them); ``u`` may hold rows of many controls.

        Parameters
        ----------
        u : array_like
            The law's control vector, shape (controls,), or rows of many, shape (n, controls).
        p : array_like
            The parameter vector, shape (6,) (m, I, k, rho0, d, g).
        """
        raise NotImplementedError

    def hip_rates(self, u, p) -> tuple[list, list]:
        """(stiffness terms [N m/rad], damping terms [N m s/rad]): smooth expressions of the
        controls whose largest is |d tau / d theta2| (resp. |d tau / d theta2_dot|) over a
        stance, exactly or as an estimate (see each law), for a limit on the torque's rates
        inside an NLP (signed pairs, so that a limit on the largest is smooth; empty where
        the torque has no such rate).

        Parameters
        ----------
        u : casadi.SX, casadi.MX or casadi.DM
            The law's control vector (SI units and radians).
        p : casadi.SX, casadi.MX or casadi.DM
            The parameter vector (m, I, k, rho0, d, g).
        """
        raise NotImplementedError

    def rate_limited_bounds(self, stiffness: float, damping: float, params) -> dict[str, tuple[float, float]]:
        """Bounds on the drawn controls (:attr:`drawn`) inside which every term of
        :meth:`hip_rates` stays within ``stiffness`` [N m/rad] and ``damping`` [N m s/rad].

        Parameters
        ----------
        stiffness, damping : float
            The largest hip stiffness [N m/rad] and damping [N m s/rad] allowed.
        params : Params
            The model parameters.
        """
        raise NotImplementedError

    @property
    def positional(self) -> bool:
        """Whether the torque depends on positions only: the law's gaits then have the
        mirror-and-time-reversal symmetry, with symmetric families at theta_h = 90 deg."""
        return False

    def control_dict(self, u) -> dict[str, float]:
        """Plain-float dictionary of a numeric control vector.

        Parameters
        ----------
        u : array_like
            The law's control vector, shape (controls,), SI units and radians.
        """
        return self.controls.to_dict(u)


def touchdown_angle(u):
    """The leg angle theta_td [rad] held through flight: the last control of every law."""
    return u[-1]


@dataclass(frozen=True, eq=False)
class PDLaw(HipLaw):
    """The thesis's PD torque on theta2, eq. 3.37.

    Attributes
    ----------
    name, controls, units, nominal, bounds, defaults, drawn
        As for :class:`HipLaw`; :data:`PD` holds this law's: controls Kp [N m/rad],
        Kd [N m s/rad], theta2_des [rad], theta2_dot_des [rad/s], theta_td [rad].
    """

    def torque(self, x, u, p):
        """tau = -Kp (th2 - th2_des) - Kd (th2dot - th2dot_des) [N m].

        Parameters
        ----------
        x : casadi.SX, casadi.MX or casadi.DM
            Stance state, 6 x 1 or 6 x n (rho [m], theta1, theta2 [rad], rhodot [m/s],
            theta1_dot, theta2_dot [rad/s]).
        u : casadi.SX, casadi.MX, casadi.DM or array_like
            The PD controls (Kp, Kd, theta2_des, theta2_dot_des, theta_td).
        p : casadi.SX, casadi.MX or casadi.DM
            The parameter vector; the PD torque does not depend on it.
        """
        c = self.controls.unpack(u)
        theta2_error = STANCE.get(x, "theta2") - c["theta2_des"]
        theta2_rate_error = STANCE.get(x, "theta2_dot") - c["theta2_dot_des"]
        return -c["Kp"] * theta2_error - c["Kd"] * theta2_rate_error

    def torque_free(self, values: Mapping[str, float]) -> bool:
        """Whether ``values`` fix both gains at zero (Kp = Kd = 0): no torque at all.

        Parameters
        ----------
        values : Mapping of str to float
            Some of the PD controls by name, SI units and radians.
        """
        return values.get("Kp") == 0.0 and values.get("Kd") == 0.0

    def step_rates(self, u, p) -> tuple[np.ndarray, np.ndarray]:
        """(|Kp| [N m/rad], |Kd| [N m s/rad]), exactly the torque's rates.

        Parameters
        ----------
        u : array_like
            The PD controls, shape (5,), or rows of many, shape (n, 5).
        p : array_like
            The parameter vector (unused).
        """
        u = np.asarray(u, dtype=float).T  # entries first
        return np.abs(u[self.controls.index("Kp")]), np.abs(u[self.controls.index("Kd")])

    def hip_rates(self, u, p) -> tuple[list, list]:
        """([Kp, -Kp], [Kd, -Kd]): the torque's rates are the gains themselves.

        Parameters
        ----------
        u : casadi.SX, casadi.MX or casadi.DM
            The PD controls (Kp, Kd, theta2_des, theta2_dot_des, theta_td).
        p : casadi.SX, casadi.MX or casadi.DM
            The parameter vector (unused).
        """
        Kp, Kd = self.controls.get(u, "Kp"), self.controls.get(u, "Kd")
        return [Kp, -Kp], [Kd, -Kd]

    def rate_limited_bounds(self, stiffness: float, damping: float, params) -> dict[str, tuple[float, float]]:
        """|Kp| <= ``stiffness`` [N m/rad] and |Kd| <= ``damping`` [N m s/rad].

        Parameters
        ----------
        stiffness, damping : float
            The largest hip stiffness [N m/rad] and damping [N m s/rad] allowed.
        params : Params
            The model parameters (unused).
        """
        return {"Kp": (-stiffness, stiffness), "Kd": (-damping, damping)}


@dataclass(frozen=True, eq=False)
class VPPLaw(HipLaw):
    """The virtual pivot point: the ground force passes through a point on the trunk axis.

    With the massless leg, the force the ground puts on the runner is the spring force
    along the leg plus the torque's reaction across it (see :func:`ground_force`). baslip
    keeps the axial part equal to the spring force, because the spring is the leg's only
    axial element: a law that set the force's magnitude to the spring force instead would
    need an axial force the massless leg cannot carry. The torque is then the one value
    that turns that force through the pivot.

    Attributes
    ----------
    name, controls, units, nominal, bounds, defaults, drawn
        As for :class:`HipLaw`; :data:`VPP` holds this law's: controls r_vpp [m] and
        theta_td [rad].
    """

    def torque(self, x, u, p):
        """tau = rho k (rho0 - rho) (V x e) / (V x n) [N m], from V x G = 0 with G of
        :func:`ground_force`, V the pivot relative to the foot.

        Parameters
        ----------
        x : casadi.SX, casadi.MX or casadi.DM
            Stance state, 6 x 1 or 6 x n (rho [m], theta1, theta2 [rad], rhodot [m/s],
            theta1_dot, theta2_dot [rad/s]).
        u : casadi.SX, casadi.MX or casadi.DM
            The VPP controls (r_vpp [m], theta_td [rad]).
        p : casadi.SX, casadi.MX or casadi.DM
            The parameter vector (m, I, k, rho0, d, g).
        """
        q = x[: CONFIGURATION.size, :]
        pivot = virtual_pivot(q, self.controls.get(u, "r_vpp"), p)
        along, across = leg_axes(STANCE.get(x, "theta1"))
        rho = STANCE.get(x, "rho")
        spring = PARAMS.get(p, "k") * (PARAMS.get(p, "rho0") - rho)
        return rho * spring * _cross(pivot, along) / _cross(pivot, across)

    @property
    def positional(self) -> bool:
        """True: the VPP torque depends on positions only (no velocities)."""
        return True

    def spin_free(self, values: Mapping[str, float], params) -> bool:
        """Whether ``values`` fix the pivot at the CoM (r_vpp = 0), whatever ``params``.

        Parameters
        ----------
        values : Mapping of str to float
            Some of the VPP controls by name, SI units and radians.
        params : Params
            The model parameters (unused: the force then points at the CoM for any d).
        """
        return values.get("r_vpp") == 0.0  # the force points at the CoM

    def step_rates(self, u, p) -> tuple[np.ndarray, np.ndarray]:
        """(3 m g (|r_vpp| + d) [N m/rad], 0 [N m s/rad]): the hip stiffness estimated from
        a force of 3 body weights on the lever to the pivot; no damping.

        Parameters
        ----------
        u : array_like
            The VPP controls, shape (2,), or rows of many, shape (n, 2).
        p : array_like
            The parameter vector, shape (6,) (m, I, k, rho0, d, g).
        """
        r = np.abs(np.asarray(u, dtype=float).T[self.controls.index("r_vpp")])
        m, d, g = (float(p[PARAMS.index(n)]) for n in ("m", "d", "g"))
        return PEAK_FORCE_IN_WEIGHTS * m * g * (r + d), np.zeros_like(r)

    def hip_rates(self, u, p) -> tuple[list, list]:
        """([3 m g (d + r_vpp), 3 m g (d - r_vpp)], []): the estimate of :meth:`step_rates`
        as a signed pair, whose larger is 3 m g (|r_vpp| + d); no damping. An estimate, not
        a bound: along the gaits of problems/vpp.yaml, vpp_human.yaml and eight cells of
        optimal_vpp, the largest |d tau / d theta2| is 0.35 to 1.6 times it.

        Parameters
        ----------
        u : casadi.SX, casadi.MX or casadi.DM
            The VPP controls (r_vpp [m], theta_td [rad]).
        p : casadi.SX, casadi.MX or casadi.DM
            The parameter vector (m, I, k, rho0, d, g).
        """
        m, d, g = (PARAMS.get(p, name) for name in ("m", "d", "g"))
        r = self.controls.get(u, "r_vpp")
        weight = PEAK_FORCE_IN_WEIGHTS * m * g
        return [weight * (d + r), weight * (d - r)], []

    def rate_limited_bounds(self, stiffness: float, damping: float, params) -> dict[str, tuple[float, float]]:
        """|r_vpp| <= ``stiffness`` / (3 m g) - d [m] (an empty range, 0 to 0, when the
        offset d alone exceeds the stiffness allowed); ``damping`` does not limit the law.

        Parameters
        ----------
        stiffness, damping : float
            The largest hip stiffness [N m/rad] and damping [N m s/rad] allowed.
        params : Params
            The model parameters (m, d and g).
        """
        reach = max(stiffness / (PEAK_FORCE_IN_WEIGHTS * params.m * params.g) - params.d, 0.0)
        return {"r_vpp": (-reach, reach)}


#: The VPP torque is a spring-force fraction of the lever to the pivot: its stiffness is
#: estimated with the force bounded by this many body weights (running's peak, about 3)
#: and the lever by |r_vpp| + d. Only step sizes and the stability NLP's rate bound use it.
PEAK_FORCE_IN_WEIGHTS = 3.0


def _cross(a, b):
    """The planar cross product a_x b_y - a_y b_x, column by column (CasADi)."""
    return a[0, :] * b[1, :] - a[1, :] * b[0, :]


def leg_axes(theta1):
    """(e, n): the unit vector from the foot to the hip, and d e / d theta1 across it."""
    return ca.vertcat(-ca.sin(theta1), ca.cos(theta1)), ca.vertcat(-ca.cos(theta1), -ca.sin(theta1))


def virtual_pivot(q, r_vpp, p):
    """The pivot V = CoM + r_vpp (cos th_h, sin th_h) [m] relative to the foot, in stance."""
    th_h = STANCE.get(q, "theta1") + STANCE.get(q, "theta2") - math.pi / 2
    return stance_com_position(q, p) + ca.vertcat(r_vpp * ca.cos(th_h), r_vpp * ca.sin(th_h))


def ground_force(x, tau, p):
    """The ground's force on the runner [N] in stance: G = k (rho0 - rho) e - (tau / rho) n.

    The massless leg carries no net force or moment, so the virtual work of G at the hip
    and of tau on the trunk equals that of the model's generalised forces (the spring on
    rho, tau on theta2): G . e = k (rho0 - rho) and rho G . n + tau = 0.
    """
    along, across = leg_axes(STANCE.get(x, "theta1"))
    rho = STANCE.get(x, "rho")
    return PARAMS.get(p, "k") * (PARAMS.get(p, "rho0") - rho) * along - tau / rho * across


PD = PDLaw(
    name="pd",
    controls=Layout(("Kp", "Kd", "theta2_des", "theta2_dot_des", "theta_td")),
    units={"Kp": "N m/rad", "Kd": "N m s/rad", "theta2_des": "rad", "theta2_dot_des": "rad/s", "theta_td": "rad"},
    nominal={"Kp": 1.0, "Kd": 0.1, "theta2_des": 0.1, "theta2_dot_des": 1.0, "theta_td": 0.1},
    bounds={"Kp": (-1e3, 1e3), "Kd": (-1e2, 1e2), "theta2_des": (-2 * math.pi, 2 * math.pi),
            "theta2_dot_des": (-100.0, 100.0), "theta_td": (-1.5, 1.5)},
    defaults={"Kp": 0.0, "Kd": 0.0, "theta2_des": math.pi - 0.1, "theta2_dot_des": 0.0, "theta_td": 0.1},
    drawn=("Kp", "Kd"),
)
VPP = VPPLaw(
    name="vpp",
    controls=Layout(("r_vpp", "theta_td")),
    units={"r_vpp": "m", "theta_td": "rad"},
    nominal={"r_vpp": 0.01, "theta_td": 0.1},
    bounds={"r_vpp": (-10.0, 10.0), "theta_td": (-1.5, 1.5)},
    defaults={"r_vpp": 0.0, "theta_td": 0.1},
    drawn=("r_vpp",),
)
#: Every law by its name in problem files.
HIP_LAWS: dict[str, HipLaw] = {law.name: law for law in (PD, VPP)}

#: The PD law's control layout (the default law's), kept for code and users that read it.
CONTROL = PD.controls


@dataclass(frozen=True)
class Control:
    """Numeric PD control vector of one stride (units as in the module docstring).

    Attributes
    ----------
    Kp : float
        Proportional gain on the leg-trunk angle theta2 [N m/rad].
    Kd : float
        Derivative gain on its rate [N m s/rad].
    theta2_des : float
        Set point of theta2 [rad].
    theta2_dot_des : float
        Set point of theta2's rate [rad/s].
    theta_td : float
        Leg angle from the vertical held in flight, so at touchdown [rad].
    """

    Kp: float
    Kd: float
    theta2_des: float
    theta2_dot_des: float
    theta_td: float

    def vector(self) -> np.ndarray:
        """The controls as an array of shape (5,) in the PD law's order (Kp, Kd, theta2_des,
        theta2_dot_des, theta_td), SI units and radians."""
        return CONTROL.pack({n: getattr(self, n) for n in CONTROL.names})


def hip_law(name: str) -> HipLaw:
    """The law called ``name`` in problem files; raises KeyError naming the known ones.

    Parameters
    ----------
    name : str
        ``"pd"`` or ``"vpp"`` (the keys of :data:`HIP_LAWS`).
    """
    try:
        return HIP_LAWS[name]
    except KeyError:
        raise KeyError(f"hip_law {name!r} is not one of {sorted(HIP_LAWS)}") from None
