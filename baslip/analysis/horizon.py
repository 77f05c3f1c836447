"""Receding-horizon re-solve: at every apex, the controls of the next N strides are solved
so that the apex after N strides is the gait's, and the first of them is applied.

With dr/du of practical rank 3 (upright PD gaits) one stride cannot correct every apex
direction; two strides reach the fourth through the first stride's dr/dX. The unknowns are
the free entries of u_1 .. u_N, scaled by the controls' nominal sizes; the residual is
X_N - X*, scaled by the apex's. Each step is Levenberg-Marquardt with the chained AD
Jacobians dX_N/du_k = A_{N-1} ... A_{k+1} B_k. The warm start at the next apex is the tail
of the plan followed by u*: where the plan reached X*, its tail still does (X* is a fixed
point under u*), so the search starts on target. Each start's miss is taken by value
strides first, and a start already within :data:`HORIZON_EPS` is kept without a Jacobian.
Given a feedback gain K, the search has a second start: the plan that u* + K (X - X*)
would follow from X (at a highly unstable gait the constant plan falls within N strides,
and there is no Jacobian to start from). It descends from the start that misses X* less,
and from the other only when that descent ends short of :data:`HORIZON_EPS`; the better
end is kept (from the nearer start alone, a descent can end at a plan that never returns).
On a family of gaits (a neutral multiplier) no plan of N strides removes the miss along
the family, both descents end short at floors that it sets, and the plan that continues
the last one does better: there the tail is searched first and kept unless the other
start's end reaches the target (measured on the thesis-scale VPP gait, 30 starts per box:
83 % returned in the 1x and 4x boxes, against 63 % and 47 % keeping the end that misses
less). A descent stops when X_N is within :data:`HORIZON_EPS` of X* or a step gains less
than 1 %. Controls are kept inside their bounds. Apexes and controls are SI units and
radians.
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
        damping = 1e-6
        for step_number in range(self.steps):
            if value[0] <= HORIZON_EPS:
                break
            if step_number:  # the first step uses the Jacobian of the start's own pass
                found = self._linearised(X, plan)
                if found is None:
                    break
                jacobian = found[2]
            improved = stalled = False
            normal = jacobian.T @ jacobian
            for _ in range(12):  # Levenberg-Marquardt: raise the damping until a step helps
                step = np.linalg.solve(normal + damping * np.eye(len(normal)), -jacobian.T @ value[1])
                trial = self._moved(plan, step)
                trial_value = self._miss(X, trial)
                # Judged in the scaled residual that the steps minimise, not in eps.
                if np.linalg.norm(trial_value[1]) < np.linalg.norm(value[1]):
                    stalled = np.linalg.norm(trial_value[1]) > HORIZON_STALL * np.linalg.norm(value[1])
                    plan, value, improved = trial, trial_value, True
                    damping = max(damping / 10, 1e-12)
                    break
                damping *= 10
            if not improved or stalled:
                break
        return plan, value[0]

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
