"""Verified fixed points of a described model's return map, and their multipliers.

The solve has four steps, each read from the description alone:

1. **A stride from the guess** (:class:`baslip.engine.hybrid.HybridMap`) gives each mode's
   duration and states, the NLP's start. A stride that cannot end (a guard that never
   fires, a fall) is reported, naming the part.
2. **The multiple-shooting NLP** (:mod:`baslip.gait.modelshooting`, IPOPT): per mode,
   node states and a duration, the guards, resets and falls, and the section coordinates
   back where they started. The objective stays nearest the guess.
3. **Newton on the return map** at the calibrated resolution (least-norm steps where more
   quantities are free than the map has coordinates), with its exact Jacobian.
4. **Independent verification** by CVODES (:mod:`baslip.engine.hybrid_check`): the point
   is reported only if that map fixes it to the spec's tolerance. The multipliers are the
   eigenvalues of the map's Jacobian in the section coordinates; one per invariant of the
   law (energy, for a passive law) and one per family it declares (the time-symmetric
   gaits of a law of positions only) is 1 by structure and marked trivial.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from baslip.engine.hybrid import HybridMap, Outcome, Resolution, calibrated_resolution
from baslip.engine.hybrid_check import IndependentStride
from baslip.errors import RunError
from baslip.gait.modelshooting import ModelShootingNLP, NoShootingSolution
from baslip.model.description import ModelError
from baslip.model.symbolic import ModelFunctions, model_functions
from baslip.problem.modelspec import ModelSpec

#: Newton iterations on the return map, at most.
NEWTON_STEPS = 30
#: Newton's steps ignore directions whose singular value is below this share of the
#: largest: a family's, along which a step through rounding would leap off the gaits.
SINGULAR = 1e-10
#: The status of a solve whose guess was a gait already, so that no NLP ran.
GUESS_IS_A_GAIT = "guess_is_a_gait"


class NoFixedPoint(RunError):
    """The solve did not find a verified fixed point; the message says where it stopped."""


def _shot(nlp: ModelShootingNLP, values: dict, first: Outcome) -> tuple[dict, str]:
    try:
        return nlp.solve(values, first)
    except NoShootingSolution as err:
        raise NoFixedPoint(str(err)) from None


@dataclass(frozen=True)
class ModelGait:
    """A verified fixed point of a described model.

    Attributes
    ----------
    spec : ModelSpec
        The problem.
    values : dict
        Every quantity's value at the gait (SI units, radians).
    section : ndarray
        The section coordinates of the gait.
    multipliers : ndarray
        Eigenvalues of d(map)/d(section coordinates).
    trivial : tuple of bool
        Which multipliers are 1 by structure (an invariant of the law, or a family's).
    residual : float
        max |map(x) - x| of the engine's map, relative to max(1, |x|).
    verification : float
        The same of the independent CVODES map.
    durations : tuple of float
        Each mode's duration [s], in stride order.
    resolution : Resolution
        The engine's resolution: its scout's step [s] and steps per mode.
    time_s : float
        Wall time of the solve [s].
    ipopt_status : str
        How the NLP ended.
    """

    spec: ModelSpec
    values: dict
    section: np.ndarray
    multipliers: np.ndarray
    trivial: tuple[bool, ...]
    residual: float
    verification: float
    durations: tuple[float, ...]
    resolution: Resolution
    time_s: float
    ipopt_status: str

    @property
    def spectral_radius(self) -> float:
        """The largest |multiplier| that is not 1 by structure."""
        return spectral_radius(self.multipliers, self.trivial)

    @property
    def stable(self) -> bool:
        """Whether every multiplier that is not 1 by structure lies inside the unit circle."""
        return self.spectral_radius < 1.0

    def to_dict(self) -> dict:
        """Plain JSON types: the model, law, values, multipliers and checks."""
        return {
            "model": self.spec.model.name, "law": self.spec.model.law(self.spec.law).name,
            "values": dict(self.values), "free": list(self.spec.free),
            "multipliers": [{"re": float(m.real), "im": float(m.imag), "modulus": float(abs(m)), "trivial": t}
                            for m, t in zip(self.multipliers, self.trivial)],
            "spectral_radius": self.spectral_radius, "stable": self.stable,
            "residual": self.residual, "verification": self.verification,
            "durations_s": list(self.durations), "resolution": self.resolution.to_dict(), "time_s": self.time_s,
            "ipopt_status": self.ipopt_status,
        }


class ModelSolver:
    """Fixed points of one described model under one law (functions built once).

    Parameters
    ----------
    spec : ModelSpec
        Any spec of the model and law; its model and law fix what is built.
    """

    def __init__(self, spec: ModelSpec):
        self.functions: ModelFunctions = model_functions(spec.model, spec.law)
        self.map = HybridMap(self.functions)
        self.check = IndependentStride(self.functions)
        self.invariants = _invariant_sensitivities(self.functions)

    # -- the quantities as vectors ------------------------------------------------------
    def split(self, spec: ModelSpec, values: dict) -> tuple[np.ndarray, np.ndarray]:
        """The section coordinates and theta (parameters, then controls) of ``values``.

        Parameters
        ----------
        spec : ModelSpec
            The problem (its model and law are the solver's).
        values : dict
            Every quantity's value by name.
        """
        section = np.array([values[c] for c in spec.model.section.coordinates])
        return section, self.functions.theta(values)

    def stride(self, spec: ModelSpec, values: dict, resolution: Resolution, jacobian: bool = False) -> Outcome:
        """One stride from ``values``.

        Parameters
        ----------
        spec : ModelSpec
            The problem (its model and law are the solver's).
        values : dict
            Every quantity's value by name.
        resolution : Resolution
            The engine's scout step and steps per mode.
        jacobian : bool
            Whether to carry the Jacobians.
        """
        section, theta = self.split(spec, values)
        return self.map.stride(section, theta, resolution, jacobian=jacobian)

    def residual(self, spec: ModelSpec, values: dict, resolution: Resolution, jacobian: bool = False):
        """map(x) - x in the section coordinates, then each fixed invariant's difference
        from its value (relative to it), and, if asked, the Jacobian in the free
        quantities; or the reason the stride failed.

        Parameters
        ----------
        spec : ModelSpec
            The problem (its model and law are the solver's).
        values : dict
            Every quantity's value by name.
        resolution : Resolution
            The engine's scout step and steps per mode.
        jacobian : bool
            Whether to give the Jacobian too (else None in its place).
        """
        outcome = self.stride(spec, values, resolution, jacobian)
        if not outcome.ok:
            return outcome.failure
        section, theta = self.split(spec, values)
        rows = self._fixed_invariants(spec)
        held = ([np.array(v) for v in self.invariants(section, theta)] if rows and self.invariants is not None else
                [np.zeros((0, 1)), np.zeros((0, len(section))), np.zeros((0, len(theta)))])
        targets = np.array(list(spec.fixed_invariants.values()))
        # An invariant's row is relative to its value (an energy of 1e4 J is not 1e4 m).
        weights = 1.0 / np.maximum(np.abs(targets), 1.0)
        r = np.concatenate([outcome.end() - section, (held[0].ravel()[rows] - targets) * weights])
        if not jacobian:
            return r, None
        coordinates = spec.model.section.coordinates
        of_section, of_theta = outcome.jacobians()
        by_section = np.vstack([of_section - np.eye(len(coordinates)), held[1][rows] * weights[:, None]])
        by_theta = np.vstack([of_theta, held[2][rows] * weights[:, None]])
        columns = [by_section[:, coordinates.index(name)] if name in coordinates
                   else by_theta[:, self.functions.theta_names.index(name)] for name in spec.free]
        return r, np.column_stack(columns) if columns else np.zeros((len(r), 0))

    def equations(self, spec: ModelSpec, values: dict, resolution: Resolution, jacobian: bool = False,
                  kept: list[int] | None = None):
        """The independent equations of a fixed point: the section coordinates' returns
        that ``kept`` names (by default :meth:`kept_rows` at ``values``; a family passes
        its own, chosen once, so that its equations do not change along it) and the fixed
        invariants, with the Jacobian in the free quantities if asked; or the reason the
        stride failed.

        Parameters
        ----------
        spec : ModelSpec
            The problem (its model and law are the solver's).
        values : dict
            Every quantity's value by name.
        resolution : Resolution
            The engine's scout step and steps per mode.
        jacobian : bool
            Whether to give the Jacobian too.
        kept : list of int, optional
            The section coordinates whose returns are asked for.
        """
        result = self.residual(spec, values, resolution, jacobian)
        if isinstance(result, str):
            return result
        kept = self.kept_rows(spec, values) if kept is None else kept
        rows = kept + list(range(len(spec.model.section.coordinates), len(result[0])))
        return result[0][rows], None if result[1] is None else result[1][rows]

    def kept_rows(self, spec: ModelSpec, values: dict) -> list[int]:
        """The section coordinates whose return is asked for: all but one for each
        invariant of the law, which returns them by itself (asking as well would leave
        the equations dependent). The one left out is the invariant's steepest, scaled.

        Parameters
        ----------
        spec : ModelSpec
            The problem (its model and law are the solver's).
        values : dict
            Every quantity's value by name.
        """
        coordinates = spec.model.section.coordinates
        kept = list(range(len(coordinates)))
        if self.invariants is None:
            return kept
        section, theta = self.split(spec, values)
        gradient = np.array(self.invariants(section, theta)[1]) * np.maximum(np.abs(section), 1.0)
        for row in gradient:
            steepest = max(kept, key=lambda i: abs(row[i]))
            kept.remove(steepest)
        return kept

    def reduced_jacobian(self, spec: ModelSpec, values: dict, jacobian: np.ndarray, kept: list[int]) -> np.ndarray:
        """The map's Jacobian on its dynamic coordinates: the section coordinates ``kept``,
        the others solved from the law's invariants (the map restricted to their level
        set, whose structural multipliers 1 are gone).

        Parameters
        ----------
        spec : ModelSpec
            The problem.
        values : dict
            Every quantity's value by name.
        jacobian : ndarray
            d(map)/d(section coordinates) there.
        kept : list of int
            The dynamic coordinates (:meth:`kept_rows`).
        """
        if self.invariants is None:
            return jacobian
        section, theta = self.split(spec, values)
        gradient = np.array(self.invariants(section, theta)[1])
        dropped = [i for i in range(len(section)) if i not in kept]
        # On the level set E(x_k, x_d) = const: dx_d/dx_k = -E_d^-1 E_k.
        solved = -np.linalg.solve(gradient[:, dropped], gradient[:, kept])
        return jacobian[np.ix_(kept, kept)] + jacobian[np.ix_(kept, dropped)] @ solved

    def multipliers(self, spec: ModelSpec, values: dict,
                    resolution: Resolution) -> tuple[np.ndarray, tuple[bool, ...]] | str:
        """The multipliers at ``values`` and which are 1 by structure, or why the stride failed.

        Parameters
        ----------
        spec : ModelSpec
            The problem (its model and law are the solver's).
        values : dict
            Every quantity's value by name.
        resolution : Resolution
            The engine's scout step and steps per mode.
        """
        outcome = self.stride(spec, values, resolution, jacobian=True)
        if not outcome.ok:
            return outcome.failure
        multipliers = np.linalg.eigvals(outcome.jacobians()[0])
        return multipliers, trivial_flags(multipliers, self._structural_count())

    def verify(self, spec: ModelSpec, values: dict, resolution: Resolution) -> float | str:
        """max |map(x) - x| of the independent CVODES stride, relative to max(1, |x|),
        or why that stride failed.

        Parameters
        ----------
        spec : ModelSpec
            The problem (its model and law are the solver's).
        values : dict
            Every quantity's value by name.
        resolution : Resolution
            The engine's scout step and steps per mode.
        """
        section, theta = self.split(spec, values)
        independent = self.check.stride(section, theta, resolution.scout)
        if isinstance(independent, str):
            return independent
        return float(np.max(np.abs(independent - section))) / max(1.0, float(np.max(np.abs(section))))

    def _fixed_invariants(self, spec: ModelSpec) -> list[int]:
        """Rows of the invariants Function that the spec fixes."""
        names = [i.name for i in spec.model.invariants_of(spec.law)]
        return [names.index(name) for name in spec.fixed_invariants]

    # -- the solve -----------------------------------------------------------------------
    def solve(self, spec: ModelSpec) -> ModelGait:
        """The verified fixed point nearest ``spec``'s guess (see the module's docstring).

        Parameters
        ----------
        spec : ModelSpec
            The problem: what is fixed, what is free, and the guess.

        Raises
        ------
        ModelError
            The stride from the guess cannot end because a guard never fires.
        NoFixedPoint
            The NLP, Newton or the verification did not give a verified point.
        """
        start = time.perf_counter()
        values = spec.values()
        resolution = self.calibrated(spec, values)
        first = self.map.stride(*self.split(spec, values), resolution, nodes=True)
        if not first.ok:
            self._refuse_start(first.failure)
        if self._is_gait(spec, values, resolution):
            # A guess that is a gait already (a committed one, say) goes straight to
            # Newton: the NLP could only move it, and where the gaits form a family at
            # fixed controls its Jacobian is singular and IPOPT can wander off.
            status = GUESS_IS_A_GAIT
        else:
            values, status = self._shooting(spec, values, first)
        values = self.polish(spec, values, resolution)
        outside = [n for n in spec.free if not spec.range_of(n)[0] <= values[n] <= spec.range_of(n)[1]]
        if outside:
            raise NoFixedPoint(f"Newton on the map left the bounds of {outside[0]} ({values[outside[0]]:g})")
        return self._verified(spec, values, resolution, status, time.perf_counter() - start)

    def _is_gait(self, spec: ModelSpec, values: dict, resolution: Resolution) -> bool:
        """Whether the equations hold at ``values`` to the spec's tolerance."""
        result = self.equations(spec, values, resolution)
        if isinstance(result, str):
            return False
        scale = max(1.0, float(np.max(np.abs(self.split(spec, values)[0]))))
        return float(np.max(np.abs(result[0]))) <= spec.tolerance * scale

    def calibrated(self, spec: ModelSpec, values: dict) -> Resolution:
        """The resolution at which a stride from ``values`` holds the spec's tolerance
        (:func:`baslip.engine.hybrid.calibrated_resolution`), its first scout a sixteenth
        of the body's time scale.

        Parameters
        ----------
        spec : ModelSpec
            The problem.
        values : dict
            Every quantity's value by name.
        """
        first = spec.model.time_scale(values) / 16
        return calibrated_resolution(self.map, *self.split(spec, values), spec.tolerance, first=first)

    def _refuse_start(self, failure: str) -> None:
        if "never fired" in failure:
            event = failure.split("guard of ", 1)[1].split(" never", 1)[0]
            key = "model.section.guard" if event == "section" else f"model.transitions.{event}.guard"
            raise ModelError(key, f"never fires on the stride from the guess ({failure})")
        raise NoFixedPoint(f"the stride from the guess fails: {failure}")

    def _shooting(self, spec: ModelSpec, values: dict, first: Outcome) -> tuple[dict, str]:
        return _shot(ModelShootingNLP(self.functions, spec, self.kept_rows(spec, values)), values, first)

    def polish(self, spec: ModelSpec, values: dict, resolution: Resolution) -> dict:
        """Every quantity's value after Newton (least-norm) steps on the independent
        equations (:meth:`equations`), until |r| is a hundredth of the tolerance or stalls
        below it (the map's own rounding): of a family, the gait nearest ``values``.

        The return an invariant implies is left out: kept, its row would make the
        Jacobian singular but for rounding, and a least-norm step through that rounding
        is a leap off the gaits (of a family, where the system is not square).

        Parameters
        ----------
        spec : ModelSpec
            The problem: what is fixed and what is free.
        values : dict
            Every quantity's value by name, near a gait.
        resolution : Resolution
            The engine's scout step and steps per mode.

        Raises
        ------
        NoFixedPoint
            A stride failed, or the steps did not converge.
        """
        values, previous = dict(values), np.inf
        kept = self.kept_rows(spec, values)
        for _ in range(NEWTON_STEPS):
            result = self.equations(spec, values, resolution, jacobian=True, kept=kept)
            if isinstance(result, str):
                raise NoFixedPoint(f"Newton left the gaits: {result}")
            r, jac = result
            scale = max(1.0, float(np.max(np.abs(self.split(spec, values)[0]))))
            size = float(np.max(np.abs(r))) / scale
            if size <= 0.01 * spec.tolerance or (size <= spec.tolerance and size > 0.5 * previous):
                return values
            previous = size
            delta = np.linalg.lstsq(jac, -r, rcond=SINGULAR)[0]
            for name, change in zip(spec.free, delta):
                values[name] += float(change)
        raise NoFixedPoint(f"Newton on the return map did not converge in {NEWTON_STEPS} steps "
                           f"(|r| = {float(np.max(np.abs(r))):.2e})")

    def _verified(self, spec: ModelSpec, values: dict, resolution: Resolution, status: str,
                  elapsed: float) -> ModelGait:
        section, theta = self.split(spec, values)
        outcome = self.map.stride(section, theta, resolution, jacobian=True)
        if not outcome.ok:
            raise NoFixedPoint(f"the stride at the polished point failed: {outcome.failure}")
        scale = max(1.0, float(np.max(np.abs(section))))
        residual = float(np.max(np.abs(outcome.end() - section))) / scale
        verification = self.verify(spec, values, resolution)
        if isinstance(verification, str):
            raise NoFixedPoint(f"the independent stride failed: {verification}")
        if verification > spec.tolerance:
            raise NoFixedPoint(f"not verified: the independent stride misses the point by {verification:.2e} "
                               f"(tolerance {spec.tolerance:.0e})")
        multipliers = np.linalg.eigvals(outcome.jacobians()[0])
        return ModelGait(spec, values, section, multipliers, trivial_flags(multipliers, self._structural_count()),
                         residual, verification, outcome.durations, resolution, elapsed + 0.0, status)

    def _structural_count(self) -> int:
        """The multipliers that are 1 by structure: one per invariant of the law, and its
        families' (:attr:`baslip.model.description.ControlLaw.families`)."""
        invariants = self.functions.invariants
        families = self.functions.model.law(self.functions.law).families
        return (0 if invariants is None else invariants.size1_out(0)) + families


def _invariant_sensitivities(functions: ModelFunctions) -> ca.Function | None:
    """The invariants at the section coordinates and their derivatives in them and theta."""
    if functions.invariants is None:
        return None
    section = ca.SX.sym("section", len(functions.model.section.coordinates))
    theta = ca.SX.sym("theta", len(functions.theta_names))
    values = functions.invariants(functions.lift(section), theta)
    return ca.Function("invariant_sens", [section, theta],
                       [values, ca.jacobian(values, section), ca.jacobian(values, theta)])


def spectral_radius(multipliers, trivial) -> float:
    """The largest |multiplier| of those not 1 by structure (0 if none)."""
    moduli = [abs(m) for m, t in zip(multipliers, trivial) if not t]
    return float(max(moduli)) if moduli else 0.0


def trivial_flags(multipliers: np.ndarray, count: int) -> tuple[bool, ...]:
    """Flags for the ``count`` multipliers nearest 1: those an invariant makes 1."""
    nearest = set(np.argsort(np.abs(np.asarray(multipliers) - 1.0))[:count].tolist())
    return tuple(i in nearest for i in range(len(multipliers)))
