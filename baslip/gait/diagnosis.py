"""Why a solve failed, and which limits a gait sits on, in words a user can act on.

At IPOPT's last iterate (:meth:`baslip.gait.shooting.ShootingNLP.rows_at`) a limit
*binds* when an inequality row or a variable's bound is met to within
:data:`ACTIVE_TOLERANCE` of its scale (when none does, those within
:data:`NEAR_TOLERANCE` are *near*), and a row is *violated* when it misses its limit by
more; each named limit with its value becomes a :class:`Limit`, and the limits that have a
known remedy become suggestions (what to change, in degrees for angles). A verified gait's
design quantities on their bounds are listed the same way (:func:`limits_on_bounds`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from baslip.gait.shooting import FixedPointSpec, NlpSolution, ShootingNLP
from baslip.gait.shot_stride import CLEARANCES, FOOT_AT_APEX, LIFTOFF_RISE, RowLabel, RowValues
from baslip.model.dynamics import Params
from baslip.model.quantities import NOMINAL, UNITS

#: A limit binds when its slack is below this fraction of its scale (lengths by rho0,
#: speeds by sqrt(g rho0), times by sqrt(rho0 / g), ...). IPOPT's interior point stops a
#: few 1e-6 m inside a binding foot clearance at human scale (rho0 = 1 m).
ACTIVE_TOLERANCE = 1e-4
#: When nothing binds (IPOPT stopped at its iteration limit, say), the limits met to
#: within this fraction of their scale are named as near: 1 mm of foot clearance at
#: human scale.
NEAR_TOLERANCE = 1e-3
#: A design quantity is on its bound when within this fraction of the bound's scale (the
#: larger of |bound| and the quantity's nominal scale); the polish keeps a bound it meets
#: exactly, so this only absorbs round-off.
ON_BOUND_TOLERANCE = 1e-6
#: At most this many violated rows are named, the worst first.
VIOLATED_SHOWN = 3


@dataclass(frozen=True)
class Limit:
    """A named quantity at (or past) its limit.

    Attributes
    ----------
    name : str
        The quantity or constraint row (``foot clearance at apex``, ``Kp``, ...).
    value : float
        Its value, in SI units and radians.
    bound : float
        The limit it meets or misses, same units.
    unit : str
        The SI unit (``rad`` and ``rad/s`` are shown in degrees).
    """

    name: str
    value: float
    bound: float
    unit: str

    def text(self) -> str:
        """``name = value unit (limit bound)`` for people, angles in degrees."""
        return f"{self.name} = {_shown(self.value, self.unit)} (limit {_shown(self.bound, self.unit)})"

    def to_json_dict(self) -> dict:
        """``{name, value, bound, unit}`` in SI units and radians."""
        return {"name": self.name, "value": float(self.value), "bound": float(self.bound), "unit": self.unit}


@dataclass(frozen=True)
class Diagnosis:
    """Why a solve failed: the limits that bind at IPOPT's last iterate, the rows it
    left violated (worst first) and what to change.

    Attributes
    ----------
    binding : tuple of Limit
        Inequality rows and variable bounds met at the last iterate.
    near : tuple of Limit
        When none binds, those within :data:`NEAR_TOLERANCE` of their limit.
    violated : tuple of Limit
        The rows missed by the most (scaled), at most :data:`VIOLATED_SHOWN`.
    suggestions : tuple of str
        What to change, in the problem file's terms (degrees for angles).
    """

    binding: tuple[Limit, ...]
    near: tuple[Limit, ...]
    violated: tuple[Limit, ...]
    suggestions: tuple[str, ...]

    def lines(self) -> list[str]:
        """The summary's lines: binding limits, violated rows, suggestions."""
        lines = []
        if self.binding:
            lines.append("  binding  " + "; ".join(limit.text() for limit in self.binding))
        if self.near:
            lines.append("  near     " + "; ".join(limit.text() for limit in self.near))
        if self.violated:
            lines.append("  violated " + "; ".join(limit.text() for limit in self.violated))
        lines += [f"  suggest  {text}" for text in self.suggestions]
        return lines

    def to_json_dict(self) -> dict:
        """result.json's ``diagnosis``: ``binding``, ``near`` and ``violated`` lists of
        ``{name, value, bound, unit}`` (SI units and radians) and ``suggestions``."""
        return {"binding": [limit.to_json_dict() for limit in self.binding],
                "near": [limit.to_json_dict() for limit in self.near],
                "violated": [limit.to_json_dict() for limit in self.violated],
                "suggestions": list(self.suggestions)}


def diagnose(rows: RowValues, spec: FixedPointSpec) -> Diagnosis:
    """The limits binding and the rows violated at ``rows`` (an NLP point of ``spec``),
    with suggestions."""
    scale = _Scales(spec.params)
    binding = _limits_within(rows, scale, ACTIVE_TOLERANCE)
    near = [] if binding else _limits_within(rows, scale, NEAR_TOLERANCE)
    violated = _violated_rows(rows, scale)
    design = dict(zip(spec.design, rows.w[: len(spec.design)]))
    limits = binding or near
    at_apex = any(limit.name.endswith(FOOT_AT_APEX) for limit in limits)
    # A foot on the ground at apex stays there through a descent that then vanishes: one remedy.
    explained = [limit for limit in limits if not (at_apex and _within_descent(limit.name))]
    suggestions = tuple(dict.fromkeys(s for limit in explained for s in _suggestions(limit, spec, design)))
    if not suggestions and violated:
        suggestions = (f"no limit binds and {violated[0].name} stays off: start from a guess nearer a gait "
                       "(docs/guides/guesses.md) or change the fixed values",)
    return Diagnosis(tuple(binding), tuple(near), tuple(violated), suggestions)


def diagnose_nlp(nlp: ShootingNLP | None, spec: FixedPointSpec, solution: NlpSolution) -> Diagnosis | None:
    """:func:`diagnose` at the last iterate of ``nlp`` in ``solution``; None without one
    (IPOPT did not run, or the point belongs to another NLP)."""
    if nlp is None or solution.w is None or len(solution.w) != nlp.variable_count:
        return None
    return diagnose(nlp.rows_at(spec, solution.w), spec)


def limits_on_bounds(spec: FixedPointSpec, X: np.ndarray, u: np.ndarray) -> tuple[Limit, ...]:
    """The free design quantities of a point that sit on one of their bounds (the
    problem's or the physical ones), to within :data:`ON_BOUND_TOLERANCE` of the bound's scale."""
    on = []
    for name, value in zip(spec.design, np.concatenate([X, u])):
        if name in spec.fixed:
            continue
        for bound in spec.bounds_of(name):
            if abs(value - bound) <= ON_BOUND_TOLERANCE * max(abs(bound), NOMINAL[name]):
                on.append(Limit(name, float(value), float(bound), UNITS[name]))
    return tuple(on)


# -- finding the limits -----------------------------------------------------------------


@dataclass(frozen=True)
class _Scales:
    """The scale of each unit for a body: lengths by rho0, times by sqrt(rho0 / g), masses by m."""

    params: Params

    def of(self, unit: str) -> float:
        p = self.params
        length, time = p.rho0, math.sqrt(p.rho0 / p.g)
        return {"m": length, "m/s": length / time, "m/s^2": p.g, "s": time, "J": p.m * p.g * length}.get(unit, 1.0)


def _limits_within(rows: RowValues, scale: _Scales, tolerance: float) -> list[Limit]:
    """The inequality rows and variable bounds met to within ``tolerance`` of their scale."""
    return [*_binding_rows(rows.rows, rows.g, rows.lbg, rows.ubg, scale, tolerance),
            *_binding_rows(rows.variables, rows.w, rows.lbx, rows.ubx, scale, tolerance)]


def _binding_rows(labels: Iterable[RowLabel], values, lower, upper, scale: _Scales, tolerance: float) -> list[Limit]:
    """The named rows whose value meets a finite limit to within ``tolerance`` of its
    scale; equal limits (an equality row, a fixed variable) are always met or violated,
    never binding."""
    found = []
    for label, value, lo, hi in zip(labels, values, lower, upper):
        if not label.name or lo == hi:
            continue
        for bound in (lo, hi):
            # A design quantity's scale is its bound's size or its nominal scale; a row's, its unit's.
            size = max(abs(bound), NOMINAL[label.name]) if label.name in NOMINAL else scale.of(label.unit)
            if math.isfinite(bound) and abs(value - bound) <= tolerance * size:
                found.append(Limit(label.name, float(value), float(bound), label.unit))
    return found


def _violated_rows(rows: RowValues, scale: _Scales) -> list[Limit]:
    """The constraint rows missed by more than their tolerance, the worst (scaled) first."""
    missed = []
    for label, value, lo, hi in zip(rows.rows, rows.g, rows.lbg, rows.ubg):
        bound = lo if value < lo else hi if value > hi else None
        if bound is None:
            continue
        size = abs(value - bound) / scale.of(label.unit)
        if size > ACTIVE_TOLERANCE:
            missed.append((size, Limit(label.name, float(value), float(bound), label.unit)))
    missed.sort(key=lambda pair: -pair[0])
    return [limit for _, limit in missed[:VIOLATED_SHOWN]]


# -- what to change -----------------------------------------------------------------------


def _suggestions(limit: Limit, spec: FixedPointSpec, design: dict[str, float]) -> list[str]:
    """What would move ``limit`` off its bound, in the problem file's terms."""
    name = limit.name.split(": ")[-1]  # an orbit's rows name their stride first
    if name == FOOT_AT_APEX:
        return [_foot_at_apex(spec, design)]
    if name.startswith("foot clearance"):
        return ["the foot reaches the ground before its touchdown: raise z or theta_td"]
    if name.endswith(" duration") or " duration of stride" in name:
        phase = name.split(" duration")[0]
        return [f"the {phase} phase vanishes ({_shown(limit.value, 's')}): the gait is about to lose it; "
                "change the fixed values (z or ydot) away from here"]
    if name == LIFTOFF_RISE:
        return ["the runner barely leaves the ground after liftoff: raise z or ydot"]
    if any(name.startswith(what) for what in CLEARANCES[:2]):
        return [f"the {name.split(' at ')[0]} reaches the ground in stance: raise z or the leg stiffness k"]
    if name == "apex energy":
        return [f"the apex energy is on its bound {_shown(limit.bound, 'J')}: widen bounds.energy"]
    if name in spec.design:
        lo, hi = spec.bounds_of(name)
        return [f"{name} is on its bound {_shown(limit.bound, limit.unit)}: widen bounds.{name} "
                f"(now [{_shown(lo, limit.unit)}, {_shown(hi, limit.unit)}]) if the physics allows"]
    return []


def _within_descent(name: str) -> bool:
    """Whether a row is the foot's clearance inside the descent or the descent's duration."""
    return "of the descent" in name or "descent duration" in name


def _foot_at_apex(spec: FixedPointSpec, design: dict[str, float]) -> str:
    """The remedy of a foot that only just clears the ground at apex: the foot clears when
    z > d sin(theta_h) + rho0 cos(theta_td)."""
    p, z, theta_h, theta_td = spec.params, design["z"], design["theta_h"], design["theta_td"]
    hip_drop = p.d * math.sin(theta_h)
    cosine = (z - hip_drop) / p.rho0
    least = math.degrees(math.acos(min(1.0, max(-1.0, cosine))))
    flatter = math.radians(max(least - 1.0, 0.0))
    needed = hip_drop + p.rho0 * math.cos(flatter)
    text = (f"the foot only just clears the ground at apex (it clears when z > d sin(theta_h) + rho0 cos(theta_td)); "
            f"at z = {z:.4g} m and theta_h = {math.degrees(theta_h):.4g} deg that keeps theta_td above "
            f"{least:.2f} deg (it is {math.degrees(theta_td):.4f} deg)")
    if "z" in spec.fixed or "theta_td" not in spec.fixed:
        text += (f", and the gait wants a flatter leg: raise z (z > {needed:.4g} m lets theta_td go to "
                 f"{math.degrees(flatter):.2f} deg)")
    if "theta_td" in spec.fixed:
        text += f"; or raise fix.theta_td above {least:.2f} deg"
    return text


def _shown(value: float, unit: str) -> str:
    """A value for people: angles in degrees, the rest in their SI unit."""
    if unit.startswith("rad"):
        return f"{math.degrees(value):.6g} deg{unit[len('rad'):]}"
    if not unit:
        return f"{value:.4g}"
    return f"{value:.4g} {unit}"
