"""Receding-horizon re-solve: at every apex, the controls of the next N strides are solved
so that the apex after N strides is the gait's, and the first of them is applied.

With dr/du of practical rank 3 (upright PD gaits) one stride cannot correct every apex
direction; two strides reach the fourth through the first stride's dr/dX. The unknowns
are the free entries of u_1 .. u_N, scaled by the controls' nominal sizes; the residual
is X_N - X*, scaled by the apex's. Each step is Levenberg-Marquardt with the chained AD
Jacobians dX_N/du_k = A_{N-1} ... A_{k+1} B_k, its damping set by Nielsen's rule, and
bent by geodesic acceleration (Transtrum and Sethna, 2012): at upright gaits the miss
lies in a curved valley (dX_N/du has singular values 1e5 apart), along which plain
damped steps gain about 10 % each and stop short; the acceleration, from one more value
pass, follows it. Measured at the shipped upright gait from 20 starts of the 1x box: the
plans reached X* (eps <= 1e-10) at 98 % of apexes, not 21 %, and the runs returned in
2.1 strides, not 9.5. The warm start at the next apex is the tail of the plan followed
by u*: where the plan reached X*, its tail still does (X* is a fixed point under u*), so
the search starts on target. Each start's miss is taken by value strides first, and a
start already within :data:`HORIZON_EPS` is kept without a Jacobian. Given a feedback
gain K, the search has a second start: the plan that u* + K (X - X*) would follow from X
(at a highly unstable gait the constant plan falls within N strides, and there is no
Jacobian to start from). It descends from the start that misses X* less, and from the
other only when that descent ends short of :data:`HORIZON_EPS`; the better end is kept
(from the nearer start alone, a descent can end at a plan that never returns). On a
family of gaits (a neutral multiplier) no plan of N strides removes the miss along the
family, both descents end short at floors that it sets, and the plan that continues the
last one does better: there the tail is searched first and kept unless the other start's
end reaches the target (measured on the thesis-scale VPP gait with damped steps alone,
30 starts per box: 83 % returned in the 1x and 4x boxes, against 63 % and 47 % keeping
the end that misses less; with the acceleration all of every box returns). A descent
stops when X_N is within :data:`HORIZON_EPS` of X* or a step gains less than 1 %.
Controls are kept inside their bounds. Apexes and controls are SI units and radians.
"""

from __future__ import annotations

import numpy as np

from baslip.analysis.feedback import control_scale
from baslip.engine.returnmap import ReturnMap, RunnerFell
from baslip.gait.polish import eps
from baslip.model.dynamics import APEX, Params
from baslip.model.quantities import NOMINAL

#: Levenberg-Marquardt steps per apex, and the eps of X_N at which a plan is good enough.
HORIZON_STEPS = 30
HORIZON_EPS = 1e-10
#: A step that lowers the plan's eps by less than this factor ends the search.
HORIZON_STALL = 0.99
APEX_SCALE = np.array([NOMINAL[n] for n in APEX.names])
#: Damping raises tried at most per step.
DAMPING_TRIALS = 12
#: The geodesic acceleration's probe, as a fraction of the step, and the largest ratio of
#: twice the acceleration to the step at which it is taken (Transtrum and Sethna's alpha).
GEODESIC_PROBE = 0.1
GEODESIC_RATIO = 0.75


class Damping:
    """Levenberg-Marquardt's damping of one descent, updated by Nielsen's rule: after a
    step that achieved the share ``rho`` of its predicted gain, it is scaled by
    max(1/3, 1 - (2 rho - 1)^3); after a failed step it is raised by a factor that doubles
    at each failure in a row (2, 4, 8, ...)."""

    def __init__(self, value: float = 1e-3):
        self.value, self._raise = value, 2.0

    def succeeded(self, rho: float) -> None:
        self.value *= max(1 / 3, 1 - (2 * min(rho, 1.0) - 1) ** 3)
        self._raise = 2.0

    def failed(self) -> None:
        self.value *= self._raise
        self._raise *= 2


class RecedingHorizon:
    """The N-stride re-solve controller (``control(X) -> (u, eps of the plan's X_N)``).

    Parameters
    ----------
    rmap : ReturnMap
        The map the plan is solved on (its hip law gives the controls).
    params : Params
        The runner's parameters.
    X_star, u_star : array_like
        The gait's apex and control.
    horizon : int
        N >= 1, the strides planned at every apex.
    fixed : tuple of int
        Indices of controls held at u* (e.g. theta2_dot_des, which acts only with theta2_des).
    lower, upper : array_like, optional
        The controls' bounds.
    K : array_like, optional
        A feedback gain (controls x apex) whose plan is the search's other start.
    steps : int
        Levenberg-Marquardt steps at most per apex.
    family : bool
        Whether the gait lies on a family of gaits (a neutral multiplier, as the VPP law's
        symmetric gaits have): then the search descends from the tail first, and keeps the
        other start's end only where it reaches the target.
    """

    def __init__(self, rmap: ReturnMap, params: Params, X_star, u_star, horizon: int = 2, fixed: tuple[int, ...] = (),
                 lower=None, upper=None, K=None, steps: int = HORIZON_STEPS, family: bool = False):
        if horizon < 1:
            raise ValueError(f"the horizon is at least 1 stride, not {horizon}")
        self.rmap, self.params, self.horizon = rmap, params, horizon
        self.name = f"receding horizon, {horizon} strides"
        self.X_star, self.u_star = np.asarray(X_star, dtype=float), np.asarray(u_star, dtype=float)
        n_u = len(self.u_star)
        self.free = np.array([i for i in range(n_u) if i not in fixed], dtype=int)
        self.scale = control_scale(rmap.law)[self.free]
        self.lower = np.full(n_u, -np.inf) if lower is None else np.asarray(lower, dtype=float)
        self.upper = np.full(n_u, np.inf) if upper is None else np.asarray(upper, dtype=float)
        self.plan = np.tile(self.u_star, (horizon, 1))
        self.K = None if K is None else np.asarray(K, dtype=float)
        self.steps, self.family = steps, family

    def control(self, X) -> tuple[np.ndarray, float]:
        """The first control of the plan solved from apex ``X``, and the eps its X_N leaves."""
        X = np.asarray(X, dtype=float)
        starts = [self.plan] + ([] if self.K is None else [self._feedback_plan(X)])
        candidates = [(start, self._miss(X, start)) for start in starts]
        if not self.family:
            candidates.sort(key=lambda candidate: candidate[1][0])
        best = None
        for start, miss in candidates:  # the first start's descent, and the other's if that ends short
            found = self._descend(X, start, miss)
            if found is not None and (best is None or self._preferred(found, best, start is self.plan)):
                best = found
            if best is not None and best[1] <= HORIZON_EPS:
                break
        if best is None:
            self.plan = np.tile(self.u_star, (self.horizon, 1))
            return self.u_star.copy(), np.inf
        plan, eps_reached = best
        self.plan = np.vstack([plan[1:], self.u_star])  # the warm start of the next apex: the plan's tail
        return plan[0], eps_reached

    def _preferred(self, found: tuple[np.ndarray, float], best: tuple[np.ndarray, float], from_tail: bool) -> bool:
        """Whether the end ``found`` replaces ``best`` (the end of the descent before it):
        the one that misses less; on a family of gaits, the tail's end unless the other
        reaches the target."""
        if self.family and not from_tail:
            return found[1] <= HORIZON_EPS
        return found[1] < best[1]

    def _descend(self, X: np.ndarray, start: np.ndarray, miss: tuple[float, np.ndarray]) -> tuple[np.ndarray, float] | None:
        """Levenberg-Marquardt on the plan from ``start``, whose :meth:`_miss` is ``miss``:
        (the plan it ends at, the eps of its X_N), or None when the start itself falls
        within the horizon. A start already within :data:`HORIZON_EPS` is its own end, and
        costs no Jacobian (near the gait, every apex's)."""
        if not np.isfinite(miss[0]):
            return None
        if miss[0] <= HORIZON_EPS:
            return start, miss[0]
        linearised = self._linearised(X, start)
        if linearised is None:
            return None
        plan, value, jacobian = linearised
        damping = Damping()
        for step_number in range(self.steps):
            if value[0] <= HORIZON_EPS:
                break
            if step_number:  # the first step uses the Jacobian of the start's own pass
                found = self._linearised(X, plan)
                if found is None:
                    break
                jacobian = found[2]
            taken = self._step(X, plan, value, jacobian, damping)
            if taken is None:
                break
            plan, value, stalled = taken
            if stalled:
                break
        return plan, value[0]

    def _step(self, X: np.ndarray, plan: np.ndarray, value: tuple[float, np.ndarray], jacobian: np.ndarray,
              damping: Damping) -> tuple[np.ndarray, tuple[float, np.ndarray], bool] | None:
        """One Levenberg-Marquardt step with geodesic acceleration from ``plan``: (the new
        plan, its miss, whether it gained less than :data:`HORIZON_STALL`), or None when no
        damping up to :data:`DAMPING_TRIALS` raises finds a step that lowers the miss.
        Steps are judged in the scaled residual that they minimise, not in eps."""
        residual = value[1]
        normal, gradient = jacobian.T @ jacobian, jacobian.T @ residual
        for _ in range(DAMPING_TRIALS):
            damped = normal + damping.value * np.eye(len(normal))
            velocity = np.linalg.solve(damped, -gradient)
            step = velocity + self._acceleration(X, plan, residual, jacobian, damped, velocity)
            trial = self._moved(plan, step)
            trial_value = self._miss(X, trial)
            if np.linalg.norm(trial_value[1]) < np.linalg.norm(residual):
                predicted = residual @ residual - np.sum((residual + jacobian @ velocity) ** 2)
                damping.succeeded((residual @ residual - trial_value[1] @ trial_value[1]) / max(predicted, 1e-300))
                return trial, trial_value, np.linalg.norm(trial_value[1]) > HORIZON_STALL * np.linalg.norm(residual)
            damping.failed()
        return None

    def _acceleration(self, X: np.ndarray, plan: np.ndarray, residual: np.ndarray, jacobian: np.ndarray,
                      damped: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """The geodesic acceleration of the step ``velocity`` (Transtrum and Sethna, 2012):
        the second directional derivative of the residual along it, from one probe at
        :data:`GEODESIC_PROBE` of its length, bends the step along the curved valley of
        the miss. Zero where the probe falls, or where it would exceed
        :data:`GEODESIC_RATIO` of the step (the second-order model is not to be trusted)."""
        probe = self._miss(X, self._moved(plan, GEODESIC_PROBE * velocity))
        if not np.isfinite(probe[0]):
            return np.zeros_like(velocity)
        curvature = 2 / GEODESIC_PROBE * ((probe[1] - residual) / GEODESIC_PROBE - jacobian @ velocity)
        acceleration = -0.5 * np.linalg.solve(damped, jacobian.T @ curvature)
        if 2 * np.linalg.norm(acceleration) > GEODESIC_RATIO * np.linalg.norm(velocity):
            return np.zeros_like(velocity)
        return acceleration

    def _feedback_plan(self, X: np.ndarray) -> np.ndarray:
        """The controls u* + K (X_k - X*) along the strides they lead to from ``X`` (u*
        after a fall), inside the bounds."""
        assert self.K is not None
        plan = []
        for _ in range(self.horizon):
            u = np.clip(self.u_star + self.K @ (X - self.X_star), self.lower, self.upper)
            plan.append(u)
            stride = self.rmap.stride(X, u, self.params)
            X = stride.apex if stride.ok and stride.apex is not None else self.X_star
        return np.array(plan)

    def _moved(self, plan: np.ndarray, step: np.ndarray) -> np.ndarray:
        moved = plan.copy()
        moved[:, self.free] += step.reshape(self.horizon, len(self.free)) * self.scale
        return np.clip(moved, self.lower, self.upper)

    def _miss(self, X: np.ndarray, plan: np.ndarray) -> tuple[float, np.ndarray]:
        """(eps of X_N against X*, the scaled residual); inf on a fall."""
        for u in plan:
            stride = self.rmap.stride(X, u, self.params)
            if not stride.ok or stride.apex is None:
                return np.inf, np.full(APEX.size, np.inf)
            X = stride.apex
        return eps(X, self.X_star), (X - self.X_star) / APEX_SCALE

    def _linearised(self, X: np.ndarray, plan: np.ndarray):
        """(plan, its miss as :meth:`_miss` gives it, d(scaled X_N) / d(scaled free
        controls of every stride)) from one pass of Jacobian strides; None on a fall."""
        steps = []
        try:
            for u in plan:
                A, B, X = self.rmap.linearised_stride(X, u, self.params)
                steps.append((A, B[:, self.free] * self.scale))
        except RunnerFell:
            return None
        blocks: list[np.ndarray] = []
        carried = np.eye(APEX.size)
        for A, B in reversed(steps):  # dX_N/du_k = A_{N-1} ... A_{k+1} B_k
            blocks.insert(0, carried @ B)
            carried = carried @ A
        miss = (eps(X, self.X_star), (X - self.X_star) / APEX_SCALE)
        return plan, miss, np.hstack(blocks) / APEX_SCALE[:, None]
