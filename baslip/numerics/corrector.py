"""The atlas's corrector: points of a solution manifold F(w) = 0 near a predicted point.

Two solvers, both for systems that may fail to evaluate (a fall) or leave their domain:

* :func:`correct` puts a predicted point w_pred onto the manifold within the hyperplane
  T^T (w - w_pred) = 0 that the predicting chart's tangent basis T spans: Newton on the
  square system G(w) = [F(w), T^T (w - w_pred)] = 0. It starts from the chart's own
  Jacobian and updates it by Broyden's rank-one formula after every step (so that a
  residual, a fraction of a Jacobian's cost, does most of the work), refreshes it where a
  step does not cut |G| enough, and halves a step with a fresh Jacobian until |G| falls (a
  damped Newton method: at very unstable gaits the full step overshoots).
* :func:`project_seed` takes least-norm Gauss-Newton steps from a seed onto F = 0.

A system that can evaluate F more cheaply to a looser accuracy (the compiled stride at a
looser tolerance) offers it as ``evaluate_roughly`` with its error ``rough_error``: the
corrector uses it while |G| is far above that error, and F itself for the last steps and
the test of convergence, which are the system's own (:meth:`ManifoldSystem.solved`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

#: Largest condition number of the corrector's square Jacobian: beyond it the chart is
#: singular (the projection of the manifold onto the tangent space folds).
SINGULAR_CONDITION = 1e10
#: A step with an updated (not fresh) Jacobian must leave at most this fraction of |G|,
#: or the Jacobian is refreshed at the iterate and the step taken again.
CHORD_RATE = 0.25
#: Times a corrector step with a fresh Jacobian is halved, at most, to lower the residual.
DAMPING_HALVINGS = 6
#: The rough evaluation is used while |G| exceeds this multiple of its error: its error
#: then moves a Newton step by well under a thousandth.
ROUGH_MARGIN = 1e3

#: The corrector's reasons for giving up, and the singular ones (see :func:`kind_of`).
DIVERGED = "Newton diverged"
SINGULAR_FOLD = "singular chart (the projection onto the tangent space folds)"
SINGULAR_RANK = "singular chart (the equations lose rank)"


@dataclass(frozen=True)
class Evaluation:
    """F at a point, or why it could not be evaluated there."""

    residual: np.ndarray | None = None
    failure: str = ""


class ManifoldSystem(Protocol):
    """What the atlas needs of a system of equations F(w) = 0 on a domain.

    A system may also offer ``evaluate_roughly(w) -> Evaluation``, F to within
    ``rough_error`` (a float, in F's norm) at less cost, and ``priority(w) -> float``, by
    which the atlas ranks its charts (:func:`baslip.analysis.atlas.cover`).
    """

    def evaluate(self, w: np.ndarray) -> Evaluation:
        """F(w), or the reason it cannot be evaluated at ``w``."""
        ...

    def jacobian(self, w: np.ndarray) -> np.ndarray | str:
        """dF/dw at ``w`` (rows: equations), or the reason it cannot be evaluated."""
        ...

    def outside(self, w: np.ndarray) -> str:
        """Why ``w`` is outside the domain ("" if it is inside)."""
        ...

    def solved(self, w: np.ndarray, residual: np.ndarray) -> bool:
        """Whether ``residual`` = F(w) is small enough for ``w`` to be a solution."""
        ...


def kind_of(reason: str) -> str:
    """The kind of atlas edge a corrector's failure ``reason`` stands for: ``singular``,
    ``corrector`` (Newton gave up) or ``domain`` (outside it, or an evaluation that fails
    there, such as a fall)."""
    if reason.startswith("singular"):
        return "singular"
    if reason.startswith("Newton"):
        return "corrector"
    return "domain"


class _Residuals:
    """F of one corrector run: rough while |G| is far above the rough error, then exact."""

    def __init__(self, system: ManifoldSystem):
        self.system = system
        rough = getattr(system, "evaluate_roughly", None)
        self.rough_limit = ROUGH_MARGIN * float(getattr(system, "rough_error", 0.0)) if rough else 0.0
        self.rough = rough is not None

    def __call__(self, w: np.ndarray, size: float) -> tuple[Evaluation, bool]:
        """F at ``w`` (and whether it is exact), rough if |G| there is about ``size``."""
        if self.rough and size > self.rough_limit:
            return self.system.evaluate_roughly(w), False  # type: ignore[attr-defined]
        return self.system.evaluate(w), True


def correct(system: ManifoldSystem, target: np.ndarray, tangent: np.ndarray, jacobian: np.ndarray,
            iterations: int) -> tuple[np.ndarray, np.ndarray, int] | str:
    """Newton on G(w) = [F(w), tangent^T (w - target)] = 0 from ``target``.

    Parameters
    ----------
    system : ManifoldSystem
        The equations and their domain.
    target : array
        The predicted point, in the system's coordinates.
    tangent : array
        Orthonormal basis (columns) of the predicting chart's tangent space: the
        correction stays in the hyperplane through ``target`` orthogonal to it.
    jacobian : array
        dF/dw at the predicting chart's centre: the first steps' Jacobian.
    iterations : int
        Steps at most (Broyden, fresh and damped ones alike).

    Returns
    -------
    tuple or str
        (w, dF/dw at w, steps taken), or the reason it failed.
    """
    residuals = _Residuals(system)
    w = np.array(target, dtype=float)
    evaluation, exact = residuals(w, np.inf)
    fresh = updated = False  # a Jacobian at the iterate; one changed by Broyden's updates
    for step in range(iterations + 1):
        if evaluation.residual is not None and not exact and np.linalg.norm(evaluation.residual) <= residuals.rough_limit:
            evaluation, exact = residuals(w, 0.0)  # close to the manifold: from here on, F itself
        if evaluation.residual is None:
            return evaluation.failure or "the equations cannot be evaluated"
        if exact and system.solved(w, evaluation.residual):
            final = system.jacobian(w)
            return final if isinstance(final, str) else (w, final, step)
        if step == iterations:
            break
        taken = _newton_step(residuals, w, evaluation, target, tangent, jacobian, fresh)
        if isinstance(taken, str) and not fresh and (taken != SINGULAR_FOLD or updated):
            # The step failed: take it again with a Jacobian at the iterate. A fold is the
            # chart's own (its Jacobian's square system is singular), not an update's.
            refreshed = system.jacobian(w)
            if isinstance(refreshed, str):
                return refreshed
            jacobian, fresh = refreshed, True
            taken = _newton_step(residuals, w, evaluation, target, tangent, jacobian, fresh)
        if isinstance(taken, str):
            return taken
        trial, at_trial, trial_exact = taken
        if trial_exact == exact:  # Broyden's update, from two values of the same accuracy
            jacobian, updated = broyden_update(jacobian, trial - w, at_trial.residual - evaluation.residual), True
        w, evaluation, exact, fresh = trial, at_trial, trial_exact, False
    return f"Newton did not converge in {iterations} iterations"


def broyden_update(jacobian: np.ndarray, step: np.ndarray, change: np.ndarray) -> np.ndarray:
    """Broyden's ("good") rank-one update of ``jacobian`` after a ``step`` that changed F
    by ``change``: the least change to it that maps the step to the change."""
    length = float(step @ step)
    if length == 0.0:
        return jacobian
    return jacobian + np.outer(change - jacobian @ step, step) / length


def _newton_step(residuals: _Residuals, w: np.ndarray, evaluation: Evaluation, target: np.ndarray,
                 tangent: np.ndarray, jacobian: np.ndarray,
                 fresh: bool) -> tuple[np.ndarray, Evaluation, bool] | str:
    """One step of :func:`correct` from ``w``: the new iterate, F there and whether F is
    exact; or why no step was taken. A step with an updated Jacobian (``fresh``
    False) must cut |G| to :data:`CHORD_RATE` of what it was; a fresh one is halved until
    |G| falls at all."""
    square = np.vstack([jacobian, tangent.T])
    if np.linalg.cond(square) > SINGULAR_CONDITION:
        return SINGULAR_FOLD
    g = np.concatenate([evaluation.residual, tangent.T @ (w - target)])
    norm, full = float(np.linalg.norm(g)), np.linalg.solve(square, g)
    reason = DIVERGED
    for halving in range(DAMPING_HALVINGS + 1 if fresh else 1):
        trial = w - full / 2**halving
        reason = residuals.system.outside(trial)
        if reason:  # a wild iterate: refused before the system is evaluated there
            continue
        # The step's own size predicts |G| at the trial: the chord rate times |G| now.
        at_trial, exact = residuals(trial, CHORD_RATE * norm)
        if at_trial.residual is None:
            reason = at_trial.failure or "the equations cannot be evaluated"
            continue
        trial_norm = float(np.linalg.norm(np.concatenate([at_trial.residual, tangent.T @ (trial - target)])))
        if trial_norm <= (CHORD_RATE if not fresh else 1.0) * norm:
            return trial, at_trial, exact
        reason = DIVERGED
    return reason


def project_seed(system: ManifoldSystem, w: np.ndarray, iterations: int = 20) -> tuple[np.ndarray, np.ndarray] | str:
    """Gauss-Newton (least-norm steps) from ``w`` onto F = 0: (point, dF/dw) or why not
    (an evaluation that fails, an iterate outside the domain, or no convergence)."""
    w = np.array(w, dtype=float)
    for _ in range(iterations + 1):
        evaluation = system.evaluate(w)
        if evaluation.residual is None:
            return evaluation.failure or "the equations cannot be evaluated"
        jacobian = system.jacobian(w)
        if isinstance(jacobian, str):
            return jacobian
        if system.solved(w, evaluation.residual):
            return w, jacobian
        w = w - np.linalg.lstsq(jacobian, evaluation.residual, rcond=None)[0]
        reason = system.outside(w)
        if reason:  # a wild iterate: refused before the system is evaluated there
            return reason
    return f"the seed did not converge in {iterations} iterations"
