"""Stride-to-stride controllers: the control u_n chosen at every apex X_n.

Three controllers, all with the same face (``control(X) -> (u, residual)``):

* :class:`ConstantControl`: the constant PD hip law of the thesis, u_n = u*;
* :class:`LinearFeedback`: event-based linear feedback u_n = u* + K (X_n - X*), the cheap
  "functional form" that the thesis's chapter 5 asks for. K comes from the AD Jacobians
  A = dr/dX and B = dr/du at the gait: deadbeat (A + B K = 0, :func:`deadbeat_gain`)
  where B has rank 4, discrete LQR (:func:`lqr_gain`) otherwise;
* :class:`ResolvedControl`: the thesis's sec. 4.7, u re-solved at every apex by
  Levenberg-Marquardt on a least-squares problem, either the thesis's criterion (the next
  apex as near as possible to the current one: ``criterion="thesis"``) or tracking (as
  near as possible to the target gait: ``criterion="tracking"``). A residual that stays
  is recorded, not an error: with B of rank 3 there is generally no exact solution.

Apexes and controls are SI units and radians; residuals are eps of eq. 4.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baslip.engine.returnmap import ReturnMap, RunnerFell
from baslip.gait.polish import eps
from baslip.model.dynamics import Params
from baslip.model.hiplaw import CONTROL
from baslip.model.quantities import NOMINAL

#: Relative singular-value cutoff for rank decisions on B (scaled by the nominal sizes).
#: Measured on the grids: B's fourth singular value is 1e-4 or more of the first where
#: it counts, and 1e-9 or less where it does not (upright gaits with gains near 1e-4).
RANK_TOLERANCE = 1e-7
CONTROL_SCALE = np.array([NOMINAL[n] for n in CONTROL.names])
#: A re-solve stops once a step lowers its eps by less than this factor (the residual
#: has reached the least-squares floor, which is not zero where dr/du has rank 3).
STALL = 0.99


def control_rank(B: np.ndarray) -> int:
    """Rank of dr/du in scaled controls."""
    s = np.linalg.svd(B * CONTROL_SCALE, compute_uv=False)
    return int(np.sum(s > RANK_TOLERANCE * s[0]))


def deadbeat_gain(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """K with A + B K = 0, the least-norm one in scaled controls (needs rank B = 4)."""
    if control_rank(B) < A.shape[0]:
        raise ValueError("deadbeat needs dr/du of rank 4")
    Bs = B * CONTROL_SCALE
    return CONTROL_SCALE[:, None] * (-np.linalg.pinv(Bs) @ A)


def lqr_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, iterations: int = 10000,
             tolerance: float = 1e-12) -> np.ndarray:
    """The discrete LQR gain K (u = K x) for x' = A x + B u with costs x'Qx + u'Ru, from
    the Riccati difference equation iterated to its fixed point; raises ValueError if it
    does not settle (the unstable modes are not reachable through B)."""
    P = Q.copy()
    for _ in range(iterations):
        gain = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        following = Q + A.T @ P @ (A - B @ gain)
        following = (following + following.T) / 2
        if np.max(np.abs(following - P)) <= tolerance * max(1.0, np.max(np.abs(P))):
            return -np.linalg.solve(R + B.T @ following @ B, B.T @ following @ A)
        if not np.all(np.isfinite(following)):
            break
        P = following
    raise ValueError("the Riccati iteration does not settle: an unstable mode is not reachable")


def closed_loop_multipliers(A: np.ndarray, B: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Eigenvalues of A + B K, the linearised closed-loop map."""
    return np.linalg.eigvals(A + B @ K)


@dataclass(frozen=True)
class ConstantControl:
    """u_n = u*: the constant PD hip law."""

    u_star: np.ndarray
    name: str = "constant PD"

    def control(self, X) -> tuple[np.ndarray, float]:
        return np.asarray(self.u_star, dtype=float), 0.0


@dataclass(frozen=True)
class LinearFeedback:
    """u_n = u* + K (X_n - X*), clipped to the controls' bounds."""

    X_star: np.ndarray
    u_star: np.ndarray
    K: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    name: str = "linear feedback"

    def control(self, X) -> tuple[np.ndarray, float]:
        u = self.u_star + self.K @ (np.asarray(X, dtype=float) - self.X_star)
        return np.clip(u, self.lower, self.upper), 0.0


class ResolvedControl:
    """u_n re-solved at every apex (thesis sec. 4.7), by Levenberg-Marquardt on
    || r(X_n, u) - target || over the controls, from the last control.

    ``criterion``: ``"thesis"`` aims the next apex at the current one (the thesis's "control
    parameters that best fit to the current state"), ``"tracking"`` at the gait X*.
    ``fixed``: indices of controls held at their u* values (e.g. theta2_dot_des, which acts
    only through c = Kp theta2_des + Kd theta2_dot_des).
    """

    name = "per-stride re-solve"

    def __init__(self, rmap: ReturnMap, params: Params, X_star, u_star, criterion: str = "thesis",
                 fixed: tuple[int, ...] = (), lower=None, upper=None, max_steps: int = 8, target_eps: float = 1e-12):
        if criterion not in ("thesis", "tracking"):
            raise ValueError(f"criterion must be 'thesis' or 'tracking', not {criterion!r}")
        self.rmap, self.params, self.criterion = rmap, params, criterion
        self.X_star, self.u_star = np.asarray(X_star, dtype=float), np.asarray(u_star, dtype=float)
        self.free = np.array([i for i in range(len(self.u_star)) if i not in fixed], dtype=int)
        self.lower = np.full(len(self.u_star), -np.inf) if lower is None else np.asarray(lower, dtype=float)
        self.upper = np.full(len(self.u_star), np.inf) if upper is None else np.asarray(upper, dtype=float)
        self.max_steps, self.target_eps = max_steps, target_eps
        self.last = self.u_star.copy()

    def control(self, X) -> tuple[np.ndarray, float]:
        """The control for apex ``X`` and the eps it leaves (the next apex against the
        target); the search starts from the last control returned."""
        X = np.asarray(X, dtype=float)
        target = X if self.criterion == "thesis" else self.X_star
        u, value = self.last.copy(), self._miss(X, self.last, target)
        damping = 1e-6
        for _ in range(self.max_steps):
            if value[0] <= self.target_eps:
                break
            try:
                B = self.rmap.jacobians(X, u, self.params)[1][:, self.free] * CONTROL_SCALE[self.free]
            except RunnerFell:
                break
            residual = value[1]
            improved = False
            for _ in range(12):  # Levenberg-Marquardt: raise the damping until a step helps
                step = np.linalg.solve(B.T @ B + damping * np.eye(len(self.free)), -B.T @ residual)
                trial = u.copy()
                trial[self.free] = np.clip(u[self.free] + step * CONTROL_SCALE[self.free],
                                           self.lower[self.free], self.upper[self.free])
                trial_value = self._miss(X, trial, target)
                if trial_value[0] < value[0]:
                    stalled = trial_value[0] > STALL * value[0]
                    u, value, improved = trial, trial_value, True
                    damping = max(damping / 10, 1e-12)
                    break
                damping *= 10
            if not improved or stalled:  # the least-squares floor is reached
                break
        self.last = u
        return u, value[0]

    def _miss(self, X, u, target) -> tuple[float, np.ndarray]:
        """(eps of the next apex against the target, the residual vector); inf on a fall."""
        stride = self.rmap.stride(X, u, self.params)
        if not stride.ok:
            return np.inf, np.full(len(X), np.inf)
        return eps(stride.apex, target) if self.criterion == "tracking" else eps(stride.apex, X), stride.apex - target


@dataclass(frozen=True)
class ClosedLoopRun:
    """A run under a controller: the apexes reached, the controls used, the residual each
    control solve left, and how it ended ('converged', 'fell' or 'bounded')."""

    apexes: np.ndarray
    controls: np.ndarray
    residuals: np.ndarray
    outcome: str
    strides_to_converge: int | None


def run_closed_loop(rmap: ReturnMap, params: Params, controller, X0, X_star, strides: int,
                    tolerance: float = 1e-6) -> ClosedLoopRun:
    """Run ``controller`` from apex ``X0`` for at most ``strides`` strides; it has
    converged when an apex comes within ``tolerance`` (eq. 4.1) of ``X_star``."""
    apexes, controls, residuals = [np.asarray(X0, dtype=float)], [], []
    X_star = np.asarray(X_star, dtype=float)
    for n in range(strides):
        u, residual = controller.control(apexes[-1])
        stride = rmap.stride(apexes[-1], u, params)
        controls.append(u)
        residuals.append(residual)
        if not stride.ok:
            return ClosedLoopRun(np.array(apexes), np.array(controls), np.array(residuals), "fell", None)
        assert stride.apex is not None  # a stride that did not fall reached its apex
        apexes.append(stride.apex)
        if eps(stride.apex, X_star) <= tolerance:
            return ClosedLoopRun(np.array(apexes), np.array(controls), np.array(residuals), "converged", n + 1)
    return ClosedLoopRun(np.array(apexes), np.array(controls), np.array(residuals), "bounded", None)
