"""The straight homotopy path from a shipped gait to a problem, and its pseudo-arclength
continuation, which turns the folds where natural steps along the path break.

A path runs, at the normalised body (the thesis's m, rho0 and g), in the dimensionless
groups and in the normalised fixed values, from a shipped gait (s = 0) to the problem
(s = 1). :func:`follow_path` continues a verified gait of the path, from where natural
steps broke, as a branch in s (:func:`baslip.numerics.continuation.continue_branch`): on a
fold s turns back and the branch goes on until s comes to 1, or it stops. So that the
equations are square, as many of the free quantities as there are periodicity rows stay
free, chosen where the Jacobian's columns are best conditioned (pivoted Gram-Schmidt);
the rest are held at the gait's values.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from baslip.engine.returnmap import ReturnMap, RunnerFell
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HipLaw
from baslip.model.quantities import NOMINAL, implied_periodicity
from baslip.model.similarity import Groups, body_with
from baslip.numerics.continuation import CorrectionFailed, Settings, continue_branch

#: The continuation's settings along a path: steps in scaled units, s kept within [-1, 1]
#: (a branch that runs back past the shipped gait has lost its way).
PATH_SETTINGS = Settings(step=0.05, min_step=1e-6, max_step=0.25, max_points=400, lam_range=(-1.0, 1.0),
                         tolerance=1e-10, max_newton=8)


@dataclass(frozen=True)
class StraightPath:
    """The straight path in the groups and the normalised fixed values."""

    start_groups: Groups
    end_groups: Groups
    start_fixed: Mapping[str, float]
    end_fixed: Mapping[str, float]

    def at(self, s: float) -> tuple[Groups, dict[str, float]]:
        """The groups and the fixed values at ``s``."""
        fixed = {n: a + s * (self.end_fixed[n] - a) for n, a in self.start_fixed.items()}
        return self.start_groups.interpolated(self.end_groups, s), fixed

    def body(self, s: float) -> Params:
        """The normalised body at ``s`` (linear in s)."""
        return body_with(self.at(s)[0])

    def is_exact(self) -> bool:
        """Whether the path has no length: its two ends are the same normalised problem."""
        same_fixed = all(math.isclose(self.start_fixed[n], self.end_fixed[n], rel_tol=1e-12, abs_tol=1e-15)
                         for n in self.start_fixed)
        return self.start_groups.distance(self.end_groups) < 1e-12 and same_fixed


class PathSystem:
    """F(v) = 0 along a path: v = (the free quantities in their nominal units, s), F the
    periodicity rows r(X, u) - X that structure does not imply, at the body and fixed
    values of s. No special points are sought (``special_types`` is empty)."""

    special_types: tuple[str, ...] = ()

    def __init__(self, path: StraightPath, law: HipLaw, values: Mapping[str, float], s: float, rmap: ReturnMap,
                 bounds: Mapping[str, tuple[float, float]]):
        self.path, self.law, self.rmap = path, law, rmap
        self.design = APEX.names + law.controls.names
        groups_s, fixed = path.at(s)
        implied = implied_periodicity(fixed, body_with(groups_s), law)
        self.rows = [APEX.index(n) for n in APEX.names if n not in implied]
        candidates = [n for n in self.design if n not in fixed]
        self.held = dict(values)
        self.free = self._best_conditioned(candidates, values, s)
        self.scale = np.array([NOMINAL[n] for n in self.free])
        self.bounds = {n: bounds.get(n, (-math.inf, math.inf)) for n in self.free}
        self._dp_ds = path.body(1.0).vector() - path.body(0.0).vector()

    def _best_conditioned(self, candidates: list[str], values: Mapping[str, float], s: float) -> list[str]:
        """As many of ``candidates`` as there are rows, chosen by pivoted Gram-Schmidt on
        the scaled Jacobian's columns at the gait: the best conditioned set."""
        columns = self._full(values, s)[:, [self.design.index(n) for n in candidates]]
        columns = columns * np.array([NOMINAL[n] for n in candidates])
        chosen: list[int] = []
        for _ in range(min(len(self.rows), len(candidates))):
            norms = np.linalg.norm(columns, axis=0)
            norms[chosen] = -1.0
            best = int(np.argmax(norms))
            chosen.append(best)
            unit = columns[:, best] / max(np.linalg.norm(columns[:, best]), 1e-300)
            columns = columns - np.outer(unit, unit @ columns)
        return [candidates[i] for i in sorted(chosen)]

    def _full(self, values: Mapping[str, float], s: float) -> np.ndarray:
        """d(r - X)/d(X, u) on the rows at ``values`` and ``s``."""
        X, u, params = self._point(values, s)
        try:
            dr_dX, dr_du = self.rmap.jacobians(X, u, params)
        except RunnerFell as err:
            raise CorrectionFailed(f"the runner falls ({err.fall.value})") from None
        return np.hstack([dr_dX - np.eye(APEX.size), dr_du])[self.rows]

    def _point(self, values: Mapping[str, float], s: float) -> tuple[np.ndarray, np.ndarray, Params]:
        """(apex, control, body) at ``values`` (the path's fixed ones at s)."""
        groups_s, fixed = self.path.at(s)
        design = np.array([{**values, **fixed}[n] for n in self.design])
        return design[: APEX.size], design[APEX.size :], body_with(groups_s)

    def pack(self, s: float) -> np.ndarray:
        """The unknowns at the held gait and ``s``."""
        return np.append(np.array([self.held[n] for n in self.free]) / self.scale, s)

    def values(self, v: np.ndarray) -> dict[str, float]:
        """Every design quantity at ``v`` (the path's fixed values at its s)."""
        free = dict(zip(self.free, map(float, v[:-1] * self.scale)))
        return {**self.held, **free, **self.path.at(float(v[-1]))[1]}

    def residual(self, v: np.ndarray) -> np.ndarray:
        X, u, params = self._point(self.values(v), float(v[-1]))
        stride = self.rmap.stride(X, u, params)
        if not stride.ok:
            raise CorrectionFailed("the runner falls" if stride.fall is None else f"the runner falls ({stride.fall.value})")
        return (stride.apex - X)[self.rows]

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        """dF/dv: the free quantities' columns (scaled), then d/ds along the path."""
        s = float(v[-1])
        X, u, params = self._point(self.values(v), s)
        try:
            dr_dX, dr_du, dr_dp = self.rmap.all_jacobians(X, u, params)
        except RunnerFell as err:
            raise CorrectionFailed(f"the runner falls ({err.fall.value})") from None
        full = np.hstack([dr_dX - np.eye(APEX.size), dr_du])[self.rows]
        along = dr_dp[self.rows] @ self._dp_ds
        for name, start in self.path.start_fixed.items():
            along = along + full[:, self.design.index(name)] * (self.path.end_fixed[name] - start)
        free = full[:, [self.design.index(n) for n in self.free]] * self.scale
        return np.column_stack([free, along])

    def multipliers(self, v: np.ndarray) -> tuple[np.ndarray, list[bool]]:
        return np.zeros(0), []  # no special points are sought along a path

    def test_functions(self, v: np.ndarray, jac: np.ndarray, tangent: np.ndarray) -> dict[str, float]:
        return {}

    def outside_bounds(self, v: np.ndarray) -> str | None:
        """Which free quantity ``v`` takes past its bounds, or None."""
        for name, value in zip(self.free, v[:-1] * self.scale):
            lo, hi = self.bounds[name]
            if not lo <= value <= hi:
                return f"{name} leaves its bounds"
        return None


@dataclass(frozen=True)
class Followed:
    """Where :func:`follow_path` ended: the gait at s = 1 (every design quantity, at the
    normalised body), or None and why; the branch's points and whether s turned back."""

    values: dict[str, float] | None
    why: str
    points: int
    turned: bool


def follow_path(path: StraightPath, law: HipLaw, values: Mapping[str, float], s: float, rmap: ReturnMap,
                bounds: Mapping[str, tuple[float, float]]) -> Followed:
    """Continue the gait ``values`` (all design quantities, a fixed point at ``s`` of
    ``path``) towards s = 1 by pseudo-arclength, within ``bounds``.

    Parameters
    ----------
    path : StraightPath
        The path, at the normalised body.
    law : HipLaw
        The hip law of the gaits.
    values : Mapping of str to float
        A fixed point at ``s`` (SI units and radians, at the normalised body).
    s : float
        Where on the path it lies.
    rmap : ReturnMap
        The map whose fixed points are followed.
    bounds : Mapping of str to (float, float)
        Bounds of the design quantities (theta_h's posture, say).

    Returns
    -------
    Followed
    """
    try:
        system = PathSystem(path, law, values, s, rmap, bounds)
        branch = continue_branch(system, system.pack(s), 1.0, PATH_SETTINGS, accept=system.outside_bounds)
    except CorrectionFailed as err:
        return Followed(None, f"the path cannot be followed from here ({err})", 0, False)
    along = np.array([p.v[-1] for p in branch.points])
    turned = bool(np.any(np.diff(along) < 0))
    if abs(along[-1] - 1.0) > 1e-12:
        return Followed(None, f"its branch stopped at s = {along[-1]:.3g} ({branch.stop_reason})", len(along), turned)
    return Followed(system.values(branch.points[-1].v), "", len(along), turned)
