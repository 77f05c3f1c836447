"""A described model's gait with no guess: its reference gait carried to the problem.

A model names one known gait (:attr:`baslip.model.description.Model.reference`) at its
default parameters. A problem of another body, other fixed values, or both, starts there:

1. **Similarity** (:mod:`baslip.model.sizes`). The mass, length and time factors that
   bring the default parameters nearest the problem's (least squares in the logarithms,
   by each parameter's dimension) give a body of the same dimensionless groups, where the
   reference gait, each value scaled by its own dimension, is a gait with the same
   multipliers.
2. **Homotopy.** From that body and its scaled values to the problem's own, along the
   straight path in the parameters and the fixed values, by pseudo-arclength
   (:func:`baslip.numerics.continuation.continue_branch`), which turns at folds.

The gait at the path's end is the start of the problem's solve, which verifies it.
:func:`carry` is step 2 alone, from any gait: a sweep's neighbour, say.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from baslip.analysis.modelfamilies import Equations
from baslip.errors import RunError
from baslip.gait.modelsolver import ModelSolver
from baslip.model.sizes import similarity
from baslip.numerics.continuation import CorrectionFailed, Settings, continue_branch
from baslip.problem.modelspec import ModelSpec


class NoStart(RunError):
    """The reference gait could not be carried to the problem; the message says where."""


def reference_start(solver: ModelSolver, spec: ModelSpec) -> dict[str, float]:
    """Every quantity's value at a gait of ``spec``'s problem, from the model's reference.

    Parameters
    ----------
    solver : ModelSolver
        The model's solver (its law must be the model's first: the reference's).
    spec : ModelSpec
        The problem; its guess says which quantities are free (its values are ignored).

    Raises
    ------
    NoStart
        The model has no reference, or the path to the problem broke.
    """
    model = spec.model
    if not model.reference:
        raise NoStart(f"model {model.name} names no reference gait to start from: give a guess")
    target = spec.values()
    scale = similarity(model, {q.name: target[q.name] for q in model.parameters})
    start = {name: value * scale.factor(model.dimension(name, spec.law))
             for name, value in _reference(solver, spec).items()}
    return carry(solver, spec, start)


def carry(solver: ModelSolver, spec: ModelSpec, start: dict[str, float]) -> dict[str, float]:
    """Every quantity's value at a gait of ``spec``, continued from the gait at ``start``
    (every quantity's value, a fixed point of the same model and law, or near one) along
    the straight path in the quantities ``spec`` fixes to another value.

    Parameters
    ----------
    solver : ModelSolver
        The model's solver.
    spec : ModelSpec
        The problem to reach; its guess says which quantities are free.
    start : dict
        A gait's values: every quantity's, and the fixed invariants'.

    Raises
    ------
    NoStart
        The path broke (a fall, or a fold it could not turn).
    """
    target = {**spec.values(), **spec.fixed_invariants}
    moved = tuple(n for n in target if n not in spec.free and not math.isclose(start[n], target[n], rel_tol=1e-13,
                                                                               abs_tol=1e-15))
    if not moved:
        return dict(start)
    return _follow(solver, spec, start, target, moved)


def _reference(solver: ModelSolver, spec: ModelSpec) -> dict[str, float]:
    """The reference gait's values, its invariants' too, at the default parameters."""
    model = spec.model
    values = {q.name: q.default for q in model.quantities(spec.law)}
    values.update(model.reference)
    if solver.invariants is not None:
        section = np.array([values[c] for c in model.section.coordinates])
        held = np.array(solver.invariants(section, solver.functions.theta(values))[0]).ravel()
        values.update({i.name: float(v) for i, v in zip(model.invariants_of(spec.law), held)})
    return values


class _Path:
    """The fixed-point equations along the straight path, v = (free, scaled; s)."""

    special_types: tuple[str, ...] = ()

    def __init__(self, equations: Equations, free: int, start: np.ndarray, delta: np.ndarray):
        self.equations, self.free, self.start, self.delta = equations, free, start, delta

    def unscaled(self, w: np.ndarray) -> np.ndarray:
        """The equations' own (scaled) unknowns at the path's ``w``."""
        moved = (self.start + w[-1] * self.delta) / self.equations.scales[self.free:]
        return np.concatenate([w[:-1], moved])

    def residual(self, w: np.ndarray) -> np.ndarray:
        result = self.equations.evaluate(self.unscaled(w), False)
        if isinstance(result, str):
            raise CorrectionFailed(result)
        return result[0]

    def jacobian(self, w: np.ndarray) -> np.ndarray:
        result = self.equations.evaluate(self.unscaled(w), True)
        if isinstance(result, str):
            raise CorrectionFailed(result)
        by_moved = result[1][:, self.free:] / self.equations.scales[self.free:]
        return np.hstack([result[1][:, :self.free], (by_moved @ self.delta)[:, None]])

    def multipliers(self, w: np.ndarray) -> tuple[np.ndarray, list[bool]]:
        return np.zeros(0), []


def _follow(solver: ModelSolver, spec: ModelSpec, start: dict, target: dict, moved: tuple[str, ...]) -> dict:
    """Continue the start's gait along the path to the problem (step 2)."""
    # Every quantity not free is held at the start's value, parameters too: the start's
    # body (a similar one, or a neighbour's) need not have the problem's defaults.
    begin = replace(spec, fixed={k: start[k] for k in target if k not in spec.free}, guess={n: start[n] for n in spec.free})
    first = solver.solve(begin)  # the start, polished and verified where it is
    values = {**first.values, **{k: start[k] for k in begin.fixed_invariants}}
    resolution = solver.calibrated(begin, values)
    equations = Equations(solver, begin, values, (*spec.free, *moved), resolution)
    origin = np.array([values[n] for n in moved])
    path = _Path(equations, len(spec.free), origin, np.array([target[n] for n in moved]) - origin)
    w0 = np.append(np.array([values[n] for n in spec.free]) / equations.scales[:len(spec.free)], 0.0)
    branch = continue_branch(path, w0, 1.0, Settings(step=0.05, max_step=0.25, max_points=400, lam_range=(0.0, 1.0)))
    end = branch.points[-1].v
    if not math.isclose(end[-1], 1.0, abs_tol=1e-9):
        raise NoStart(f"the path to the problem broke at {end[-1]:.3f} of the way ({branch.stop_reason})")
    return equations.point(path.unscaled(end))
