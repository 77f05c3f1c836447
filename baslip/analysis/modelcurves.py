"""Bifurcation curves of a described model's gaits in two parameters.

A fold, period doubling or Neimark-Sacker point on a branch
(:func:`baslip.analysis.modelfamilies.continue_model`) moves with a second fixed quantity
along a curve. :func:`trace_model_curve` follows it with the minimally extended system of
:class:`baslip.analysis.bifurcation.CurveSystem`, whose base here reads the model only
through :class:`baslip.gait.modelsolver.ModelSolver`:

* the fixed-point equations and their exact Jacobian in (free quantities, l1, l2);
* the map's Jacobian on its *dynamic* coordinates: the section coordinates, less one for
  each invariant of the law, the map restricted to the invariant's level set (so that a
  conserved energy's multiplier 1 does not hide the fold's);
* that Jacobian's gradient in the unknowns, by central differences of exact Jacobians
  (the BA-SLIP's curves take exact second derivatives of its compiled stride; a
  described model's are accurate to about 1e-7, which the corrector's Newton tolerates).

Every point of a curve is verified by the independent stride.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from baslip.analysis.bifurcation import CURVE_TYPES, CurveSystem, trace_curve
from baslip.analysis.modelfamilies import ModelBranchSystem
from baslip.errors import ArgumentError
from baslip.gait.modelsolver import ModelGait, ModelSolver
from baslip.numerics.continuation import CorrectionFailed, Settings

#: Relative step of the central differences of the map's Jacobian.
DIFFERENCE_STEP = 1e-5


class ModelCurveBase(ModelBranchSystem):
    """The fixed-point equations in (free quantities, l1, l2), as the ``base`` of a
    :class:`CurveSystem` (see the module's docstring)."""

    symmetric = False

    @property
    def normal_forms(self) -> bool:
        """The cusp's and the generalised period doubling's coefficients need the map's
        own derivatives, which a level set's restriction does not give."""
        return not self.invariant_rows

    def map_jacobian(self, v: np.ndarray, shift: np.ndarray | None = None) -> np.ndarray:
        """d(map)/d(dynamic coordinates) at ``v``, the kept coordinates moved by ``shift``."""
        values = self.point(v)
        if shift is not None:
            coordinates = self.spec.model.section.coordinates
            for i, delta in zip(self.kept, shift):
                values[coordinates[i]] += float(delta)
        outcome = self.solver.stride(self.spec_at(v), values, self.resolution, jacobian=True)
        if not outcome.ok:
            raise CorrectionFailed(outcome.failure)
        return self.solver.reduced_jacobian(self.spec_at(v), values, outcome.jacobians()[0], self.kept)

    def map_jacobian_gradient(self, v: np.ndarray, seed: np.ndarray) -> np.ndarray:
        """The gradient in (scaled) ``v`` of <seed, map_jacobian(v)>, by central differences."""
        gradient = np.zeros(len(v))
        for i in range(len(v)):
            step = DIFFERENCE_STEP * max(1.0, abs(v[i]))
            up, down = v.copy(), v.copy()
            up[i] += step
            down[i] -= step
            gradient[i] = float(np.sum(seed * (self.map_jacobian(up) - self.map_jacobian(down)))) / (2 * step)
        return gradient


@dataclass(frozen=True)
class ModelCurvePoint:
    """A point of a curve: every quantity's value, the multipliers and the verification."""

    values: dict
    multipliers: np.ndarray
    special: str
    verification: float


@dataclass(frozen=True)
class ModelCurve:
    """A traced curve of ``kind`` in (``first``, ``second``), its points in order."""

    kind: str
    first: str
    second: str
    points: tuple[ModelCurvePoint, ...]
    stop_reason: str


def trace_model_curve(solver: ModelSolver, gait: ModelGait, kind: str, parameters: tuple[str, str],
                      ranges: tuple[tuple[float, float], tuple[float, float]],
                      settings: Settings = Settings(step=0.02, max_step=0.1, max_points=200),
                      at: dict | None = None) -> ModelCurve:
    """The curve of ``kind`` through a point on it, in two fixed quantities, each point
    verified independently.

    Parameters
    ----------
    solver : ModelSolver
        The model's solver.
    gait : ModelGait
        A gait of the model: its spec says what is fixed and free, and its resolution is
        the curve's.
    kind : str
        ``fold``, ``period_doubling`` or ``neimark_sacker``.
    parameters : (str, str)
        Two fixed quantities of the gait's spec (or fixed invariants, such as ``energy``).
    ranges : ((float, float), (float, float))
        Each parameter's range [its unit].
    settings : Settings
        Steps and limits; the ranges are set from ``ranges``.
    at : dict, optional
        Every quantity's value (and the parameters') at a point near the curve, such as
        a branch's special point; the gait's own values by default.

    Returns
    -------
    ModelCurve
        The points from one end to the other, and why each end stopped.
    """
    if kind not in CURVE_TYPES:
        raise ArgumentError("kind", f"expected one of {', '.join(CURVE_TYPES)}, not {kind!r}")
    spec = gait.spec
    for name in parameters:
        if name not in spec.fixed:
            raise ArgumentError("parameters", f"{name!r} must be a fixed quantity of the spec ({', '.join(spec.fixed)})")
    values = {**gait.values, **spec.fixed_invariants, **(at or {})}
    base = ModelCurveBase(solver, spec, values, (*spec.free, *parameters), gait.resolution)
    scales = base.scales[-2:]
    bounds = tuple((lo / s, hi / s) for (lo, hi), s in zip(ranges, scales))
    n = len(base.names)
    settings = Settings(step=settings.step, min_step=settings.min_step, max_step=settings.max_step,
                        max_points=settings.max_points, lam_range=bounds[1], other_ranges=((n - 2, *bounds[0]),),
                        tolerance=settings.tolerance, max_newton=settings.max_newton)
    curve = CurveSystem(base, kind)
    v0 = np.array([values[name] for name in base.names]) / base.scales
    branch = trace_curve(curve, v0, settings)
    points = []
    for point in branch.points:
        at = base.point(point.v)
        verification = solver.verify(base.spec_at(point.v), at, gait.resolution)
        points.append(ModelCurvePoint(at, point.multipliers, point.special,
                                      math.inf if isinstance(verification, str) else verification))
    return ModelCurve(kind, parameters[0], parameters[1], tuple(points), branch.stop_reason)
