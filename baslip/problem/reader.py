"""Problem files: YAML validated into frozen dataclasses, with errors that name the key.

A problem file says *what* to solve::

    name: downward
    params: {m: 1.0, I: 0.0033, k: 1000, rho0: 0.2, d: 0.04, g: 9.81}
    hip_law: pd            # or vpp: the controls fix, guess and bounds may name
    fix: {ydot: 0.5, z: 0.4}
    guess: {theta_h: "-90 deg", Kp: 1.0, theta_td: "8 deg"}
    bounds: {theta_h: ["-120 deg", "-60 deg"]}
    objective: nearest_guess
    solver: {nodes: 20, substeps: 1, max_iter: 300, tol: 1.0e-10, print_level: 0}

Values are SI units and radians. Angles (``theta_h``, ``theta2_des``, ``theta_td``) may be
written ``"-90 deg"`` and rates (``theta_h_dot``, ``theta2_dot_des``) ``"30 deg/s"``.
Every problem in a file raises :class:`ProblemError` carrying the offending key.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

from baslip.errors import ProblemError, ProblemKindError
from baslip.model.dynamics import APEX, PARAMS, Params
from baslip.model.hiplaw import HIP_LAWS, PD, HipLaw
from baslip.model.quantities import (
    ANY_DESIGN,
    OBJECTIVES,
    POSTURES,
    STABILITY_OBJECTIVES,
    design_names,
    implied_periodicity,
    physical_range,
    quantity_names,
    quantity_text,
    start_value,
    value_text,
)
from baslip.model.virtual_constraint import VIRTUAL_CONSTRAINT
from baslip.problem.continuation import ContinuationSpec, check_continuation, parse_continuation
from baslip.problem.solver import SolverSettings, parse_solver
from baslip.problem.source import read_problem_file
from baslip.problem.study import ADAPTED_CONTROLS, Atlas, Basin, Families, Optimal, Study, Sweep, parse_study
from baslip.problem.text import check_plain_data, clip, excerpt
from baslip.problem.values import mapping, physical
from baslip.problem.values import number as _number

TOP_LEVEL_KEYS = ("name", "params", "hip_law", "fix", "guess", "bounds", "posture", "objective", "strides", "solver",
                  "study", "continuation")
#: What fix, guess and bounds may name under some hip law; :func:`_check_law` then holds
#: each problem to its own law's.
_ANY_QUANTITY = ANY_DESIGN + ("energy",)
#: The value of ``model`` that names the BA-SLIP itself (a problem without ``model`` is one too).
BA_SLIP_NAME = "ba-slip"
#: Longest orbit, in strides, that a problem may ask for.
MAX_STRIDES = 16
#: Most fixed points one sweep may ask for (a day of solving on two cores).
MAX_SWEEP_POINTS = 100_000
@dataclass(frozen=True)
class Problem:
    """A validated fixed-point problem (values in SI units and radians).

    Attributes
    ----------
    name : str
        The problem's name (up to 100 letters, digits, ``_``, ``-`` or ``.``).
    params : Params
        The model parameters.
    hip_law : HipLaw
        The stance hip law, whose controls ``fix``, ``guess`` and ``bounds`` name.
    fix : Mapping of str to float
        Fixed values of design quantities (apex state, controls) or of the apex ``energy``
        [J], SI units and radians.
    guess : Mapping of str to float
        Starting values of design quantities that are not fixed. With none at all, a
        problem's own gait starts from the body alone (:mod:`baslip.gait.anybody`).
    bounds : Mapping of str to tuple of float
        (lo, hi) bounds by quantity, infinite where a file gave null.
    posture : str
        The trunk at the apex: ``upright``, ``hanging`` or ``any`` (the default);
        ``upright`` and ``hanging`` bound theta_h unless ``bounds`` does.
    objective : str
        ``nearest_guess``, ``min_torque``, ``feasibility`` or ``least_spectral_radius``.
    strides : int
        The orbit's period in strides (1 to 16); ``fix`` and ``guess`` refer to its first apex.
    solver : SolverSettings
        Discretisation and IPOPT settings.
    study : Study or None
        Many solves or simulations instead of one fixed point (a sweep, a basin, ...).
    continuation : ContinuationSpec or None
        A branch to trace instead.
    """

    name: str
    params: Params = Params()
    hip_law: HipLaw = PD  # the stance hip law, whose controls fix, guess and bounds name
    fix: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    guess: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=lambda: MappingProxyType({}))
    posture: str = "any"  # the trunk at the apex: upright, hanging or any
    objective: str = "nearest_guess"
    strides: int = 1  # period of the orbit in strides; fix and guess refer to its first apex
    solver: SolverSettings = SolverSettings()
    study: Study | None = None  # many solves or simulations instead of one fixed point
    continuation: ContinuationSpec | None = None  # trace a branch instead

    @property
    def design(self) -> tuple[str, ...]:
        """The design quantities: the apex state, then the hip law's controls."""
        return design_names(self.hip_law)

    def full_guess(self) -> dict[str, float]:
        """Starting value of every design quantity that is not fixed."""
        return {n: self.start_value(n) for n in self.design if n not in self.fix}

    def start_value(self, name: str) -> float:
        """The fixed value of ``name`` if fixed, else its starting value (guessed, or the
        default for this body: :func:`baslip.model.quantities.default_guess`).

        Parameters
        ----------
        name : str
            A design quantity (``z``, ``theta_h``, ..., a control); the value is in its SI
            unit or radians.
        """
        return start_value(name, self.fix, self.guess, self.bounds, self.params)

    def __reduce__(self):
        # Workers get the problem itself, as data; mapping proxies do not pickle, so they
        # travel as dicts and are wrapped again on arrival.
        state = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return _unpickled_problem, ({k: dict(v) if k in _MAPPINGS else v for k, v in state.items()},)

    def replace(self, **changes: Any) -> Problem:
        """A new problem with ``changes`` to its top-level keys, checked like a problem file.

        Values are given as in a problem file (``fix={"z": 0.45}``, ``params={"k": 2000}``,
        ``study={...}``), or as the objects the problem holds (``params=Params(k=2000)``,
        ``study=Controllers(...)``, ``continuation=ContinuationSpec(...)``, ``fix=p.fix``,
        ``bounds=p.bounds`` with its open ends); an object is checked as its mapping form
        would be. Raises :class:`ProblemError` with the same one-line message a file
        would get.

        Parameters
        ----------
        **changes : Any
            New values by top-level key (``name``, ``params``, ``hip_law``, ``fix``,
            ``guess``, ``bounds``, ``objective``, ``strides``, ``solver``, ``study``,
            ``continuation``); each replaces that key's whole value.
        """
        return replace_problem(self, **changes)


#: The fields of a problem held as read-only mappings.
_MAPPINGS = ("fix", "guess", "bounds")


def _unpickled_problem(state: dict) -> Problem:
    fields: dict[str, Any] = {k: MappingProxyType(v) if k in _MAPPINGS else v for k, v in state.items()}
    return Problem(**fields)


def load_problem(path: str | Path) -> Problem:
    """Read and validate a YAML problem file of the BA-SLIP.

    Parameters
    ----------
    path
        The file; a bare name that is no file here (``downward``, ``downward.yaml``)
        means the shipped problem of that name (``baslip problems`` lists them).

    Raises
    ------
    ProblemError
        If anything is invalid; its ``key`` names the offending entry.
    ProblemKindError
        If the file names a described model of its own (``model: file.py:Name``), which
        :func:`baslip.problem.model_file.load_any_problem` reads.
    """
    data, name, _ = read_problem_file(path)
    if isinstance(data, Mapping) and "model" in data:
        if data["model"] != BA_SLIP_NAME:
            raise ProblemKindError("model", f"{excerpt(data['model'])} is a described model's problem: "
                                            "run it with `baslip solve` or baslip.run")
        data = {k: v for k, v in data.items() if k != "model"}
    return parse_problem(data, default_name=name)


def parse_problem(data: Any, default_name: str = "problem") -> Problem:
    """Validate a problem given as plain data (as read from YAML).

    ``params``, ``solver``, ``study`` and ``continuation`` may also be given as the
    objects a problem holds (:class:`Params`, :class:`SolverSettings`, a study,
    :class:`ContinuationSpec`); they are checked like their mappings.

    Parameters
    ----------
    data : Any
        A mapping of the problem file's top-level keys to their values (SI units and
        radians, or strings such as ``"-90 deg"``).
    default_name : str
        The name when ``data`` has no ``name``.

    Returns
    -------
    Problem
        The validated problem.

    Raises
    ------
    ProblemError
        If anything is invalid; its ``key`` names the offending entry.
    """
    check_plain_data(data)
    top = mapping(data, "", TOP_LEVEL_KEYS)
    fields: dict[str, Any] = {key: _FIELDS[key](top[key]) for key in TOP_LEVEL_KEYS if key in top}
    fields.setdefault("name", _name(default_name))
    return _checked(Problem(**fields))


def replace_problem(problem: Problem, **changes: Any) -> Problem:
    """``problem`` with ``changes`` (top-level keys, as in a problem file), validated by the
    same rules as a problem file. Raises :class:`ProblemError` naming the key."""
    for key in changes:
        if key not in TOP_LEVEL_KEYS:
            raise ProblemError(clip(str(key)), f"unknown key (expected one of {', '.join(TOP_LEVEL_KEYS)})")
    check_plain_data(changes)
    fields = {key: _FIELDS[key](value) for key, value in changes.items()}
    return _checked(dataclasses.replace(problem, **fields))


def check_problem(problem: Problem) -> Problem:
    """``problem`` checked whole, each top-level value as a problem file's would be: for a
    problem built in Python by ``Problem(...)``, which checks nothing itself. Raises
    :class:`ProblemError` naming the key; returns the problem as the reader makes it."""
    return replace_problem(problem, **{f.name: getattr(problem, f.name) for f in dataclasses.fields(problem)})


def _checked(problem: Problem) -> Problem:
    """``problem``, once the rules that tie its sections together hold."""
    if problem.study is not None and problem.continuation is not None:
        raise ProblemError("continuation", "a problem has either a study or a continuation, not both")
    if problem.study is not None and problem.strides != 1:
        raise ProblemError("strides", "studies solve one-stride gaits; remove strides or the study")
    if problem.objective in STABILITY_OBJECTIVES and (problem.strides != 1 or problem.continuation is not None):
        raise ProblemError("objective", f"{problem.objective} bounds the multipliers of one one-stride gait; it takes "
                           "neither strides nor a continuation")
    _check_law(problem)
    _check_ranges(problem)
    _check_consistency(problem)
    _check_sweep(problem)
    _check_atlas(problem)
    _check_basin(problem)
    _check_continuation(problem)
    return problem


def _name(value: Any) -> str:
    if not isinstance(value, str) or not re.fullmatch(r"[A-Za-z0-9_.-]{1,100}", value) or set(value) == {"."}:
        raise ProblemError("name", f"expected up to 100 letters, digits, '_', '-' or '.', got {excerpt(value)}")
    return value


def _hip_law(value: Any) -> HipLaw:
    if isinstance(value, HipLaw):
        return value
    if value == VIRTUAL_CONSTRAINT.name:
        raise ProblemError("hip_law", f"{value} is a law of the BA-SLIP's description, not of its compiled engine: "
                                      f"write model: ba-slip-described and law: {value}")
    if not isinstance(value, str) or value not in HIP_LAWS:
        raise ProblemError("hip_law", f"expected one of {', '.join(HIP_LAWS)}, got {excerpt(value)}")
    return HIP_LAWS[value]


def _check_law(problem: Problem) -> None:
    """fix, guess, bounds, a study's axes and plot, and a branch's plot name only
    quantities of the problem's hip law."""
    allowed = quantity_names(problem.hip_law) + PARAMS.names
    named = [(f"{section}.{name}", name) for section in _MAPPINGS for name in getattr(problem, section)]
    study = problem.study
    named += [(f"study.vary.{a.name}", a.name) for a in getattr(study, "axes", ())]
    named += [("study.plot", name) for name in getattr(study, "plot", ()) if isinstance(study, Atlas)]
    if problem.continuation is not None:
        named += [("continuation.plot", problem.continuation.plot)]
    for key, name in named:
        if name not in allowed:
            law = problem.hip_law
            accepted = f"it plots one of {', '.join(problem.design)}" if key == "continuation.plot" else \
                f"its controls are {', '.join(law.controls.names)}"
            raise ProblemError(key, f"{name} is not a quantity under hip_law {law.name} ({accepted})")
    _check_adapted_controls(problem)


def _check_adapted_controls(problem: Problem) -> None:
    """A controller that adapts named controls (``pivot``: r_vpp) needs a law that has them."""
    for name in getattr(problem.study, "controllers", ()):
        missing = [c for c in ADAPTED_CONTROLS.get(name, ()) if c not in problem.hip_law.controls.names]
        if missing:
            raise ProblemError("study.controllers", f"{name} adapts {', '.join(missing)}, which hip_law "
                               f"{problem.hip_law.name} does not have (its controls are "
                               f"{', '.join(problem.hip_law.controls.names)}); use hip_law vpp")


def _objective(value: Any) -> str:
    if not isinstance(value, str) or value not in OBJECTIVES:
        raise ProblemError("objective", f"expected one of {', '.join(OBJECTIVES)}, got {excerpt(value)}")
    return value


def _optional(parse: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """A section's parser that also takes None, for no section. The parser checks an object
    built in Python (a study, a continuation) as its mapping form, like a file's."""
    return lambda value: None if value is None else parse(value)


# --- pieces -------------------------------------------------------------------------------


def _params(value: Any) -> Params:
    raw = mapping(value, "params", PARAMS.names)
    return Params(**{name: physical(name, _number(v, f"params.{name}"), f"params.{name}") for name, v in raw.items()})


def _quantities(value: Any, key: str, allowed: tuple[str, ...]) -> dict[str, float]:
    # Their physical ranges depend on the body: :func:`_check_ranges` checks them.
    raw = mapping(value, key, allowed)
    return {name: _number(v, f"{key}.{name}") for name, v in raw.items()}


def _bounds(value: Any) -> dict[str, tuple[float, float]]:
    raw = mapping(value, "bounds", _ANY_QUANTITY)
    bounds = {}
    for name, pair in raw.items():
        key = f"bounds.{name}"
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise ProblemError(key, f"expected [lo, hi] (null for no bound), got {excerpt(pair)}")
        # A missing end is the physical limit; a written one must lie within the range
        # (the body's: :func:`_check_ranges`). The open ends a problem holds (-inf, inf)
        # mean the same, so that its own bounds can be given back.
        lo, hi = (_bound_end(end, key, open_end) for end, open_end in zip(pair, (-math.inf, math.inf)))
        if lo > hi:
            raise ProblemError(key, f"lower bound {lo:g} exceeds upper bound {hi:g}")
        bounds[name] = (lo, hi)
    return bounds


def _bound_end(value: Any, key: str, open_end: float) -> float:
    """One end of a bound: None, or the open end itself (-inf below, inf above), for none."""
    if value is None or (isinstance(value, float) and value == open_end):
        return open_end
    return _number(value, key)


def _posture(value: Any) -> str:
    if value not in POSTURES:
        raise ProblemError("posture", f"expected one of {', '.join(POSTURES)}, got {excerpt(value)}")
    return value


def _strides(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_STRIDES:
        raise ProblemError("strides", f"expected an integer in [1, {MAX_STRIDES}], got {excerpt(value)}")
    return value


def _study(value: Any) -> Study:
    return parse_study(value)


#: The parser of each top-level key's value.
_FIELDS: dict[str, Callable[[Any], Any]] = {
    "name": _name,
    "params": lambda v: _params(dataclasses.asdict(v) if isinstance(v, Params) else v),
    "hip_law": _hip_law,
    "fix": lambda v: MappingProxyType(_quantities(v, "fix", _ANY_QUANTITY)),
    "guess": lambda v: MappingProxyType(_quantities(v, "guess", ANY_DESIGN)),
    "bounds": lambda v: MappingProxyType(_bounds(v)),
    "posture": lambda v: _posture(v),
    "objective": _objective,
    "strides": lambda v: _strides(v),
    "solver": lambda v: parse_solver(dataclasses.asdict(v) if isinstance(v, SolverSettings) else v),
    "study": _optional(_study),
    "continuation": _optional(parse_continuation),
}


def _check_ranges(problem: Problem) -> None:
    """Every written value of fix and guess, and every written end of bounds, lies in its
    physical range for the problem's body."""
    for section in ("fix", "guess"):
        for name, value in getattr(problem, section).items():
            physical(name, value, f"{section}.{name}", problem.params)
    for name, ends in problem.bounds.items():
        for end in ends:
            if math.isfinite(end):
                physical(name, end, f"bounds.{name}", problem.params)


def _check_consistency(problem: Problem) -> None:
    for name, value in problem.fix.items():
        if name in problem.guess:
            raise ProblemError(f"guess.{name}", f"{name} is fixed at {value_text(name, value, 6)}; remove it from guess")
        lo, hi = problem.bounds.get(name, (-math.inf, math.inf))
        if not lo <= value <= hi:
            raise ProblemError(f"fix.{name}", _outside_bounds(name, value, lo, hi))
    for name, value in problem.guess.items():
        lo, hi = problem.bounds.get(name, (-math.inf, math.inf))
        if not lo <= value <= hi:
            raise ProblemError(f"guess.{name}", _outside_bounds(name, value, lo, hi))
    _check_energy(problem)
    _check_touchdown_angle(problem)
    _check_foot_clearance(problem)


def _outside_bounds(name: str, value: float, lo: float, hi: float) -> str:
    shown = [value_text(name, v, 6) for v in (value, lo, hi)]
    return f"{shown[0]} lies outside bounds.{name} = [{shown[1]}, {shown[2]}]"


def _swept(problem: Problem) -> tuple[str, ...]:
    """The quantities a study fixes at each of its points: their own value in the problem
    is never used, so it is not checked (each point is)."""
    return tuple(a.name for a in getattr(problem.study, "axes", ()))


def _source(problem: Problem, name: str) -> tuple[str, str]:
    """(key, how the value was given) of a design quantity's starting value, for messages:
    ``fix.z`` or ``guess.z`` as written, or ``guess.z`` and a note that it is the default."""
    if name in problem.fix:
        return f"fix.{name}", ""
    if name in problem.guess:
        return f"guess.{name}", ""
    clipped = f", clipped into bounds.{name}" if name in problem.bounds else ""
    return f"guess.{name}", f" (the default for this body{clipped}, not written in the file)"


def _check_touchdown_angle(problem: Problem) -> None:
    theta_td = problem.start_value("theta_td")
    if "theta_td" not in _swept(problem) and not abs(theta_td) < math.pi / 2:
        key, source = _source(problem, "theta_td")
        raise ProblemError(key, f"touchdown angle {value_text('theta_td', theta_td, 4)}{source} must lie within "
                           "(-90 deg, 90 deg)")


def _check_foot_clearance(problem: Problem) -> None:
    """The foot, with the leg at theta_td, lies above ground at the apex. Not checked where
    the angles are neither fixed nor guessed (a start from the body alone chooses them; its
    solve names the clearance if that is what stops it)."""
    if {"z", "theta_h", "theta_td"} & set(_swept(problem)):
        return
    if not problem.guess and not {"theta_h", "theta_td"} <= set(problem.fix):
        return
    z, theta_h, theta_td = (problem.start_value(n) for n in ("z", "theta_h", "theta_td"))
    p = problem.params
    least_z = p.d * math.sin(theta_h) + p.rho0 * math.cos(theta_td)
    if z >= least_z:
        return
    key, source = _source(problem, "z")
    remedy = f"; write {key} above {least_z:.4g} m" if source else ""
    angles = f"{quantity_text('theta_h', theta_h, 4)}, {quantity_text('theta_td', theta_td, 4)}"
    raise ProblemError(key, f"apex height {z:.4g} m{source} puts the foot below ground at apex (foot at "
                       f"{z - least_z:.4g} m with {angles}){remedy}")


def _check_energy(problem: Problem) -> None:
    """A fixed apex energy must be reachable: E = m g z + m ydot^2/2 + I theta_h_dot^2/2."""
    if "energy" not in problem.fix:
        return
    p, fix = problem.params, problem.fix
    energy = fix["energy"]

    def least(name: str) -> float:
        """Smallest value of name (if fixed, its value) allowed by the bounds, in its term."""
        if name in fix:
            return fix[name] if name == "z" else fix[name] ** 2
        physical_lo, physical_hi = physical_range(name, p)
        lo, hi = problem.bounds.get(name, (physical_lo, physical_hi))
        lo, hi = max(lo, physical_lo), min(hi, physical_hi)
        return lo if name == "z" else (0.0 if lo <= 0.0 <= hi else min(lo * lo, hi * hi))

    lowest = p.m * p.g * least("z") + 0.5 * p.m * least("ydot") + 0.5 * p.I * least("theta_h_dot")
    tolerance = 1e-9 * max(1.0, abs(energy))
    if energy < lowest - tolerance:
        raise ProblemError("fix.energy", f"{energy:g} J is below the least apex energy {lowest:.6g} J that the other values allow")
    if all(n in fix for n in ("z", "ydot", "theta_h_dot")) and energy > lowest + tolerance:
        raise ProblemError(
            "fix.energy",
            f"{energy:g} J contradicts fix.z, fix.ydot and fix.theta_h_dot, which make it {lowest:.12g} J",
        )


def check_point(problem: Problem, values: Mapping[str, float]) -> None:
    """Raise :class:`ProblemError` unless ``problem`` with ``values`` fixed on top of its own
    fixed values passes every check a written ``fix`` gets (physical range, the problem's
    bounds, touchdown angle, foot above ground at apex, reachable energy)."""
    for name, value in values.items():
        physical(name, value, f"fix.{name}", problem.params)
    guess = {n: v for n, v in problem.guess.items() if n not in values}
    variant = replace(problem, fix=MappingProxyType({**problem.fix, **values}), guess=MappingProxyType(guess),
                      study=None)
    _check_consistency(variant)


def _check_sweep(problem: Problem) -> None:
    """Every point of a sweep (or an optimal-gait search) must be a problem that would be
    accepted written out."""
    if not isinstance(problem.study, (Sweep, Optimal, Atlas)):
        return
    axes = problem.study.axes
    points = math.prod(len(a.values) for a in axes) * getattr(problem.study, "starts", 1)
    if points > MAX_SWEEP_POINTS:
        raise ProblemError("study.vary", f"{points} points is more than {MAX_SWEEP_POINTS}")
    for point in itertools.product(*(a.values for a in axes)):
        values = {a.name: v for a, v in zip(axes, point)}
        try:
            check_point(problem, values)
        except ProblemError as err:
            name = err.key.rsplit(".", 1)[-1]
            where = ", ".join(quantity_text(n, v, 6) for n, v in values.items())
            key = f"study.vary.{name}" if name in values else "study.vary"
            raise ProblemError(key, f"at {where}: {err.message}") from None


def _check_atlas(problem: Problem) -> None:
    """An atlas charts a manifold of dimension 1 to 3, and plots two of its free quantities."""
    study = problem.study
    if not isinstance(study, Atlas):
        return
    if isinstance(study, Families) and not any(n in problem.fix for n in problem.design):
        raise ProblemError("fix", "a families study answers at the problem's own cell: fix its speed and apex "
                           "height (fix: {ydot: ..., z: ...})")
    held = set(problem.fix) | {a.name for a in study.axes}
    free = [name for name in problem.design if name not in held]
    # Rows implied by structure (z's under a law of positions only) leave a dimension more.
    implied = implied_periodicity(problem.fix, problem.params, problem.hip_law)
    dimension = len(free) - (APEX.size - len(implied)) - ("energy" in held)
    if not 1 <= dimension <= 3:
        hint = "fix more quantities (theta2_dot_des, say)" if dimension > 3 else "fix fewer quantities"
        raise ProblemError("study", f"with {', '.join(sorted(held))} held, the fixed points form a set of dimension "
                           f"{dimension}; an atlas covers dimensions 1 to 3: {hint}")
    for name in study.plot:
        if name not in free:
            raise ProblemError("study.plot", f"{name} is held (fixed or swept); plot two of the free quantities: "
                               f"{', '.join(free)}")


def _check_basin(problem: Problem) -> None:
    """Basin start states lie in the physical ranges of ydot and z."""
    study = problem.study
    if not isinstance(study, Basin):
        return
    for axis in study.grid:
        for value in axis.values:
            physical(axis.name, value, f"study.grid.{axis.name}", problem.params)
    for key, (ydot, z) in (("study.stable_at", study.stable_at), ("study.unstable_at", study.unstable_at)):
        physical("ydot", ydot, f"{key}.ydot", problem.params)
        physical("z", z, f"{key}.z", problem.params)


def _check_continuation(problem: Problem) -> None:
    if problem.continuation is not None:
        check_continuation(problem.continuation, problem.fix, problem.params, problem.objective, problem.hip_law)
