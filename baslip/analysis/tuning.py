"""Choosing a gait's event-based feedback u = u* + K (X - X*): deadbeat (offered only where
its gains keep the controls inside their bounds over the box of starts) or discrete LQR
with weights chosen by the tool.

The LQR weights are Q = diag(10^e_i / s_i^2) on the apex deviations (s_i their nominal
sizes, e_i in :data:`WEIGHT_EXPONENTS`) and R = diag(1 / c_j^2) on the controls (c_j theirs);
only the ratio of Q to R matters, so scaling R as well would repeat candidates. Of the
candidates whose closed loop is linearly stable, and deadbeat where it is offered, the one
kept brings back the largest share of a pilot sample of starts (``pilot``, a callable that
measures it); ties go to deadbeat, then to the smaller closed-loop radius. Without a
pilot, deadbeat where offered, else the least closed-loop radius wins.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from baslip.analysis.feedback import closed_loop_multipliers, control_rank, deadbeat_gain, lqr_gain_for_gait
from baslip.model.dynamics import APEX
from baslip.model.quantities import NOMINAL

#: Exponents of each apex coordinate's LQR weight, relative to its nominal size.
WEIGHT_EXPONENTS = (-1.0, 0.0, 1.0)


@dataclass(frozen=True)
class FeedbackChoice:
    """The feedback chosen for a gait, and why.

    Attributes
    ----------
    kind : str
        ``deadbeat`` or ``lqr``.
    K : numpy.ndarray
        The gain (controls x apex), SI units and radians.
    weights : tuple of float
        The LQR's apex weight exponents e_i (empty for deadbeat).
    closed_loop_radius : float
        The largest modulus of the eigenvalues of A + B K, structural ones left out.
    pilot_share : float or None
        The pilot sample's converged share under K (None without a pilot).
    candidates : int
        The linearly stable LQR candidates that were compared.
    reason : str
        Why this kind: deadbeat's gains within bounds, or why not.
    """

    kind: str
    K: np.ndarray
    weights: tuple[float, ...]
    closed_loop_radius: float
    pilot_share: float | None
    candidates: int
    reason: str


def saturates(K: np.ndarray, u_star: np.ndarray, lower: np.ndarray, upper: np.ndarray, half_widths) -> bool:
    """Whether u* + K d leaves the bounds at some corner d of the box with ``half_widths``."""
    corners = np.array(list(itertools.product(*[(-w, w) for w in half_widths])))
    u = u_star + corners @ K.T
    return bool(np.any(u < lower) or np.any(u > upper))


def transverse_radius(A: np.ndarray, B: np.ndarray, K: np.ndarray, neutral: int = 0) -> float:
    """The largest modulus of the eigenvalues of A + B K, leaving out the ``neutral`` ones
    nearest 1: the structural multipliers at 1 (a VPP gait's symmetry), which no control
    moves at first order."""
    multipliers = closed_loop_multipliers(A, B, K)
    kept = np.argsort(np.abs(multipliers - 1.0))[neutral:]
    return float(np.max(np.abs(multipliers[kept]))) if kept.size else 0.0


def lqr_candidates(A: np.ndarray, B: np.ndarray, scale: np.ndarray,
                   neutral: int = 0) -> list[tuple[tuple[float, ...], np.ndarray, float]]:
    """(weight exponents, K, closed-loop radius without the ``neutral`` multipliers) of
    every weighting whose closed loop is linearly stable, least radius first."""
    apex_scale = np.array([NOMINAL[n] for n in APEX.names])
    R = np.diag(1 / scale**2)
    found = []
    for exponents in itertools.product(WEIGHT_EXPONENTS, repeat=APEX.size):
        Q = np.diag(10.0 ** np.array(exponents) / apex_scale**2)
        try:
            K = lqr_gain_for_gait(A, B, Q, R, neutral)
        except ValueError:
            continue
        radius = transverse_radius(A, B, K, neutral)
        if radius < 1.0:
            found.append((tuple(exponents), K, radius))
    return sorted(found, key=lambda c: c[2])


def choose_feedback(A: np.ndarray, B: np.ndarray, u_star: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    half_widths, scale: np.ndarray,
                    pilot: Callable[[np.ndarray], float] | None = None, neutral: int = 0) -> FeedbackChoice:
    """The feedback for a gait with Jacobians ``A``, ``B`` and control ``u_star``.

    Parameters
    ----------
    A, B : numpy.ndarray
        dr/dX (4 x 4) and dr/du (4 x controls) at the gait.
    u_star, lower, upper : numpy.ndarray
        The gait's control and the controls' bounds.
    half_widths : array_like
        The half-widths of the largest box of starts (apex order, SI units, rad).
    scale : numpy.ndarray
        The controls' nominal sizes.
    pilot : callable, optional
        K -> the converged share of a pilot sample of starts under u* + K (X - X*).
    neutral : int
        The gait's structural multipliers at 1, left out of the closed-loop radius.

    Raises
    ------
    ValueError
        If no weighting stabilises the linearised closed loop and deadbeat is not possible.
    """
    candidates = lqr_candidates(A, B, scale, neutral)
    reason = f"dr/du has rank {control_rank(B, scale)}, deadbeat needs 4"
    deadbeat = None
    if control_rank(B, scale) == APEX.size:
        K = deadbeat_gain(A, B, scale)
        if saturates(K, u_star, lower, upper, half_widths):
            reason = "deadbeat's controls would leave their bounds over the box"
        else:
            deadbeat = FeedbackChoice("deadbeat", K, (), transverse_radius(A, B, K, neutral), None, len(candidates) + 1,
                                      "deadbeat's controls stay within their bounds over the box")
    if not candidates and deadbeat is None:
        raise ValueError(f"no LQR weighting stabilises the linearised closed loop ({reason})")
    if pilot is None:
        if deadbeat is not None:
            return deadbeat
        weights, K, radius = candidates[0]
        return FeedbackChoice("lqr", K, weights, radius, None, len(candidates), reason)
    shares = [pilot(K) for _, K, _ in candidates]
    best = max(range(len(candidates)), key=lambda i: (shares[i], -candidates[i][2])) if candidates else None
    if deadbeat is not None:
        share = pilot(deadbeat.K)
        if best is None or share >= shares[best]:
            return replace(deadbeat, pilot_share=share, reason=deadbeat.reason + "; it brings back the most of the pilot")
        reason = (f"deadbeat's controls stay within their bounds, but it brings back {share:.0%} of the pilot, "
                  f"an LQR {shares[best]:.0%}")
    assert best is not None
    weights, K, radius = candidates[best]
    return FeedbackChoice("lqr", K, weights, radius, shares[best], len(candidates) + (deadbeat is not None), reason)
