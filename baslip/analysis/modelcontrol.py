"""Stride-to-stride controllers of a described model's gait, and their measured basins.

At a verified gait x* (the section coordinates) with controls u* (the law's), the map's
exact Jacobians A = dP/dx and B = dP/du give the event-based linear feedback
u_n = u* + K (x_n - x*), designed as for the BA-SLIP (:mod:`baslip.analysis.feedback`):

* ``constant``: K = 0, the open loop;
* ``deadbeat``: A + B K = 0, where B has the rank of x (least norm, in scaled controls);
* ``lqr``: the discrete LQR with unit weights on x and u in their own scales, designed on
  the transverse dynamics where an invariant leaves a multiplier at 1.

A controller's basin is measured, not predicted: from each start of a grid around x*,
the closed loop runs stride after stride with the model's own map, and a start counts
when its last stride is back within :data:`RETURNED` of the gait (in each coordinate's
scale) without a fall.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from baslip.analysis.feedback import closed_loop_multipliers, control_rank, deadbeat_gain, lqr_gain_for_gait
from baslip.engine.hybrid import Resolution
from baslip.errors import ArgumentError
from baslip.gait.modelsolver import ModelGait, ModelSolver

#: A start has returned when its last stride lies this close to the gait (scaled).
RETURNED = 1e-3
#: The controllers designed at a gait, in order.
CONTROLLERS = ("constant", "deadbeat", "lqr")


@dataclass(frozen=True)
class ModelController:
    """u = u* + K (x - x*) in the named controls.

    Parameters
    ----------
    name : str
        ``constant``, ``deadbeat`` or ``lqr``.
    controls : tuple of str
        The controls it sets.
    gain : ndarray
        K (controls x section coordinates).
    multipliers : ndarray
        The linearised closed loop's multipliers, eig(A + B K).
    """

    name: str
    controls: tuple[str, ...]
    gain: np.ndarray
    multipliers: np.ndarray

    @property
    def spectral_radius(self) -> float:
        """The largest |multiplier| of the linearised closed loop."""
        return float(np.max(np.abs(self.multipliers)))


def design(solver: ModelSolver, gait: ModelGait) -> tuple[ModelController, ...]:
    """The controllers of :data:`CONTROLLERS` that exist at ``gait``.

    Parameters
    ----------
    solver : ModelSolver
        The model's solver.
    gait : ModelGait
        A verified gait; its law's controls are the ones set.
    """
    spec = gait.spec
    controls = tuple(q.name for q in spec.model.controls_of(spec.law))
    if not controls:
        raise ArgumentError("law", f"law {spec.model.law(spec.law).name!r} has no controls to feed back")
    outcome = solver.stride(spec, gait.values, gait.resolution, jacobian=True)
    A, by_theta = outcome.jacobians()
    B = by_theta[:, [solver.functions.theta_names.index(n) for n in controls]]
    x_scale = np.maximum(np.abs(gait.section), 0.1)
    u_scale = np.array([max(abs(gait.values[n]), 0.1) for n in controls])
    found = [ModelController("constant", controls, np.zeros((len(controls), len(x_scale))), np.linalg.eigvals(A))]
    if control_rank(B, u_scale) == len(x_scale):
        K = deadbeat_gain(A, B, u_scale)
        found.append(ModelController("deadbeat", controls, K, closed_loop_multipliers(A, B, K)))
    neutral = sum(gait.trivial)
    try:
        K = lqr_gain_for_gait(A, B, np.diag(1 / x_scale**2), np.diag(1 / u_scale**2), neutral)
        found.append(ModelController("lqr", controls, K, closed_loop_multipliers(A, B, K)))
    except ValueError:
        pass  # an unstable mode no control reaches: no LQR
    return tuple(found)


def grid_starts(gait: ModelGait, spread: float, count: int) -> np.ndarray:
    """Starts around the gait: each of its first two section coordinates on ``count``
    values within ``spread`` (relative) of the gait's, the others at the gait's."""
    x = gait.section
    starts = []
    axes = [np.linspace(-spread, spread, count) if i < 2 else np.zeros(1) for i in range(len(x))]
    for offsets in np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(x), -1).T:
        starts.append(x * (1 + offsets))
    return np.array(starts)


def returns(solver: ModelSolver, gait: ModelGait, controller: ModelController, start: np.ndarray, strides: int,
            resolution: Resolution | None = None) -> tuple[bool, int]:
    """Whether the closed loop from ``start`` returns to the gait in ``strides`` strides,
    and the strides it took (or ran before it fell)."""
    spec, values = gait.spec, dict(gait.values)
    resolution = resolution or gait.resolution
    x_scale = np.maximum(np.abs(gait.section), 0.1)
    u_star = np.array([gait.values[n] for n in controller.controls])
    coordinates = spec.model.section.coordinates
    x = np.array(start, dtype=float)
    for stride in range(strides):
        if np.max(np.abs(x - gait.section) / x_scale) <= RETURNED:
            return True, stride
        u = u_star + controller.gain @ (x - gait.section)
        values.update(zip(coordinates, x))
        values.update(zip(controller.controls, u))
        outcome = solver.stride(spec, values, resolution)
        if not outcome.ok:
            return False, stride
        x = outcome.end()
    return bool(np.max(np.abs(x - gait.section) / x_scale) <= RETURNED), strides


def basin(solver: ModelSolver, gait: ModelGait, controller: ModelController, starts: np.ndarray, strides: int,
          progress: Callable[[int], None] = lambda done: None) -> list[tuple[bool, int]]:
    """:func:`returns` from each start, in order."""
    outcomes = []
    for done, start in enumerate(starts, start=1):
        outcomes.append(returns(solver, gait, controller, start, strides))
        progress(done)
    return outcomes
