"""Stability of a fixed point from the eigenvalues of the return-map Jacobian dr/dX.

Some multipliers equal 1 by structure, whatever the gait:

* ``energy``: with no hip torque (under PD, Kp = Kd = 0) the total energy is conserved, so the
  energy gradient is a left eigenvector of dr/dX with eigenvalue 1;
* ``spin`` (two, a Jordan pair): with d = 0 and no torque (or under VPP with the pivot at
  the CoM, r_vpp = 0) the trunk decouples and spins freely, so (theta_h, theta_h_dot) map
  as [[1, T], [0, 1]];
* ``symmetry``: under a hip law of positions only (VPP) a gait symmetric under mirror and
  time reversal has one periodicity row that follows from the others, so
  [dr/dX - I, dr/du] has a left null vector w, and w^T dr/dX = w^T: a multiplier 1
  (:func:`baslip.model.quantities.implied_periodicity`).

They are labelled, when a multiplier lies within :data:`TRIVIAL_TOLERANCE` of 1, and left
out of ``spectral_radius`` and ``stable``: stability then means asymptotic stability
transverse to those neutral directions (e.g. on the energy level). ``stable`` also asks for
a margin: a radius within :data:`STABILITY_MARGIN` of 1 is neutral to the accuracy of the
Jacobian, not stable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baslip.model.dynamics import Params
from baslip.model.hiplaw import PD, HipLaw

#: Distance from 1 within which a structurally trivial multiplier is recognised (the spin
#: Jordan pair splits by about the square root of the Jacobian's error).
TRIVIAL_TOLERANCE = 1e-5
#: Radii in [1 - margin, 1) are called neutral, not stable.
STABILITY_MARGIN = 1e-6


@dataclass(frozen=True)
class Multiplier:
    """One eigenvalue of dr/dX, with ``label`` naming it if it is trivial by structure.

    Attributes
    ----------
    value : complex
        The eigenvalue (dimensionless).
    label : str or None
        ``"energy"``, ``"spin"`` or ``"symmetry"`` for a multiplier that is 1 by structure,
        else None.
    """

    value: complex
    label: str | None = None  # None, "energy", "spin" or "symmetry"

    @property
    def trivial(self) -> bool:
        """Whether the multiplier is 1 by structure (it has a label), and so left out of the
        spectral radius."""
        return self.label is not None


@dataclass(frozen=True)
class Stability:
    """Multipliers of a fixed point; radius and verdict over the non-trivial ones.

    Attributes
    ----------
    jacobian : numpy.ndarray
        dr/dX (of r^n for an n-stride orbit), shape (4, 4), rows and columns in the apex's
        order and units: z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s].
    multipliers : tuple of Multiplier
        Its eigenvalues, the trivial ones labelled.
    spectral_radius : float
        The largest modulus of the non-trivial multipliers (0 when all are trivial).
    stable : bool
        Whether ``spectral_radius`` is below 1 by more than :data:`STABILITY_MARGIN`.
    """

    jacobian: np.ndarray  # dr/dX, 4 x 4
    multipliers: tuple[Multiplier, ...]
    spectral_radius: float
    stable: bool

    def __repr__(self) -> str:
        values = ", ".join(f"{m.value:.4g}" + (f" [{m.label}]" if m.label else "") for m in self.multipliers)
        return f"<Stability: {'stable' if self.stable else 'unstable'}, radius {self.spectral_radius:.6g}; {values}>"

    def _repr_html_(self) -> str:
        return repr(self).replace("<", "&lt;").replace(">", "&gt;")


def trivial_labels(params: Params, u, law: HipLaw = PD) -> list[str]:
    """Labels of the multipliers that equal 1 by the structure of the problem, for the
    runner of ``params`` under control ``u`` [SI, rad] of hip law ``law``.

    The spin pair comes first: it is 1 at every apex, the energy multiplier only at a
    fixed point, and labels go to the multipliers nearest 1 in this order.
    """
    control = law.control_dict(u)
    spin = ["spin", "spin"] if law.spin_free(control, params) else []
    if law.positional:
        return spin + ["symmetry"]
    # Under PD the trunk spins freely only without torque, so spin is empty otherwise.
    return (spin + ["energy"]) if law.torque_free(control) else []


def classify(jacobian: np.ndarray, params: Params, u, law: HipLaw = PD) -> Stability:
    """Eigenvalues of ``jacobian``; the trivial ones are those expected by structure that
    lie nearest to 1, and within :data:`TRIVIAL_TOLERANCE` of it.

    Parameters
    ----------
    jacobian : array_like
        dr/dX at the fixed point, shape (4, 4).
    params : Params
        The model parameters (``d`` decides whether the trunk spins freely).
    u : array_like
        The controls of ``law`` at the fixed point, SI units and radians.
    law : HipLaw
        The stance hip law, which decides the multipliers that are 1 by structure.

    Returns
    -------
    Stability
        The labelled multipliers, the spectral radius and the verdict.
    """
    eigenvalues = np.linalg.eigvals(np.asarray(jacobian, dtype=float))
    labels = trivial_labels(params, u, law)
    order = np.argsort(np.abs(eigenvalues - 1.0))
    label_of = {
        int(i): label
        for i, label in zip(order, labels)
        if abs(eigenvalues[i] - 1.0) <= TRIVIAL_TOLERANCE
    }
    multipliers = tuple(Multiplier(complex(ev), label_of.get(i)) for i, ev in enumerate(eigenvalues))
    nontrivial = [abs(m.value) for m in multipliers if not m.trivial]
    radius = max(nontrivial) if nontrivial else 0.0
    return Stability(np.asarray(jacobian), multipliers, float(radius), bool(radius < 1.0 - STABILITY_MARGIN))


def without_symmetry_direction(jacobian: np.ndarray) -> np.ndarray:
    """``jacobian`` - v v^T, with v the unit vector that A - I maps nearest to zero (its
    smallest right singular vector): at a symmetric gait of a law of positions only (VPP),
    where A v = v, the structural multiplier moves to 0 and the others are unchanged
    (in the basis (v, v's complement) A is block triangular with 1 in the corner).

    Unlike :func:`without_symmetry_multiplier` it needs no left eigenvector, so it stays
    finite where a second multiplier meets +1 in a Jordan block (a fold of the symmetric
    family, where the two eigenvectors merge and v is still the smallest singular
    vector): the deflation of fold curves. Off the gaits (A v != v) the others move by
    about |A v - v|.
    """
    A = np.asarray(jacobian, dtype=float)
    _, _, vt = np.linalg.svd(A - np.eye(len(A)))
    v = vt[-1]
    return A - np.outer(v, v)


def without_symmetry_multiplier(jacobian: np.ndarray) -> np.ndarray:
    """``jacobian`` with its real multiplier nearest 1 moved to 0, the others unchanged
    (Wielandt deflation: A - mu P, with P the spectral projector of mu).

    At a symmetric gait of a law of positions only (VPP) that multiplier is the structural
    ``symmetry`` one; near the gait (as where a curve's derivatives are differenced) it is
    still the one nearest 1, and the projector changes smoothly with the matrix while mu
    stays simple. A multiplier that crosses +1 there (a fold of the symmetric family)
    meets it and makes P singular, so fold curves use :func:`without_symmetry_direction`.
    """
    A = np.asarray(jacobian, dtype=float)
    mu, V = np.linalg.eig(A)
    real = np.abs(mu.imag) <= 1e-9 * max(1.0, float(np.max(np.abs(mu))))
    if not real.any():
        return A
    k = int(np.argmin(np.where(real, np.abs(mu - 1.0), np.inf)))
    right = np.real(V[:, k])
    left = np.real(np.linalg.inv(V)[k])  # left eigenvector with left @ right = 1
    return A - float(np.real(mu[k])) * np.outer(right, left)
