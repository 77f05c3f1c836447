"""Families of a described model's gaits: branches in one quantity, and atlases.

Both read the model only through :class:`baslip.gait.modelsolver.ModelSolver`: the
independent equations of a fixed point (the section coordinates' returns, less one per
invariant, and the fixed invariants), their exact Jacobian and the multipliers.

* :func:`continue_model` follows the branch through a solved gait as one fixed quantity
  moves (pseudo-arclength, :mod:`baslip.numerics.continuation`), finding folds,
  period doublings, Neimark-Sacker points and branch points on it.
* :func:`cover_model` covers the gaits of a problem with more free quantities than
  equations with an atlas (:mod:`baslip.analysis.atlas`).

Every point either reports is re-simulated by the independent CVODES stride, and carries
its verification.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from baslip.analysis.atlas import Atlas, AtlasSettings, cover
from baslip.engine.hybrid import Resolution
from baslip.errors import ArgumentError, RunError
from baslip.gait.modelsolver import ModelGait, ModelSolver, spectral_radius
from baslip.numerics.continuation import CorrectionFailed, Settings, continue_branch
from baslip.numerics.corrector import Evaluation
from baslip.problem.modelspec import ModelSpec


def _scales(spec: ModelSpec, values: dict, names: tuple[str, ...]) -> np.ndarray:
    """Each unknown's unit in the scaled coordinates: its size at the start, at least 0.1."""
    return np.array([max(abs(values[n]), 0.1) for n in names])


class Equations:
    """The fixed-point equations in scaled unknowns ``names`` (the rest at ``values``).

    A name may be an invariant of the law (``energy``): its value is then the one the
    equations fix it to, moved with ``v`` (so that a branch can follow the energy).
    """

    def __init__(self, solver: ModelSolver, spec: ModelSpec, values: dict, names: tuple[str, ...],
                 resolution: Resolution):
        held = [i.name for i in spec.model.invariants_of(spec.law)]
        self.solver, self.values, self.names, self.resolution = solver, dict(values), names, resolution
        quantities = tuple(n for n in names if n not in held)
        self.invariant_names = tuple(n for n in names if n in held)
        self.spec = replace(spec, fixed={k: v for k, v in spec.fixed.items() if k not in quantities},
                            guess={n: values[n] for n in quantities})
        self.scales = _scales(spec, values, names)
        # The solver's columns are in the spec's order of free quantities; ours in names'.
        self.columns = [self.spec.free.index(n) if n in quantities else -1 for n in names]
        # The returns asked for are chosen once, at the start, for the whole family.
        self.kept = solver.kept_rows(self.spec, self.values)
        fixed = list(self.spec.fixed_invariants)
        self.invariant_rows = {n: len(self.kept) + fixed.index(n) for n in self.invariant_names}

    def point(self, v: np.ndarray) -> dict:
        """Every quantity's value (and the moved invariants') at the scaled ``v``."""
        return {**self.values, **dict(zip(self.names, (np.asarray(v) * self.scales).tolist()))}

    def spec_at(self, v: np.ndarray) -> ModelSpec:
        """The spec with the moved invariants fixed at their values at ``v``."""
        if not self.invariant_names:
            return self.spec
        at = self.point(v)
        return replace(self.spec, fixed={**self.spec.fixed, **{n: at[n] for n in self.invariant_names}})

    def evaluate(self, v: np.ndarray, jacobian: bool):
        """The equations at ``v`` and, if asked, their Jacobian in scaled ``v``; or why
        the stride failed."""
        spec = self.spec_at(v)
        result = self.solver.equations(spec, self.point(v), self.resolution, jacobian, self.kept)
        if isinstance(result, str) or not jacobian:
            return result
        residual, by_free = result
        columns = np.zeros((len(residual), len(self.names)))
        for j, (name, column) in enumerate(zip(self.names, self.columns)):
            if column >= 0:
                columns[:, j] = by_free[:, column]
            else:  # the row holds (E - E_fixed) / max(1, |E_fixed|): its rate in E_fixed
                columns[self.invariant_rows[name], j] = -1.0 / max(1.0, abs(spec.fixed[name]))
        return residual, columns * self.scales[None, :]


class ModelBranchSystem(Equations):
    """:class:`baslip.numerics.continuation.System` of a described model's branch."""

    def residual(self, v: np.ndarray) -> np.ndarray:
        result = self.evaluate(v, False)
        if isinstance(result, str):
            raise CorrectionFailed(result)
        return result[0]

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        result = self.evaluate(v, True)
        if isinstance(result, str):
            raise CorrectionFailed(result)
        return result[1]

    def multipliers(self, v: np.ndarray) -> tuple[np.ndarray, list[bool]]:
        result = self.solver.multipliers(self.spec_at(v), self.point(v), self.resolution)
        if isinstance(result, str):
            raise CorrectionFailed(result)
        return result[0], list(result[1])


@dataclass(frozen=True)
class ModelBranchPoint:
    """A point of a described model's branch: its values, multipliers and checks."""

    values: dict
    multipliers: np.ndarray
    trivial: tuple[bool, ...]
    special: str
    verification: float

    @property
    def spectral_radius(self) -> float:
        """The largest |multiplier| that is not 1 by structure."""
        return spectral_radius(self.multipliers, self.trivial)


@dataclass(frozen=True)
class ModelBranch:
    """A traced branch in ``parameter``: its points in order and why it stopped."""

    parameter: str
    points: tuple[ModelBranchPoint, ...]
    stop_reason: str


def continue_model(solver: ModelSolver, gait: ModelGait, parameter: str, bounds: tuple[float, float],
                   settings: Settings = Settings(step=0.02, max_step=0.2, max_points=200),
                   progress: Callable[[int, object], None] = lambda n, p: None) -> ModelBranch:
    """The branch of gaits through ``gait`` as the fixed quantity ``parameter`` moves
    between ``bounds``, both ways, each point verified independently.

    Parameters
    ----------
    solver : ModelSolver
        The model's solver.
    gait : ModelGait
        A verified gait of the model.
    parameter : str
        A fixed quantity of the gait's spec (a control, a parameter, a section coordinate).
    bounds : (float, float)
        Its range [its unit].
    settings : Settings
        Step control; its ``lam_range`` is set from ``bounds``.
    progress : callable
        Called with the count of points and the last point.

    Returns
    -------
    ModelBranch
        Points from the low end to the high end, and why each side stopped.
    """
    spec = gait.spec
    if parameter not in spec.fixed:
        raise ArgumentError("parameter", f"{parameter!r} must be a fixed quantity of the spec "
                                         f"({', '.join(spec.fixed)}), not one of the free {spec.free}")
    values = {**gait.values, **spec.fixed_invariants}
    system = ModelBranchSystem(solver, spec, values, (*spec.free, parameter), gait.resolution)
    scale = system.scales[-1]
    lam_range = (bounds[0] / scale, bounds[1] / scale)
    settings = replace(settings, lam_range=lam_range)
    v0 = np.array([values[n] for n in system.names]) / system.scales
    sides = [continue_branch(system, v0, direction, settings, progress=progress) for direction in (-1.0, 1.0)]
    points = [*reversed(sides[0].points[1:]), *sides[1].points]
    return ModelBranch(parameter, tuple(_branch_point(system, p) for p in points),
                       f"low end: {sides[0].stop_reason}; high end: {sides[1].stop_reason}")


def _branch_point(system: ModelBranchSystem, point) -> ModelBranchPoint:
    """A point of the branch, verified; one that misses its verification at the branch's
    resolution (calibrated at its first gait) is polished at a resolution calibrated
    where it lies, and its multipliers taken there."""
    solver, spec, values = system.solver, system.spec_at(point.v), system.point(point.v)
    multipliers, trivial = point.multipliers, tuple(point.trivial)
    verification = solver.verify(spec, values, system.resolution)
    if isinstance(verification, str) or verification > spec.tolerance:
        values, resolution = _polished(solver, spec, values, system.resolution)
        verification = solver.verify(spec, values, resolution)
        found = solver.multipliers(spec, values, resolution)
        if not isinstance(found, str):
            multipliers, trivial = found[0], tuple(found[1])
    return ModelBranchPoint(values, multipliers, trivial, point.special,
                            math.inf if isinstance(verification, str) else verification)


def _polished(solver: ModelSolver, spec: ModelSpec, values: dict, fallback: Resolution) -> tuple[dict, Resolution]:
    """``values`` polished onto the gaits at a resolution calibrated there, and that
    resolution; or as they are, with ``fallback``, where the polish fails.

    A family holds one resolution, calibrated at its first gait, so that its equations
    are one smooth map; far from there (a stiffer leg, a larger gain) it may miss the
    tolerance, and a point found with it would then fail its verification.
    """
    resolution = solver.calibrated(spec, values)
    try:
        return solver.polish(spec, values, resolution), resolution
    except RunError:
        return values, fallback


class ModelManifoldSystem(Equations):
    """:class:`baslip.numerics.corrector.ManifoldSystem` of a described model's gaits."""

    def __init__(self, solver: ModelSolver, spec: ModelSpec, values: dict, resolution: Resolution):
        super().__init__(solver, spec, values, spec.free, resolution)
        self.lower = np.array([spec.range_of(n)[0] for n in self.names]) / self.scales
        self.upper = np.array([spec.range_of(n)[1] for n in self.names]) / self.scales

    def evaluate(self, w: np.ndarray, jacobian: bool = False):
        result = super().evaluate(w, jacobian)
        if jacobian:
            return result
        return Evaluation(failure=result) if isinstance(result, str) else Evaluation(residual=result[0])

    def jacobian(self, w: np.ndarray) -> np.ndarray | str:
        result = super().evaluate(w, True)
        return result if isinstance(result, str) else result[1]

    def outside(self, w: np.ndarray) -> str:
        for name, value, lo, hi in zip(self.names, w, self.lower, self.upper):
            if not lo <= value <= hi:
                return f"{name} outside its bounds"
        return ""

    def solved(self, w: np.ndarray, residual: np.ndarray) -> bool:
        return float(np.max(np.abs(residual))) <= 0.1 * self.spec.tolerance


@dataclass(frozen=True)
class ModelChart:
    """A chart centre of a described model's atlas: its values, spectral radius and the
    independent verification."""

    values: dict
    spectral_radius: float
    piece: int
    verification: float


def cover_model(solver: ModelSolver, gait: ModelGait, settings: AtlasSettings = AtlasSettings(max_charts=200),
                progress: Callable[[int, int], None] | None = None) -> tuple[Atlas, tuple[ModelChart, ...]]:
    """An atlas of the gaits around ``gait`` in its spec's free quantities.

    Parameters
    ----------
    solver : ModelSolver
        The model's solver.
    gait : ModelGait
        A verified gait; its spec must have more free quantities than equations.
    settings : AtlasSettings
        Radii (in units of each quantity's size at the gait) and limits.
    progress : callable, optional
        ``progress(charts, seeds)``.

    Returns
    -------
    (Atlas, tuple of ModelChart)
        The covering, and each chart centre's values, radius and verification.
    """
    system = ModelManifoldSystem(solver, gait.spec, gait.values, gait.resolution)
    equations = len(system.evaluate(np.array([gait.values[n] for n in system.names]) / system.scales).residual)
    k = len(system.names) - equations
    if not 1 <= k <= 3:
        raise ArgumentError("free", f"an atlas needs 1 to 3 more free quantities than equations; "
                                    f"{len(system.names)} free and {equations} equations give {k}")
    seed = np.array([gait.values[n] for n in system.names]) / system.scales
    atlas = cover(system, [seed], k, settings, progress=progress)
    charts = tuple(_chart(solver, system, system.point(chart.center), piece)
                   for chart, piece in zip(atlas.charts, atlas.pieces))
    return atlas, charts


def _chart(solver: ModelSolver, system: ModelManifoldSystem, values: dict, piece: int) -> ModelChart:
    """A chart centre polished onto the gaits at a resolution calibrated there
    (:func:`_polished`), with its spectral radius and verification at that resolution."""
    values, resolution = _polished(solver, system.spec, values, system.resolution)
    found = solver.multipliers(system.spec, values, resolution)
    radius = math.inf if isinstance(found, str) else spectral_radius(*found)
    verification = solver.verify(system.spec, values, resolution)
    return ModelChart(values, float(radius), piece, math.inf if isinstance(verification, str) else verification)
