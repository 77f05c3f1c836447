"""Stride-to-stride controllers of a described model's gait, and their measured basins.

At a verified gait x* (the section coordinates) with controls u* (the law's), the map's
exact Jacobians A = dP/dx and B = dP/du give the event-based linear feedback
u_n = u* + K (x_n - x*), designed as for the BA-SLIP (:mod:`baslip.analysis.feedback`):

* ``constant``: K = 0, the open loop;
* ``deadbeat``: A + B K = 0, where B has the rank of x (least norm, in scaled controls);
* ``lqr``: the discrete LQR with unit weights on x and u in their own scales, designed on
  the transverse dynamics where an invariant, or a family of gaits that no control moves
  (:func:`families`), leaves a multiplier at 1.

A controller's basin is measured, not predicted: from each start of a grid around x*,
the closed loop runs stride after stride with the model's own map, and a start counts
when its last stride is back within :data:`RETURNED` of the gait (in each coordinate's
scale) without a fall. Where the law conserves an invariant (the energy of a passive
walker), the starts lie on the gait's level set of it: a start of another energy can
never return to the gait, whatever the controller, and the multiplier 1 the invariant
leaves is not counted in a closed loop's spectral radius.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from baslip.analysis.feedback import (
    RANK_TOLERANCE,
    closed_loop_multipliers,
    control_rank,
    deadbeat_gain,
    lqr_gain_for_gait,
)
from baslip.engine.hybrid import Resolution
from baslip.errors import ArgumentError
from baslip.gait.modelsolver import ModelGait, ModelSolver, spectral_radius, trivial_flags

#: A start has returned when its last stride lies this close to the gait (scaled).
RETURNED = 1e-3
#: The controllers designed at a gait, in order.
CONTROLLERS = ("constant", "deadbeat", "lqr")
#: A coordinate's scale is its size at the gait, but no less than this (SI units).
SMALLEST_SCALE = 0.1
#: A multiplier this close to 1 that no control reaches is a family's (:func:`families`).
FAMILY = 1e-7
#: Newton steps that bring a start onto the gait's level set of the invariants.
LEVEL_STEPS = 20


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
    neutral : int
        How many of them the law's invariants hold at 1.
    """

    name: str
    controls: tuple[str, ...]
    gain: np.ndarray
    multipliers: np.ndarray
    neutral: int = 0

    @property
    def spectral_radius(self) -> float:
        """The largest |multiplier| of the linearised closed loop, but the invariants' 1s."""
        return spectral_radius(self.multipliers, trivial_flags(self.multipliers, self.neutral))


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
    x_scale = np.maximum(np.abs(gait.section), SMALLEST_SCALE)
    u_scale = np.array([max(abs(gait.values[n]), SMALLEST_SCALE) for n in controls])
    neutral = sum(gait.trivial) + families(A, B, u_scale, sum(gait.trivial))
    found = [ModelController("constant", controls, np.zeros((len(controls), len(x_scale))), np.linalg.eigvals(A),
                             neutral)]
    if control_rank(B, u_scale) == len(x_scale):
        K = deadbeat_gain(A, B, u_scale)
        found.append(ModelController("deadbeat", controls, K, closed_loop_multipliers(A, B, K), neutral))
    try:
        K = lqr_gain_for_gait(A, B, np.diag(1 / x_scale**2), np.diag(1 / u_scale**2), neutral)
        found.append(ModelController("lqr", controls, K, closed_loop_multipliers(A, B, K), neutral))
    except ValueError:
        pass  # an unstable mode no control reaches: no LQR
    return tuple(found)


def families(A: np.ndarray, B: np.ndarray, u_scale: np.ndarray, invariants: int) -> int:
    """How many multipliers at 1, besides the ``invariants`` ones (the gait's trivial
    ones: its law's invariants and declared families), no control reaches.

    Such a multiplier is a family's: at fixed controls the gaits form a curve (the upright
    VPP gaits do, time reversal making each one symmetric). No feedback on the controls
    moves it (the Popov-Belevitch-Hautus test: [A - I, B] loses rank), so the LQR is
    designed on the transverse dynamics and the 1 is not counted in a closed loop's radius;
    a start that settles on a neighbour of the family has not returned to the gait.

    Parameters
    ----------
    A, B : numpy.ndarray
        dP/dx and dP/du at the gait.
    u_scale : numpy.ndarray
        The controls' scales.
    invariants : int
        The multipliers at 1 already accounted for by structure.
    """
    multipliers = np.linalg.eigvals(A)
    nearest_one = multipliers[np.argsort(np.abs(multipliers - 1.0))][invariants:]
    found = 0
    for multiplier in nearest_one[np.abs(nearest_one - 1.0) < FAMILY]:
        pencil = np.hstack([A - multiplier * np.eye(len(A)), B * u_scale])
        values = np.linalg.svd(pencil, compute_uv=False)
        found += int(values[-1] < RANK_TOLERANCE * values[0])
    return found


def grid_starts(solver: ModelSolver, gait: ModelGait, spread: float, count: int) -> np.ndarray:
    """Starts around the gait on its level set of the law's invariants.

    The first two section coordinates the invariants leave free (all of them, for a law
    without invariants) take ``count`` values each within ``spread`` of the gait's, in
    the coordinate's scale (its size at the gait, no less than :data:`SMALLEST_SCALE`,
    so that a coordinate near zero is spread too); the rest of those coordinates stay at
    the gait's, and the ones the invariants fix are solved to hold them at the gait's
    values. A start that cannot reach the level set is left out.

    Parameters
    ----------
    solver : ModelSolver
        The model's solver.
    gait : ModelGait
        A verified gait.
    spread : float
        The grid's half-width, relative to each coordinate's scale.
    count : int
        Values along each of the two coordinates.
    """
    x = gait.section
    free = solver.kept_rows(gait.spec, gait.values)
    spread_over = grid_axes(solver, gait)
    scale = np.maximum(np.abs(x), SMALLEST_SCALE)
    axes = [np.linspace(-spread, spread, count) if i in spread_over else np.zeros(1) for i in range(len(x))]
    grid = [x + offsets * scale for offsets in np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(x), -1).T]
    starts = [_on_level_set(solver, gait, start, free) for start in grid]
    return np.array([start for start in starts if start is not None])


def grid_axes(solver: ModelSolver, gait: ModelGait) -> list[int]:
    """The section coordinates (by index) that :func:`grid_starts` spreads: the first two
    the law's invariants leave free.

    Parameters
    ----------
    solver : ModelSolver
        The model's solver.
    gait : ModelGait
        A verified gait.
    """
    return solver.kept_rows(gait.spec, gait.values)[:2]


def _on_level_set(solver: ModelSolver, gait: ModelGait, start: np.ndarray, free: list[int]) -> np.ndarray | None:
    """``start`` with the coordinates not in ``free`` moved (Newton) to hold the law's
    invariants at the gait's values; None if they cannot be."""
    if solver.invariants is None or len(free) == len(start):
        return start
    theta = solver.split(gait.spec, gait.values)[1]
    held = np.array(solver.invariants(gait.section, theta)[0]).ravel()
    fixed = [i for i in range(len(start)) if i not in free]
    x = np.array(start, dtype=float)
    for _ in range(LEVEL_STEPS):
        values, gradient = (np.array(v) for v in solver.invariants(x, theta)[:2])
        miss = values.ravel() - held
        if np.all(np.abs(miss) <= 1e-12 * np.maximum(np.abs(held), 1.0)):
            return x
        try:
            x[fixed] -= np.linalg.solve(gradient[:, fixed], miss)
        except np.linalg.LinAlgError:
            return None
        if not np.all(np.isfinite(x)):
            return None
    return None


def returns(solver: ModelSolver, gait: ModelGait, controller: ModelController, start: np.ndarray, strides: int,
            resolution: Resolution | None = None) -> tuple[bool, int]:
    """Whether the closed loop from ``start`` returns to the gait in ``strides`` strides,
    and the strides it took (or ran before it fell)."""
    spec, values = gait.spec, dict(gait.values)
    resolution = resolution or gait.resolution
    x_scale = np.maximum(np.abs(gait.section), SMALLEST_SCALE)
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
