"""Stride-to-stride controllers: the control u_n chosen at every apex X_n.

Controllers with the same face (``control(X) -> (u, residual)``), for any hip law's
controls (scaled by :func:`control_scale`):

* :class:`ConstantControl`: the constant hip law (the thesis's PD), u_n = u*;
* :class:`LinearFeedback`: event-based linear feedback u_n = u* + K (X_n - X*), the cheap
  "functional form" that the thesis's chapter 5 asks for. K comes from the AD Jacobians
  A = dr/dX and B = dr/du at the gait: deadbeat (A + B K = 0, :func:`deadbeat_gain`)
  where B has rank 4, discrete LQR (:func:`lqr_gain`) otherwise;
  :mod:`baslip.analysis.tuning` chooses between them and tunes the LQR weights;
* :class:`baslip.analysis.horizon.RecedingHorizon`: the controls of the next N strides
  solved at every apex so that the apex after N strides is the gait's;
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
from baslip.model.hiplaw import PD, HipLaw
from baslip.model.quantities import NOMINAL

#: Relative singular-value cutoff for rank decisions on B (scaled by the nominal sizes).
#: Measured on the grids: B's fourth singular value is 1e-4 or more of the first where
#: it counts, and 1e-9 or less where it does not (upright gaits with gains near 1e-4).
RANK_TOLERANCE = 1e-7


def control_scale(law: HipLaw = PD) -> np.ndarray:
    """The nominal size of each of ``law``'s controls (:data:`baslip.model.quantities.NOMINAL`)."""
    return np.array([NOMINAL[n] for n in law.controls.names])


#: A plain LQR design counts only if it brings every multiplier this far inside the unit circle.
STABILISED_MARGIN = 1e-6
#: The PD law's control scale.
CONTROL_SCALE = control_scale(PD)
#: A re-solve stops once a step lowers its eps by less than this factor (the residual
#: has reached the least-squares floor, which is not zero where dr/du has rank 3).
STALL = 0.99


def control_rank(B: np.ndarray, scale: np.ndarray = CONTROL_SCALE) -> int:
    """Rank of dr/du in controls scaled by ``scale``."""
    s = np.linalg.svd(B * scale, compute_uv=False)
    return int(np.sum(s > RANK_TOLERANCE * s[0]))


def deadbeat_gain(A: np.ndarray, B: np.ndarray, scale: np.ndarray = CONTROL_SCALE) -> np.ndarray:
    """K with A + B K = 0, the least-norm one in controls scaled by ``scale`` (needs rank B = 4)."""
    if control_rank(B, scale) < A.shape[0]:
        raise ValueError("deadbeat needs dr/du of rank 4")
    return scale[:, None] * (-np.linalg.pinv(B * scale) @ A)


def lqr_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, iterations: int = 60,
             tolerance: float = 1e-12) -> np.ndarray:
    """The discrete LQR gain K (u = K x) for x' = A x + B u with costs x'Qx + u'Ru
    (``A`` n x n, ``B`` n x m, ``Q`` n x n, ``R`` m x m; ``iterations`` doubling steps at
    most, until no entry of P changes by more than ``tolerance`` times max(1, its largest
    entry)).

    The Riccati equation's stabilising solution P comes from the structure-preserving
    doubling algorithm, which converges quadratically (a few tens of 4 x 4 products, where
    the Riccati difference equation took thousands of steps near a multiplier at 1);
    raises ValueError if it does not settle (an unstable mode is not reachable through B).
    """
    n = A.shape[0]
    Ak, Gk, Hk = A.copy(), B @ np.linalg.solve(R, B.T), Q.copy()
    for _ in range(iterations):
        W = np.linalg.solve(np.eye(n) + Gk @ Hk, np.column_stack([Ak, Gk]))
        V1, V2 = W[:, :n], W[:, n:]
        following = Hk + Ak.T @ Hk @ V1
        Gk, Ak = Gk + Ak @ V2 @ Ak.T, Ak @ V1
        following = (following + following.T) / 2
        if not np.all(np.isfinite(following)):
            break
        settled = np.max(np.abs(following - Hk)) <= tolerance * max(1.0, np.max(np.abs(following)))
        Hk = following
        if settled:
            K = -np.linalg.solve(R + B.T @ Hk @ B, B.T @ Hk @ A)
            # A mode at 1 that B cannot reach makes P grow without bound; round-off may put
            # it a hair inside 1, where P settles, huge, on a gain that leaves it there.
            if np.max(np.abs(np.linalg.eigvals(A + B @ K))) < 1.0 - STABILISED_MARGIN:
                return K
            break
    raise ValueError("the Riccati iteration does not settle: an unstable mode is not reachable")


def transverse_lqr_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, neutral: int) -> np.ndarray:
    """The discrete LQR gain K (u = K x) of :func:`lqr_gain`, designed on the transverse
    dynamics alone: the ``neutral`` eigen-directions of ``A`` nearest 1 (structural
    multipliers, which no control moves at first order) are left out of the Riccati
    equation, and K is zero on them.

    With such a multiplier at 1 to the last bit, or above it by round-off, the Riccati
    equation of the whole apex has no stabilising solution (its P grows without bound);
    whether the plain iteration settles then depends on the last bits of the Jacobian,
    which differ between processors' libm. The transverse design does not.

    Parameters
    ----------
    A, B : numpy.ndarray
        dr/dX (n x n) and dr/du (n x m) at the gait.
    Q, R : numpy.ndarray
        The apex's (n x n) and the controls' (m x m) weights.
    neutral : int
        How many of A's eigenvalues nearest 1 to leave out (at least 1, less than n).

    Returns
    -------
    numpy.ndarray
        K (m x n), with K v = 0 for each left-out eigenvector v of A.

    Raises
    ------
    ValueError
        If the transverse Riccati iteration does not settle either.
    """
    n = A.shape[0]
    values, right = np.linalg.eig(A)
    left_out = np.argsort(np.abs(values - 1.0))[:neutral]
    V = np.real_if_close(right[:, left_out])
    # The projector onto the other eigen-directions along the left-out ones: the rows of
    # the inverse eigenvector matrix that belong to the left-out values span their left
    # eigenvectors, normalised so that W V = I.
    W = np.real_if_close(np.linalg.inv(right)[left_out, :])
    transverse = np.real(np.eye(n) - V @ W)
    # An orthonormal basis T of the transverse subspace (the projector's range), and the
    # dynamics in its coordinates xi = T' P x.
    T = np.linalg.svd(transverse)[0][:, : n - neutral]
    K_reduced = lqr_gain(T.T @ A @ T, T.T @ transverse @ B, T.T @ Q @ T, R)
    return K_reduced @ T.T @ transverse


def lqr_gain_for_gait(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, neutral: int = 0) -> np.ndarray:
    """:func:`lqr_gain`, or where its iteration does not settle and the gait has
    ``neutral`` structural multipliers at 1, :func:`transverse_lqr_gain`. Where the plain
    design settles its gain is kept, so results made with it stand.

    Parameters
    ----------
    A, B, Q, R : numpy.ndarray
        As :func:`lqr_gain`.
    neutral : int
        The gait's structural multipliers at 1 (0 for none).

    Raises
    ------
    ValueError
        If neither design settles.
    """
    try:
        return lqr_gain(A, B, Q, R)
    except ValueError:
        if neutral <= 0:
            raise
        return transverse_lqr_gain(A, B, Q, R, neutral)


def closed_loop_multipliers(A: np.ndarray, B: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Eigenvalues of A + B K, the linearised closed-loop map."""
    return np.linalg.eigvals(A + B @ K)


@dataclass(frozen=True)
class ConstantControl:
    """u_n = u*: the constant hip law (the thesis's, under PD)."""

    u_star: np.ndarray
    name: str = "constant"

    def control(self, X) -> tuple[np.ndarray, float]:
        return np.asarray(self.u_star, dtype=float), 0.0

    def controls(self, Xs: np.ndarray) -> np.ndarray:
        """The controls for many apexes (rows of ``Xs``) at once."""
        return np.broadcast_to(np.asarray(self.u_star, dtype=float), (len(Xs), len(self.u_star)))


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
        return self.controls(np.asarray(X, dtype=float)[None, :])[0], 0.0

    def controls(self, Xs: np.ndarray) -> np.ndarray:
        """The controls for many apexes (rows of ``Xs``) at once, saturated at the bounds."""
        u = self.u_star + (np.asarray(Xs, dtype=float) - self.X_star) @ self.K.T
        return np.clip(u, self.lower, self.upper)


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
        self.scale = control_scale(rmap.law)
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
                B = self.rmap.jacobians(X, u, self.params)[1][:, self.free] * self.scale[self.free]
            except RunnerFell:
                break
            residual = value[1]
            improved = False
            for _ in range(12):  # Levenberg-Marquardt: raise the damping until a step helps
                step = np.linalg.solve(B.T @ B + damping * np.eye(len(self.free)), -B.T @ residual)
                trial = u.copy()
                trial[self.free] = np.clip(u[self.free] + step * self.scale[self.free],
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


#: Outcomes of a closed-loop run: back to the gait, onto a neighbouring gait of its family
#: (where a structural multiplier 1 leaves a direction no control can correct), neither,
#: or a fall.
OUTCOMES = ("converged", "settled", "bounded", "fell")


@dataclass(frozen=True)
class ClosedLoopRun:
    """A run under a controller: the apexes reached, the controls used, the residual each
    control solve left, and how it ended (one of :data:`OUTCOMES`)."""

    apexes: np.ndarray
    controls: np.ndarray
    residuals: np.ndarray
    outcome: str
    strides_to_converge: int | None


def run_closed_loop(rmap: ReturnMap, params: Params, controller, X0, X_star, strides: int,
                    tolerance: float = 1e-6, settle: bool = False) -> ClosedLoopRun:
    """Run ``controller`` from apex ``X0`` for at most ``strides`` strides; it has
    converged when an apex comes within ``tolerance`` (eq. 4.1) of ``X_star``. With
    ``settle``, a run whose apex repeats to ``tolerance`` elsewhere has settled on a
    neighbouring gait.

    Parameters
    ----------
    rmap : ReturnMap
        The return map the strides are taken on (its hip law gives the controls).
    params : Params
        The runner's parameters.
    controller
        Anything with ``control(X) -> (u, residual)``: the control [SI, rad] applied at
        apex ``X``, and the residual its own solve left (0 for a law without one).
    X0, X_star : array_like
        The first apex and the gait's, shape (4,) [m, rad, m/s, rad/s].
    strides : int
        Strides at most.
    tolerance : float
        eps (eq. 4.1) within which an apex counts as the gait's (or as repeating).
    settle : bool
        Whether a run that repeats away from ``X_star`` ends as settled (a family of gaits).

    Returns
    -------
    ClosedLoopRun
        The apexes, controls and residuals of the run, and how it ended.
    """
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
        if settle and eps(stride.apex, apexes[-2]) <= tolerance:
            return ClosedLoopRun(np.array(apexes), np.array(controls), np.array(residuals), "settled", None)
    return ClosedLoopRun(np.array(apexes), np.array(controls), np.array(residuals), "bounded", None)


@dataclass(frozen=True)
class Outcome:
    """How one closed-loop run ended (one of :data:`OUTCOMES`), after how many
    strides, and its last apex's eps against the gait."""

    outcome: str
    strides_run: int
    strides_to_converge: int | None
    final_eps: float


def run_closed_loop_many(rmap: ReturnMap, params: Params, controller, X0s: np.ndarray, X_star, strides: int,
                         tolerance: float = 1e-6, settle: bool = False) -> list[Outcome]:
    """:func:`run_closed_loop` from every row of ``X0s`` at once, for a controller whose
    control depends on the apex alone (``controller.controls(Xs)``): the runs go in
    lockstep, so that each stride of all live runs is one batched call of the engine.
    ``X0s`` is n x 4; the other parameters are :func:`run_closed_loop`'s. Returns each
    run's outcome, in the rows' order."""
    X_star = np.asarray(X_star, dtype=float)
    X = np.array(X0s, dtype=float)
    ended: dict[int, Outcome] = {}
    alive = np.arange(len(X))
    for n in range(strides):
        if not alive.size:
            break
        results = rmap.strides(X[alive], controller.controls(X[alive]), params)
        for i, stride in zip(alive, results):
            if not stride.ok:
                ended[int(i)] = Outcome("fell", n + 1, None, eps(X[i], X_star))
                continue
            previous, X[i] = X[i].copy(), stride.apex
            if eps(X[i], X_star) <= tolerance:
                ended[int(i)] = Outcome("converged", n + 1, n + 1, eps(X[i], X_star))
            elif settle and eps(X[i], previous) <= tolerance:
                ended[int(i)] = Outcome("settled", n + 1, None, eps(X[i], X_star))
        alive = np.array([i for i in alive if int(i) not in ended], dtype=int)
    return [ended.get(i, Outcome("bounded", strides, None, eps(X[i], X_star))) for i in range(len(X))]
