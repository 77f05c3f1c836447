"""The Newton polish: from the NLP's point to a fixed point of the exact return map.

The NLP's RK4 discretisation is good to about 1e-6. Gauss-Newton on r^N(X, u) - X (and
the apex energy, when a problem holds it) over the free quantities that sit on no bound
brings the point onto the manifold of fixed points of the compiled map (error estimate
<= 1e-12). The step is the minimum-norm least-squares step in scaled variables (truncated
SVD), so rank-deficient equations converge too: energy conservation with no torque, and
the SLIP limit.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from baslip.engine.returnmap import ReturnMap
from baslip.gait.shooting import FixedPointSpec
from baslip.model.dynamics import APEX, PARAMS, apex_energy
from baslip.model.quantities import NOMINAL

#: Gauss-Newton stops once eps is below this (well inside the verification's 1e-10).
POLISH_EPS = 1e-12
POLISH_MAX_ITER = 10
#: Halvings of a step before the polish gives up, and the growth of the residual's norm
#: that makes a step back off.
POLISH_BACKTRACKS = 8
POLISH_GROWTH = 10.0
#: Relative singular-value cutoff of the step (rank-deficient fixed-point equations).
POLISH_RCOND = 1e-9
#: How far past (or short of) a bound IPOPT may return a quantity that it holds on the
#: bound, relative to max(1, |bound|): its ``bound_relax_factor`` is 1e-8, and the
#: interior point stops up to as far inside.
BOUND_RELAXATION = 1e-7


def eps(apex_next, X) -> float:
    """Thesis eq. 4.1: |X[n+1] - X[n]| / |X[n]|."""
    return float(np.linalg.norm(np.asarray(apex_next) - np.asarray(X)) / np.linalg.norm(X))


class Polish:
    """Gauss-Newton onto the fixed points of ``residual_map``, with Jacobians from
    ``jacobian_map``."""

    def __init__(self, residual_map: ReturnMap, jacobian_map: ReturnMap):
        self.residual_map, self.jacobian_map = residual_map, jacobian_map
        X, p = APEX.sym("X"), PARAMS.sym("p")
        self._energy = ca.Function("apex_energy", [X, p], [apex_energy(X, p)])
        self._energy_gradient = ca.Function("energy_gradient", [X, p], [ca.gradient(apex_energy(X, p), X)])

    def run_in_bounds(self, spec: FixedPointSpec, X, u) -> tuple[np.ndarray, np.ndarray, int, str]:
        """:meth:`run`, and if its point leaves the problem's bounds, :meth:`run` again
        from (X, u) holding each quantity on the bound it would leave.

        The free polish comes first because it moves least (its steps are of minimum
        norm); a point it takes past a bound would be refused by the verification, while
        the family of fixed points often goes on along the bound.
        """
        X_free, u_free, iterations, note = self.run(spec, X, u)
        if within(spec, np.concatenate([X_free, u_free])):
            return X_free, u_free, iterations, note
        return self.run(spec, X, u, hold_bounds=True)

    def run(self, spec: FixedPointSpec, X, u, within_bounds: bool = False,
            hold_bounds: bool = False) -> tuple[np.ndarray, np.ndarray, int, str]:
        """(X, u, iterations, note): the polished point, and a note (with a leading space)
        when the polish stopped before eps <= :data:`POLISH_EPS`.

        A step that falls or multiplies the residual's norm by :data:`POLISH_GROWTH` is
        halved: where the NLP's RK4 point is far from the exact map's manifold, a full step
        can overshoot into a fall. Gauss-Newton may raise the residual for a step before it
        falls quadratically, so smaller growth is accepted. With ``within_bounds``, a step
        that leaves the problem's bounds is halved too, before any stride is taken there
        (for callers that refuse such points anyway: an iterate at Kp = 1e6 N m/rad costs
        seconds a stride). With ``hold_bounds``, free quantities within IPOPT's relaxation
        of a bound, or past it, start on it, and a quantity that a step would take past
        its bound is put on it and held there for the remaining steps.
        """
        design = np.concatenate([X, u])
        # IPOPT relaxes bounds by ~1e-8, so fixed quantities come back slightly off: reset them.
        for i, name in enumerate(spec.design):
            if name in spec.fixed:
                design[i] = spec.fixed[name]
        lower, upper = np.array([spec.bounds_of(n) for n in spec.design]).T
        if hold_bounds:
            free = np.array([name not in spec.fixed for name in spec.design])
            design[free] = np.clip(onto_bounds(spec, design), lower, upper)[free]
        movable = movable_quantities(spec, design)
        energy_target = self.energy_target(spec, design[: APEX.size])
        nominal = np.array([NOMINAL[n] for n in spec.design])
        nx = APEX.size
        rows, fall = self._rows(spec, design, energy_target)
        if fall is not None:
            return design[:nx], design[nx:], 0, f" (polish stopped: {fall.value})"
        for iteration in range(POLISH_MAX_ITER + 1):
            X, u = design[:nx], design[nx:]
            if eps(X + rows[:nx], X) <= POLISH_EPS and np.all(np.abs(rows[nx:]) <= POLISH_EPS):
                return X, u, iteration, ""
            if iteration == POLISH_MAX_ITER or not movable.any():
                break
            scale = nominal[movable]
            step = np.linalg.lstsq(self.equations_jacobian(spec, X, u, energy_target)[:, movable] * scale, -rows,
                                   rcond=POLISH_RCOND)[0]
            fall, outside = None, False
            for _ in range(POLISH_BACKTRACKS + 1):
                trial = design.copy()
                trial[movable] += step * scale
                if hold_bounds:
                    leaving = movable & ((trial < lower) | (trial > upper))
                    trial = np.clip(trial, lower, upper)
                outside = within_bounds and not within(spec, trial)
                if not outside:
                    trial_rows, fall = self._rows(spec, trial, energy_target)
                    if fall is None and np.linalg.norm(trial_rows) < POLISH_GROWTH * np.linalg.norm(rows):
                        break
                step = step / 2
            else:
                reason = ("no step within the bounds" if outside else
                          f"a fall: {fall.value}" if fall is not None else "no step reduces the residual")
                return X, u, iteration, f" (polish stopped: {reason})"
            design, rows = trial, trial_rows
            if hold_bounds:
                movable &= ~leaving
        return design[:nx], design[nx:], POLISH_MAX_ITER, f" (polish reached {POLISH_MAX_ITER} iterations)"

    def energy(self, X, params) -> float:
        """Total mechanical energy at apex ``X`` [J]."""
        return float(self._energy(X, params.vector()))

    def energy_target(self, spec: FixedPointSpec, X) -> float | None:
        """The apex energy the polish must hold: the fixed value, or a bound IPOPT ended on."""
        if "energy" in spec.fixed:
            return spec.fixed["energy"]
        energy = self.energy(X, spec.params)
        for bound in spec.bounds.get("energy", ()):
            if np.isfinite(bound) and abs(energy - bound) <= 1e-7 * max(1.0, abs(bound)):
                return bound
        return None

    def _rows(self, spec: FixedPointSpec, design: np.ndarray, energy_target: float | None):
        """(r^N(X, u) - X with the energy row if the energy is held, or None; the fall)."""
        X, u = design[: APEX.size], design[APEX.size :]
        orbit = self.residual_map.simulate(X, u, spec.params, spec.strides)
        if orbit.fall is not None:
            return None, orbit.fall
        rows = [orbit.apexes[-1] - X]
        if energy_target is not None:
            rows.append([self.energy(X, spec.params) - energy_target])
        return np.concatenate(rows), None

    def equations_jacobian(self, spec: FixedPointSpec, X, u, energy_target: float | None) -> np.ndarray:
        """d(rows)/d(X, u): [dr/dX - I, dr/du], and the energy gradient row if held."""
        dr_dX, dr_du = self.jacobian_map.jacobians(X, u, spec.params, spec.strides)
        jac = np.hstack([dr_dX - np.eye(APEX.size), dr_du])
        if energy_target is None:
            return jac
        gradient = np.asarray(self._energy_gradient(X, spec.params.vector())).ravel()
        return np.vstack([jac, np.concatenate([gradient, np.zeros(len(u))])])


def within(spec: FixedPointSpec, design: np.ndarray) -> bool:
    """Whether every design quantity lies within its bounds (the problem's, inside the
    physical ones)."""
    return all(lo <= value <= hi for value, (lo, hi) in zip(design, map(spec.bounds_of, spec.design)))


def onto_bounds(spec: FixedPointSpec, design: np.ndarray) -> np.ndarray:
    """``design`` with every quantity within :data:`BOUND_RELAXATION` of a bound (either
    side, relative to max(1, |bound|)) put exactly on it."""
    design = design.copy()
    for i, name in enumerate(spec.design):
        for bound in spec.bounds_of(name):
            if np.isfinite(bound) and abs(design[i] - bound) <= BOUND_RELAXATION * max(1.0, abs(bound)):
                design[i] = bound
    return design


def movable_quantities(spec: FixedPointSpec, design: np.ndarray) -> np.ndarray:
    """Free design quantities not sitting on one of their bounds."""
    movable = np.ones(len(spec.design), dtype=bool)
    for i, name in enumerate(spec.design):
        lo, hi = spec.bounds_of(name)
        on_bound = min(abs(design[i] - lo), abs(design[i] - hi)) <= 1e-7 * NOMINAL[name]
        movable[i] = name not in spec.fixed and not on_bound
    return movable
