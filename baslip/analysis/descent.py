"""Stability-optimal gaits: the least spectral radius on the fixed-point manifold.

The fixed points of a problem (its fixed quantities held) form a manifold; which point a
solve returns depends on the objective and the guess. Here we descend on the manifold to
the gait whose multipliers are smallest.

**Objective.** The spectral radius rho = max |mu_i| is not differentiable where the
largest multiplier changes or a pair coalesces. We minimise the smooth surrogate

    phi = log( sum_i |mu_i|^(2q) ) / (2q),   q = :data:`SURROGATE_POWER`,

the log of the 2q-norm of the non-trivial multipliers: log rho <= phi <= log rho +
log(4) / (2q), i.e. exp(phi) is within 9 % of rho for q = 8, and phi is smooth wherever
the multipliers are simple. (A log-sum-exp of |mu|^2 behaves the same; the norm form keeps
the bound independent of the size of rho, which spans 0.1 to 1e3 here.)

**Gradient.** An eigenvalue's derivative is dmu_i = u_i dA v_i, with v_i the right
eigenvector and u_i the matching row of V^-1 (the left eigenvector with u_i v_i = 1). So
dphi = <G, dA> for a real 4 x 4 seed G (:func:`surrogate`), and the gradient of phi in
(X, u) is the gradient of <G, dr/dX (X, u)>: one reverse sweep through the AD Jacobian
of the compiled stride, i.e. exact second derivatives of the map
(:meth:`baslip.engine.returnmap.ReturnMap.jacobian_gradient`).

**Descent.** The manifold is charted by some of its free quantities, chosen so that the
equations can be solved well for the others (greedy column pivoting of their Jacobian).
On the chart, phi is an ordinary function: a point is the fixed point with the chart
quantities held (the Newton polish solves for the rest), and its gradient follows by the
implicit-function theorem. BFGS with an Armijo line search minimises it; the line search
backtracks, and lengthens a step along which phi is straight or concave (where BFGS learns
no curvature and its step is the bare gradient's); a degenerate chart is replaced. Where
phi stops falling (a kink of rho, where two multipliers of equal modulus meet), a compass
search on rho itself goes on. Every accepted point is a fixed point of the compiled map to
eps <= 1e-12; the caller verifies the end point independently.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from baslip.analysis.compass import CompassSettings, compass_search
from baslip.engine.returnmap import NoSecondDerivatives, ReturnMap, RunnerFell
from baslip.gait.fixedpoint import FixedPointResult, FixedPointSolver
from baslip.gait.polish import Polish, eps, movable_quantities
from baslip.gait.shooting import FixedPointSpec
from baslip.gait.stability import classify
from baslip.model.dynamics import APEX
from baslip.model.quantities import design_names, nominal

#: q of the surrogate (see the module docstring).
SURROGATE_POWER = 8
#: The apex's share of a design vector (X, u): the rest are the law's controls.
NX = APEX.size
#: Armijo constant, largest step (scaled units), halvings per iteration, and the
#: reduced-gradient norm and step length at which the descent stops.
ARMIJO = 1e-4
MAX_STEP = 2.0
HALVINGS = 10
#: Largest condition number of the equations' Jacobian in the quantities that follow the
#: chart, before another chart is chosen.
MAX_CHART_CONDITION = 1e8
GRADIENT_TOLERANCE = 1e-7
#: A line search's first trial, accepted, is lengthened only if it lowered phi by at least
#: this share of the slope's prediction: then phi is nearly straight (or concave) along the
#: direction, and a quadratic through the two values and the slope puts its minimum at five
#: times the length or beyond.
EXTEND_RATIO = 0.9
STEP_TOLERANCE = 1e-9
#: The compass search's steps (scaled units) and trial budget.
COMPASS = CompassSettings(first_step=0.05, largest_step=0.4, last_step=1e-6, trials=600)


def surrogate(dr_dX: np.ndarray, trivial: np.ndarray | None = None, q: int = SURROGATE_POWER) -> tuple[float, np.ndarray]:
    """(phi, G): the surrogate of the multipliers of ``dr_dX`` and its gradient with
    respect to the entries of dr/dX (so dphi = sum(G * dA)). ``trivial`` marks
    multipliers to leave out (structural ones)."""
    mu, V = np.linalg.eig(np.asarray(dr_dX, dtype=float))
    U = np.linalg.inv(V)  # row i: left eigenvector with U[i] @ V[:, i] = 1
    keep = np.ones(len(mu), dtype=bool) if trivial is None else ~np.asarray(trivial)
    modulus = np.abs(mu)
    scale = modulus[keep].max()  # work with mu / scale: no overflow for large q
    terms = np.where(keep, (modulus / scale) ** (2 * q), 0.0)
    total = terms.sum()
    phi = float(np.log(scale) + np.log(total) / (2 * q))
    # d phi = sum_i |mu_i|^(2q-2) Re(conj(mu_i) dmu_i) / S, with dmu_i = U[i] dA V[:, i].
    weight = np.where(keep, (modulus / scale) ** (2 * q - 2) / scale**2, 0.0) / total
    coefficient = weight * np.conj(mu)
    G = np.real(U.T @ np.diag(coefficient) @ V.T)
    return phi, G


@dataclass(frozen=True)
class DescentStep:
    """One accepted point of a descent."""

    X: np.ndarray
    u: np.ndarray
    spectral_radius: float
    surrogate: float


@dataclass(frozen=True)
class Descent:
    """Where a descent went: its accepted points (the first is the start) and why it ended."""

    steps: tuple[DescentStep, ...]
    stop_reason: str
    gradient_norm: float = float("nan")
    evaluations: int = 0

    @property
    def best(self) -> DescentStep:
        """The accepted point of least spectral radius (BFGS lowers the surrogate, which
        may let rho itself rise slightly on a step)."""
        return min(self.steps, key=lambda step: step.spectral_radius)


class StabilityDescent:
    """Quasi-Newton descent of the multipliers' surrogate on the fixed-point manifold."""

    def __init__(self, rmap: ReturnMap, max_iterations: int = 60, compass_trials: int = COMPASS.trials):
        """``rmap``: the compiled map whose strides, Jacobians and second derivatives the
        descent takes (:meth:`~baslip.engine.returnmap.ReturnMap.jacobian_gradient`: a
        library of the map's, compiled on first use, about 80 s, then cached);
        ``max_iterations`` quasi-Newton steps at most, then a compass search of at most
        ``compass_trials`` trials."""
        self.rmap, self.max_iterations = rmap, max_iterations
        self.compass = replace(COMPASS, trials=compass_trials)
        self.polish = Polish(rmap, rmap)

    def _scale(self, spec: FixedPointSpec) -> np.ndarray:
        """The scaled units of the design quantities: their nominal scales at the body."""
        return np.array([nominal(n, spec.params) for n in design_names(self.rmap.law)])

    # -- the objective ---------------------------------------------------------------------

    def evaluate(self, spec: FixedPointSpec, X, u) -> tuple[float, float, np.ndarray]:
        """(spectral radius, phi, gradient of phi in (X, u)) at a fixed point."""
        radius, phi, G = self.surrogate_at(spec, X, u)
        return radius, phi, self.gradient(X, u, spec, G)

    def surrogate_at(self, spec: FixedPointSpec, X, u) -> tuple[float, float, np.ndarray]:
        """(spectral radius, phi, G) at a fixed point, from first derivatives only; G is
        phi's gradient in the entries of dr/dX, which :meth:`gradient` takes."""
        dr_dX, _ = self.rmap.jacobians(X, u, spec.params)
        stability = classify(dr_dX, spec.params, u, spec.law)
        trivial = np.array([m.trivial for m in stability.multipliers])
        phi, G = surrogate(dr_dX, trivial)
        return stability.spectral_radius, phi, G

    def gradient(self, X, u, spec: FixedPointSpec, G: np.ndarray) -> np.ndarray:
        """The gradient of <G, dr/dX> in (X, u), by AD second derivatives of the stride."""
        return self.rmap.jacobian_gradient(X, u, spec.params, G)[: NX + self.rmap.law.controls.size]

    # -- the descent -----------------------------------------------------------------------

    def run(self, spec: FixedPointSpec, X, u) -> Descent:
        """Descend from the fixed point (X, u) of ``spec`` (one-stride gaits): ``X`` the apex
        [m, rad, m/s, rad/s] and ``u`` the control of the spec's hip law [SI, rad].

        The manifold is charted by some of its free quantities (:meth:`_chart`); the rest
        follow from the fixed-point equations (the polish with the chart held). On the
        chart, phi is an ordinary function whose gradient comes by the implicit-function
        theorem, and BFGS with a backtracking (Armijo) line search minimises it. When no
        step lowers phi, its reduced gradient vanishes, or after ``max_iterations``, a
        compass search on the spectral radius itself goes on (:meth:`_pattern_search`).
        Where the start has no second derivatives (the compiled engine cannot vouch for its
        stride, as at gaits whose trunk swings far and fast), the compass search is all
        there is.
        """
        if spec.strides != 1:
            raise ValueError("the stability descent handles one-stride gaits")
        if spec.law is not self.rmap.law:
            raise ValueError(f"this descent is built for hip law {self.rmap.law.name}, not {spec.law.name}")
        design = np.concatenate([X, u]).astype(float)
        try:
            radius, phi, grad = self.evaluate(spec, design[:NX], design[NX:])
        except NoSecondDerivatives:
            return self._compass_only(spec, design)
        steps = [DescentStep(design[:NX].copy(), design[NX:].copy(), radius, phi)]
        evaluations, chart, norm, stretch = 1, None, float("nan"), 1.0
        known: np.ndarray | None = None  # the reduced gradient here, where the last pass found it
        for _ in range(self.max_iterations):
            if chart is None:
                chart, fresh_chart = self._chart(spec, design), True
                if not chart.size:
                    return Descent(tuple(steps), "the manifold has no free direction here", 0.0, evaluations)
                inverse_hessian = np.eye(chart.size)
            reduced = known if known is not None else self._reduced_gradient(spec, design, grad, chart)
            known = None
            if reduced is None:  # the chart degenerated here: choose another, once
                if fresh_chart:
                    break
                chart = None
                continue
            fresh_chart = False
            norm = float(np.linalg.norm(reduced))
            if norm < GRADIENT_TOLERANCE:
                # Stationary for the surrogate, which need not be a minimum of rho (at a
                # kink where multipliers coalesce): the compass search on rho goes on.
                return self._compass_after(spec, steps, "stationary: reduced gradient below tolerance; ", norm,
                                           evaluations)
            direction = -inverse_hessian @ reduced
            if direction @ reduced >= 0:
                inverse_hessian, direction = np.eye(chart.size), -reduced
            # Only a bare gradient step (no curvature learnt yet) may be lengthened: a BFGS
            # step's own length already carries what the updates learnt.
            bare = bool(np.array_equal(inverse_hessian, np.eye(chart.size)))
            try:
                found = self._line_search(spec, design, chart, direction, reduced, phi, stretch, bare)
            except NoSecondDerivatives:  # the step's end has no gradient: the compass search goes on
                return self._compass_after(spec, steps, "no second derivatives at a step's end; ", norm, evaluations)
            evaluations += found[-1]
            stretch = 1.0
            if found[0] is None:
                if not np.allclose(inverse_hessian, np.eye(chart.size)):
                    inverse_hessian, known = np.eye(chart.size), reduced  # retry along the gradient
                    continue
                break
            trial, t_radius, t_phi, t_grad, length, _ = found
            s = (trial[chart] - design[chart]) / self._scale(spec)[chart]
            t_reduced = self._reduced_gradient(spec, trial, t_grad, chart)
            design, radius, phi, grad = trial, t_radius, t_phi, t_grad
            steps.append(DescentStep(design[:NX].copy(), design[NX:].copy(), radius, phi))
            if t_reduced is None:
                chart = None
                continue
            known, y = t_reduced, t_reduced - reduced
            if s @ y > 1e-12 * np.linalg.norm(s) * np.linalg.norm(y):
                inverse_hessian = _bfgs(inverse_hessian, s, y)
            elif length > 1.0:
                # No curvature to learn from (phi straight or concave along the step), and
                # the search lengthened the step: the next direction is scaled as this one
                # was, so the next search starts at the length this one reached.
                stretch = length
            if np.max(np.abs(s)) < STEP_TOLERANCE:
                break
        else:
            return self._compass_after(spec, steps, f"reached {self.max_iterations} iterations; ", norm, evaluations)
        # The surrogate stopped falling: typically where two multipliers of nearly equal
        # modulus coalesce, a kink of rho that a gradient cannot cross. A compass search on
        # rho itself goes on from there.
        return self._compass_after(spec, steps, "", norm, evaluations)

    def _compass_after(self, spec: FixedPointSpec, steps: list[DescentStep], why: str, norm: float,
                       evaluations: int) -> Descent:
        """The descent ``steps`` followed by the compass search on the radius from the last
        of them, its stop reason after ``why``."""
        last = steps[-1]
        found, searched, compass = self._pattern_search(spec, np.concatenate([last.X, last.u]), last.spectral_radius)
        return Descent(tuple(steps + found), f"{why}{compass}", norm, evaluations + searched)

    def _compass_only(self, spec: FixedPointSpec, design) -> Descent:
        """The descent where the start has no second derivatives (the compiled engine
        cannot vouch for its stride, so the surrogate has no gradient): the compass search
        on the spectral radius alone, which needs first derivatives only."""
        dr_dX, _ = self.rmap.jacobians(design[:NX], design[NX:], spec.params)
        start = _step_at(design, dr_dX, spec)
        found, searched, compass = self._pattern_search(spec, design, start.spectral_radius)
        return Descent((start, *found), f"{compass} (no second derivatives at the start)", float("nan"), 1 + searched)

    def _line_search(self, spec, design, chart, direction, reduced, phi, first: float = 1.0,
                     lengthen: bool = False):
        """(point, radius, phi, gradient, length, evaluations) of a step along ``direction``
        (chart coordinates, scaled) with enough decrease (Armijo), (None, ..., evaluations)
        if there is none. The first trial's length is ``first`` times the direction (capped
        so that no coordinate moves more than MAX_STEP); it is halved until a trial is
        accepted. With ``lengthen`` (a bare gradient direction), a first trial accepted at
        once is doubled while that lowers phi further: where phi is straight or concave
        along the direction, BFGS learns no curvature, the direction stays the bare reduced
        gradient, and its unit step is short (0.015 scaled units a step, 396 steps in a row,
        at a hanging gait of atlas_downward)."""
        cap = MAX_STEP / max(np.max(np.abs(direction)), 1e-300)
        length, evaluations = min(first, cap), 0
        slope = float(direction @ reduced)
        # A search that starts longer than the unit step may halve down to where a unit
        # start would have ended.
        for halving in range(HALVINGS + max(0, math.ceil(math.log2(max(first, 1.0))))):
            if length * np.max(np.abs(direction)) < STEP_TOLERANCE:
                break
            taken = self._trial(spec, design, chart, direction, length, phi, slope)
            evaluations += taken is not None
            if taken is not None and taken[0] is not None:
                if lengthen and halving == 0 and phi - taken[2] >= -EXTEND_RATIO * length * slope:
                    taken, length, more = self._extended(spec, design, chart, direction, length, cap, phi, slope, taken)
                    evaluations += more
                trial, t_radius, t_phi, G = taken
                # Second derivatives only where a trial is taken: a turned-down trial's
                # gradient (a reverse sweep through the stride's Jacobian, several Jacobians'
                # cost) would go unused.
                return trial, t_radius, t_phi, self.gradient(trial[:NX], trial[NX:], spec, G), length, evaluations
            length /= 2
        return None, None, None, None, None, evaluations

    def _extended(self, spec, design, chart, direction, length, cap, phi, slope, taken):
        """(the accepted trial, its length, trials made): ``taken`` at ``length``, or the
        trial at a doubled length, doubled again while each keeps Armijo's decrease and
        lowers phi further, up to ``cap``."""
        made = 0
        while length < cap:
            longer = min(2 * length, cap)
            further = self._trial(spec, design, chart, direction, longer, phi, slope)
            made += further is not None
            if further is None or further[0] is None or further[2] >= taken[2]:
                break
            taken, length = further, longer
        return taken, length, made

    def _trial(self, spec, design, chart, direction, length, phi, slope):
        """The point ``length`` times ``direction`` away, pulled back onto the manifold, with
        its (radius, phi, G): None where it cannot be placed, (None, ...) where it falls,
        has no second derivatives or lacks Armijo's decrease."""
        values = design[chart] + length * direction * self._scale(spec)[chart]
        trial = self._retract(spec, design, chart, values)
        if trial is None:
            return None
        try:
            t_radius, t_phi, G = self.surrogate_at(spec, trial[:NX], trial[NX:])
        except (RunnerFell, NoSecondDerivatives):
            return None, None, None, None
        if t_phi > phi + ARMIJO * length * slope:
            return None, None, None, None
        return trial, t_radius, t_phi, G

    def _free(self, spec: FixedPointSpec, design) -> np.ndarray:
        """Indices of the free quantities not held on a bound."""
        return np.nonzero(movable_quantities(spec, design))[0]

    def _constraints(self, spec: FixedPointSpec, design) -> np.ndarray:
        """The fixed-point equations' Jacobian in the scaled design quantities (nine under
        PD, six under VPP)."""
        energy_target = self.polish.energy_target(spec, design[:NX])
        return self.polish.equations_jacobian(spec, design[:NX], design[NX:], energy_target) * self._scale(spec)

    def _chart(self, spec: FixedPointSpec, design) -> np.ndarray:
        """Chart quantities: the free ones left after picking, column by column (greedy
        pivoting), the best-conditioned set of free quantities to solve the equations for."""
        free = self._free(spec, design)
        C = self._constraints(spec, design)[:, free]
        dependent: list[int] = []
        residual = C.copy()
        for _ in range(min(C.shape)):
            norms = np.linalg.norm(residual, axis=0)
            norms[dependent] = -1
            pick = int(np.argmax(norms))
            if norms[pick] <= 1e-9 * np.linalg.norm(C, 2):
                break
            dependent.append(pick)
            column = residual[:, pick] / norms[pick]
            residual = residual - np.outer(column, column @ residual)
        return np.array([free[i] for i in range(len(free)) if i not in dependent], dtype=int)

    def _reduced_gradient(self, spec, design, grad, chart) -> np.ndarray | None:
        """d phi / d (chart quantities, scaled), the others following the equations; None
        if they cannot (the chart is singular here)."""
        free = self._free(spec, design)
        rest = np.array([i for i in free if i not in chart], dtype=int)
        C = self._constraints(spec, design)
        g = grad * self._scale(spec)
        if not rest.size:
            return g[chart]
        C_rest = C[:, rest]
        if np.linalg.cond(C_rest) > MAX_CHART_CONDITION:
            return None
        follow = -np.linalg.lstsq(C_rest, C[:, chart], rcond=None)[0]  # d rest / d chart
        return g[chart] + follow.T @ g[rest]

    def _pattern_search(self, spec: FixedPointSpec, design, radius) -> tuple[list[DescentStep], int, str]:
        """Compass search (:mod:`baslip.analysis.compass`) on the spectral radius in the
        scaled chart quantities, each trial pulled back onto the manifold. Returns the
        accepted points, the trial count and why it stopped."""
        chart = self._chart(spec, design)

        def move(point, displacement):
            trial = self._retract(spec, point, chart, point[chart] + displacement * self._scale(spec)[chart])
            if trial is None:
                return None
            try:
                dr_dX, _ = self.rmap.jacobians(trial[:NX], trial[NX:], spec.params)
            except RunnerFell:
                return np.inf, trial, None
            here = _step_at(trial, dr_dX, spec)
            return here.spectral_radius, trial, here

        found = compass_search(move, design, radius, chart.size, self.compass)
        stop = ("compass search on the spectral radius converged" if found.converged
                else f"compass search on the spectral radius reached {self.compass.trials} trials")
        return list(found.accepted), found.trials, stop

    def _retract(self, spec: FixedPointSpec, design, chart, values) -> np.ndarray | None:
        """The fixed point with the chart quantities at ``values`` (clipped into their
        bounds), the others solved from the equations by the polish; None if that fails
        or leaves a bound."""
        held = dict(spec.fixed)
        for i, value in zip(chart, values):
            lo, hi = spec.bounds_of(spec.design[i])
            held[spec.design[i]] = float(min(max(value, lo), hi))
        start = design.copy()
        for i in chart:
            start[i] = held[spec.design[i]]
        X, u, _, note = self.polish.run(replace(spec, fixed=held), start[:NX], start[NX:], within_bounds=True)
        if note:
            return None
        point = np.concatenate([X, u])
        stride = self.rmap.stride(X, u, spec.params)
        if not stride.ok or eps(stride.apex, X) > 1e-12:
            return None
        return point


def _step_at(design: np.ndarray, dr_dX: np.ndarray, spec: FixedPointSpec) -> DescentStep:
    """The descent's record of the fixed point ``design`` whose return-map Jacobian is
    ``dr_dX``: its spectral radius and surrogate (structural multipliers left out)."""
    stability = classify(dr_dX, spec.params, design[NX:], spec.law)
    trivial = np.array([m.trivial for m in stability.multipliers])
    return DescentStep(design[:NX].copy(), design[NX:].copy(), stability.spectral_radius, surrogate(dr_dX, trivial)[0])


def _bfgs(H: np.ndarray, s: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The BFGS update of an inverse Hessian approximation."""
    rho = 1.0 / float(s @ y)
    V = np.eye(len(s)) - rho * np.outer(s, y)
    return V @ H @ V.T + rho * np.outer(s, s)


@dataclass(frozen=True)
class OptimalGait:
    """One start of the search: the drawn gains, the fixed point solved with them held,
    the descent from there (gains free) and the independently verified end point (None
    where a stage did not happen)."""

    held: dict
    start: FixedPointResult
    descent: Descent | None = None
    end: FixedPointResult | None = None
    note: str = ""


def optimise_from(solver: FixedPointSolver, descent: StabilityDescent, spec: FixedPointSpec, held: dict,
                  name: str = "problem") -> OptimalGait:
    """Solve ``spec`` with the quantities ``held`` fixed, descend from that gait (with them
    free again) to the least spectral radius nearby, and verify where the descent ended
    with the solver's own checks."""
    start = solver.solve(replace(spec, fixed={**spec.fixed, **held}), name=name)
    if not start.converged:
        return OptimalGait(held, start, note=f"no starting fixed point: {start.message}")
    try:
        found = descent.run(spec, start.X, start.u)
    except (RunnerFell, NoSecondDerivatives) as err:
        return OptimalGait(held, start, end=start, note=f"no descent: {err}")
    end = solver.verify_point(spec, found.best.X, found.best.u, name)
    return OptimalGait(held, start, found, end, found.stop_reason)
