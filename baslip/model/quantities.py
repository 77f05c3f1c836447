"""The quantities of a fixed-point problem: names, scales, physical bounds, defaults.

A small vocabulary shared by the problem schema and the NLP, so that neither has to
import the other.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HIP_LAWS, PD, HipLaw
from baslip.model.ranges import PARAM_RANGES, PARAM_UNITS  # noqa: F401  (PARAM_RANGES: re-exported)


def design_names(law: HipLaw = PD) -> tuple[str, ...]:
    """The design quantities under ``law``: the apex state, then the law's controls."""
    return APEX.names + law.controls.names


def design_values(X, u, law: HipLaw = PD) -> dict[str, float]:
    """The apex ``X`` and control ``u`` under ``law`` as floats by design quantity."""
    return dict(zip(design_names(law), map(float, [*X, *u])))


def quantity_names(law: HipLaw = PD) -> tuple[str, ...]:
    """Everything a problem under ``law`` can fix or bound: its design quantities and the
    apex energy [J]."""
    return design_names(law) + ("energy",)


#: Design quantities of the default (PD) law.
DESIGN = design_names(PD)
#: What a problem under the default (PD) law can fix or bound.
QUANTITIES = quantity_names(PD)
#: The design quantities of some law: what a problem file may name before its law is known.
ANY_DESIGN = tuple(dict.fromkeys(name for law in HIP_LAWS.values() for name in design_names(law)))


def _every_law(table: str) -> dict:
    """One table (``nominal``, ``bounds``, ...) over the controls of every law."""
    return {name: value for law in HIP_LAWS.values() for name, value in getattr(law, table).items()}


#: Scale of each design quantity for the ``nearest_guess`` distance and the polish step.
NOMINAL = {"z": 0.1, "theta_h": 0.1, "ydot": 0.1, "theta_h_dot": 1.0, **_every_law("nominal")}

#: Physical bounds of each design quantity; a problem's bounds must lie inside them.
DEFAULT_BOUNDS = {
    "z": (0.0, 10.0),
    "theta_h": (-2 * math.pi, 2 * math.pi),
    "ydot": (-20.0, 20.0),
    "theta_h_dot": (-100.0, 100.0),
    **_every_law("bounds"),
}

#: Physical range of the apex energy [J] (z, ydot and theta_h_dot within their bounds
#: and the parameters within theirs never give more).
ENERGY_RANGE = (0.0, 1e8)


#: SI unit of each quantity and parameter, for messages and axis labels.
UNITS = {
    "z": "m", "theta_h": "rad", "ydot": "m/s", "theta_h_dot": "rad/s", **_every_law("units"),
    "energy": "J", **PARAM_UNITS,
}


def quantity_text(name: str, value: float, digits: int = 7) -> str:
    """``name = value unit`` for people: angles (in radians in data and code) in degrees,
    the rest in their SI units."""
    return f"{name} = {value_text(name, value, digits)}"


def value_text(name: str, value: float, digits: int = 7) -> str:
    """``value unit`` of quantity ``name`` for people: an angle [rad] or a rate [rad/s]
    in deg or deg/s, the rest in its SI unit (``17 deg``, ``3 m/s``)."""
    unit = UNITS.get(name, "")
    if unit.startswith("rad"):
        return f"{math.degrees(value):.{digits}g} deg{unit[len('rad'):]}"
    return f"{value:.{digits}g}" + (f" {unit}" if unit else "")


#: The body whose defaults :data:`DEFAULT_GUESS` and :data:`DEFAULT_BOUNDS` hold: the
#: thesis's (m 1 kg, rho0 0.2 m, g 9.81 m/s^2, ...).
THESIS_BODY = Params()

#: Dimension of each SI unit as exponents of (mass, length, time); radians count as 1.
UNIT_DIMENSIONS = {
    "rad": (0, 0, 0), "m": (0, 1, 0), "m/s": (0, 1, -1), "rad/s": (0, 0, -1), "J": (1, 2, -2),
    "N m/rad": (1, 2, -2), "N m s/rad": (1, 2, -1),
}


def body_scale(name: str, params: Params) -> float:
    """Factor that carries a value of ``name`` from the thesis's body to ``params``'s body.

    The two bodies are compared by their dimensionless groups: a length scales by rho0, a
    time by sqrt(rho0/g) and a mass by m, so that a speed scales by sqrt(g rho0), a rate by
    sqrt(g/rho0), Kp by m g rho0 and Kd by m g rho0 sqrt(rho0/g). At the thesis's body
    every factor is exactly 1.

    Parameters
    ----------
    name : str
        A design quantity or ``energy`` (its unit in :data:`UNITS` gives its dimension).
    params : Params
        The body; its m [kg], rho0 [m] and g [m/s^2] set the scales.

    Returns
    -------
    float
        The dimensionless factor (1 for angles).
    """
    mass, length, time = UNIT_DIMENSIONS[UNITS[name]]
    length_ratio = params.rho0 / THESIS_BODY.rho0
    time_ratio = math.sqrt(length_ratio * THESIS_BODY.g / params.g)
    return (params.m / THESIS_BODY.m) ** mass * length_ratio**length * time_ratio**time


def nominal(name: str, params: Params = THESIS_BODY) -> float:
    """The nominal scale of design quantity ``name`` at the body ``params``: the thesis
    body's (:data:`NOMINAL`) carried to it (:func:`body_scale`), so that a search measured
    in these units is the same search at every size of a body (exactly NOMINAL at the
    thesis's body)."""
    return NOMINAL[name] * body_scale(name, params)


def physical_range(name: str, params: Params = THESIS_BODY) -> tuple[float, float]:
    """Documented range of a design quantity, ``energy`` or a model parameter.

    Parameters
    ----------
    name : str
        The quantity or parameter.
    params : Params
        The body: a design quantity's range is the thesis body's scaled to it
        (:func:`body_scale`); the energy's and the parameters' ranges are fixed.
    """
    if name in DEFAULT_BOUNDS:
        scale = body_scale(name, params)
        lo, hi = DEFAULT_BOUNDS[name]
        return lo * scale, hi * scale
    if name == "energy":
        return ENERGY_RANGE
    lo, hi, _ = PARAM_RANGES[name]
    return lo, hi


#: Starting values of design quantities that a problem neither fixes nor guesses, for the
#: thesis's body (:func:`default_guess` scales them to another; they are clipped into the
#: problem's bounds).
DEFAULT_GUESS = {"z": 0.4, "theta_h": math.pi / 2, "ydot": 0.5, "theta_h_dot": 0.0, **_every_law("defaults")}


#: What a problem may ask of the trunk at the apex: pointing up, hanging down, or either.
POSTURES = ("upright", "hanging", "any")
#: The trunk's apex angle theta_h [rad] that each posture allows: up or down, by at most
#: 80 deg from the vertical.
POSTURE_BOUNDS = {"upright": (math.radians(10), math.radians(170)), "hanging": (math.radians(-170), math.radians(-10))}


def posture_of(theta_h: float) -> str:
    """``upright`` if the trunk at apex angle ``theta_h`` [rad] points up, else ``hanging``."""
    return "upright" if math.sin(theta_h) > 0 else "hanging"


def default_guess(name: str, params: Params = THESIS_BODY) -> float:
    """Default starting value of design quantity ``name`` for the body ``params``: the
    thesis body's :data:`DEFAULT_GUESS` scaled by :func:`body_scale` (SI units, radians)."""
    return DEFAULT_GUESS[name] * body_scale(name, params)

#: Objectives and their weights (nearest-guess distance, integral of tau^2 dt):
#: ``nearest_guess``, ``min_torque`` (with a 1e-6 nearest-guess term to make the minimiser
#: unique) and ``feasibility`` (the constraints, with only that 1e-6 nearest-guess term:
#: with none at all IPOPT's answer followed round-off in its path, and a start changed
#: at 1e-14 moved it from Kp = 2.6 to Kp = 881 N m/rad). ``least_spectral_radius`` adds
#: the NLP's bound on the multipliers' moduli to that 1e-6 term (the stability NLP of
#: :mod:`baslip.gait.monodromy`).
OBJECTIVES = {
    "nearest_guess": (1.0, 0.0),
    "min_torque": (1e-6, 1.0),
    "feasibility": (1e-6, 0.0),
    "least_spectral_radius": (1e-6, 0.0),
}
#: The objectives that bound the multipliers inside the NLP.
STABILITY_OBJECTIVES = ("least_spectral_radius",)


def start_value(name: str, fixed, guess, bounds, params: Params) -> float:
    """Value a design quantity starts from: fixed, else guessed, else its default for the
    body ``params`` (:func:`default_guess`) clipped into the problem's bounds."""
    if name in fixed:
        return fixed[name]
    if name in guess:
        return guess[name]
    lo, hi = bounds.get(name, (-math.inf, math.inf))
    return min(max(default_guess(name, params), lo), hi)


def implied_periodicity(fixed: Mapping[str, float], params: Params, law: HipLaw = PD) -> tuple[str, ...]:
    """Apex coordinates whose periodicity follows from the others by structure.

    Without hip torque (under PD, Kp = Kd = 0 fixed) energy is conserved, so a periodic
    ydot and theta_h_dot make z periodic. With d = 0 as well, the trunk spins freely:
    theta_h_dot is always periodic, and theta_h is too when theta_h_dot is fixed at zero.

    Under a law of positions only (VPP) the gaits are symmetric under mirror and time
    reversal (theta_h = +-90 deg at the apex), and at a symmetric gait one periodicity
    row follows from the others: [dr/dX - I, dr/du] has a left null vector, 0.9987 on z's
    row and 0.051 on ydot's at the thesis-scale gait (z = 0.4 m, ydot = 0.5 m/s, r_vpp =
    0.02 m). So z's row is the one left out. With r_vpp = 0 the force points at the CoM
    and the trunk spins freely, as with d = 0 and no torque.
    """
    if not (law.positional or law.torque_free(fixed)):
        return ()
    implied = ["z"]
    if law.spin_free(fixed, params):
        implied.append("theta_h_dot")
        if fixed.get("theta_h_dot") == 0.0:
            implied.append("theta_h")
    return tuple(implied)
