"""Bifurcation curves in two parameters, and the codimension-two points on them.

A fold, period doubling or Neimark-Sacker bifurcation of the fixed points of a map holds
on a curve in a plane of two parameters (l1, l2). Such a curve is traced as a branch of
the minimally extended system (Govaerts, *Numerical methods for bifurcations of dynamical
equilibria*, 2000)::

    F(w, l1, l2) = 0    the fixed-point equations: n equations, n unknowns w
    g(w, l1, l2) = 0    one test function

with the pseudo-arclength engine of :mod:`baslip.numerics.continuation`. g is the last component
of the solution of the bordered system::

    [ M    b ] [ phi ]   [ 0 ]
    [ c^T  0 ] [  g  ] = [ 1 ]

where A is the Jacobian of the map on its dynamic coordinates (no multiplier 1 by
structure there; see :meth:`baslip.analysis.gaitsystem.FixedPointSystem.dynamic_coordinates`;
under a law of positions only, VPP, the symmetric gaits' multiplier 1 is deflated to 0:
by its spectral projector for period-doubling and Neimark-Sacker curves,
:func:`baslip.gait.stability.without_symmetry_multiplier`, and by its right eigenvector
alone for fold curves, :func:`baslip.gait.stability.without_symmetry_direction`, since
there the critical multiplier meets it at +1 and the projector is singular) and

* fold: M = A - I (a multiplier at +1);
* period doubling: M = A + I (a multiplier at -1);
* Neimark-Sacker: M = A (.) A - I, with A (.) A the bialternate product, whose
  eigenvalues are the products mu_i mu_j (i < j) of the multipliers: a complex pair on
  the unit circle, or a real pair mu, 1/mu (a *neutral saddle*, which is no bifurcation
  and is labelled as such).

g vanishes exactly where M is singular; b and c, the singular vectors of M at the last
point, keep the bordered matrix regular there. g itself comes from the algorithmic
Jacobian A, so the curve is located to Newton's tolerance. Its gradient is
dg/dv = -psi^T (dM/dv) phi (psi from the transposed system). M is algebra on the
base's map Jacobian R (A = R, or R deflated), so psi^T dM phi = <S, dR> for a seed S
(:func:`defining_seed`), and the base turns <S, dR/dv> into exact second derivatives
of the map (``map_jacobian_gradient``: for a gait, Hessian-vector products of the
compiled stride, :meth:`baslip.analysis.gaitsystem.FixedPointSystem.map_jacobian_gradient`).

Codimension-two points are zeros of the test functions of :data:`CODIM2_TESTS`, located
by regula falsi along the curve. The normal-form coefficients of the cusp and of the
generalised period doubling need the map's second and third derivatives B and C, taken
as differences of the Jacobian along the null vectors (relative accuracy about 1e-6,
enough for the sign changes they are used for).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import casadi as ca
import numpy as np

from baslip.gait.stability import without_symmetry_direction, without_symmetry_multiplier
from baslip.numerics.continuation import Branch, CorrectionFailed, Point, Settings, continue_branch, join

#: The curves that can be followed.
CURVE_TYPES = ("fold", "period_doubling", "neimark_sacker")
#: Codimension-two points looked for along each kind of curve (see the module docstring
#: and :func:`codim2_tests` for their test functions).
CODIM2_TESTS = {
    "fold": ("cusp", "bogdanov_takens", "fold_flip", "fold_neimark_sacker"),
    "period_doubling": ("generalised_period_doubling", "resonance_1_2", "fold_flip"),
    "neimark_sacker": ("resonance_1_1", "resonance_1_2", "resonance_1_3", "resonance_1_4", "fold_neimark_sacker"),
}

#: Step of the central differences on the map Jacobian's entries that linearise a
#: symmetry deflation for :func:`defining_seed` (algebra on a k x k matrix only).
DEFLATION_STEP = 1e-6
#: Steps along unit null vectors for the map's second (B) and third (C) derivatives.
SECOND_DERIVATIVE_STEP = 1e-4
THIRD_DERIVATIVE_STEP = 1e-3


def bialternate(A: np.ndarray) -> np.ndarray:
    """The bialternate product A (.) A: for A (k x k), the k(k-1)/2 square matrix on pairs
    (i > j) whose eigenvalues are the products mu_i mu_j of A's eigenvalues."""
    pairs = [(i, j) for i in range(1, len(A)) for j in range(i)]
    out = np.empty((len(pairs), len(pairs)))
    for row, (p, q) in enumerate(pairs):
        for column, (r, s) in enumerate(pairs):
            out[row, column] = A[p, r] * A[q, s] - A[p, s] * A[q, r]
    return out


def defining_matrix(kind: str, A: np.ndarray) -> np.ndarray:
    """M, singular exactly on the curve of ``kind``, from the map's Jacobian ``A``."""
    if kind == "fold":
        return A - np.eye(len(A))
    if kind == "period_doubling":
        return A + np.eye(len(A))
    product = bialternate(A)
    return product - np.eye(len(product))


def defining_seed(matrix_of: Callable[[np.ndarray], np.ndarray], R: np.ndarray, phi: np.ndarray, psi: np.ndarray,
                  quadratic: bool) -> np.ndarray:
    """S with psi^T dM phi = <S, dR>, for M = ``matrix_of(R)``: the derivative of the
    scalar psi^T M(R) phi in each entry of R, by central differences on R alone. Where M
    is a polynomial of degree two or less in R (``quadratic``: the fold's A - I, the period
    doubling's A + I, the bialternate product's A (.) A - I) the difference with a unit
    step is exact; through a deflation it takes :data:`DEFLATION_STEP`."""
    step = 1.0 if quadratic else DEFLATION_STEP * max(1.0, float(np.max(np.abs(R))))
    seed = np.empty_like(R)
    for index in np.ndindex(*R.shape):
        shift = np.zeros_like(R)
        shift[index] = step
        seed[index] = psi @ (matrix_of(R + shift) - matrix_of(R - shift)) @ phi / (2 * step)
    return seed


def critical_pair(multipliers: np.ndarray) -> tuple[int, int]:
    """Indices of the two multipliers whose product is nearest 1 (on a Neimark-Sacker
    curve, the pair on the unit circle)."""
    pairs = [(i, j) for i in range(len(multipliers)) for j in range(i + 1, len(multipliers))]
    return min(pairs, key=lambda ij: abs(multipliers[ij[0]] * multipliers[ij[1]] - 1.0))


def _product(values) -> float:
    """Real part of a product over multipliers (a conjugate pair contributes |.|^2 > 0),
    NaN for none."""
    values = list(values)
    return float(np.real(np.prod(values))) if values else math.nan


class CurveSystem:
    """The extended system F = 0, g = 0 of a curve of ``kind`` for :mod:`baslip.numerics.continuation`.

    ``base`` gives the fixed-point equations in two parameters: ``residual(v)`` (n),
    ``jacobian(v)`` (n x (n + 2)), ``multipliers(v)`` and ``map_jacobian(v, shift)``,
    the Jacobian of the map on its dynamic coordinates at the fixed point displaced by
    ``shift``, ``map_jacobian_gradient(v, seed)``, the gradient in v of <seed,
    map_jacobian(v)>, ``symmetric``, whether that Jacobian has a multiplier 1 by structure
    (the curve deflates it, see the module docstring), and ``normal_forms``, whether the
    deflated Jacobian's derivatives are the map's own (False where a structural multiplier
    is deflated from it: the cusp and generalised period-doubling coefficients are then
    not computed). v = (w, l1, l2).
    """

    #: Its Jacobian needs the map's second derivatives, many times a residual's cost: the
    #: continuation's corrector updates the last point's instead (see
    #: :func:`baslip.numerics.continuation.correct_updated`).
    costly_jacobian = True

    def __init__(self, base, kind: str):
        if kind not in CURVE_TYPES:
            raise ValueError(f"unknown curve {kind!r}; expected one of {', '.join(CURVE_TYPES)}")
        self.base, self.kind = base, kind
        self.special_types = CODIM2_TESTS[kind]
        self.parameter_count = 2  # codimension-two points are located in both parameters
        self._border: tuple[np.ndarray, np.ndarray] | None = None  # (b, c): left, right
        self._version = 0  # counts border updates: g depends on the border
        self._cache: tuple[tuple, tuple] | None = None

    # -- the defining function --------------------------------------------------------------

    def map_jacobian(self, v: np.ndarray, shift: np.ndarray | None = None) -> np.ndarray:
        """The base's map Jacobian with a structural multiplier 1 deflated (see the module
        docstring): the matrix whose multipliers this curve's conditions read."""
        return self._deflated(self.base.map_jacobian(v, shift))

    def _deflated(self, R: np.ndarray) -> np.ndarray:
        if not getattr(self.base, "symmetric", False):
            return R
        return without_symmetry_direction(R) if self.kind == "fold" else without_symmetry_multiplier(R)

    def _check_size(self, A: np.ndarray) -> None:
        if self.kind == "neimark_sacker" and len(A) < 2:
            raise CorrectionFailed("a Neimark-Sacker curve needs a map of two or more dynamic coordinates")

    def _set_border(self, M: np.ndarray, previous: tuple[np.ndarray, np.ndarray] | None) -> None:
        """b, c: M's singular vectors of its least singular value, signed like the old ones."""
        u, _, vt = np.linalg.svd(M)
        b, c = u[:, -1], vt[-1]
        if previous is not None:
            b = b if np.dot(b, previous[0]) >= 0 else -b
            c = c if np.dot(c, previous[1]) >= 0 else -c
        self._border, self._version = (b, c), self._version + 1

    def _bordered(self, M: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(g, phi, psi): the bordered solutions, phi and psi near M's right and left
        null vectors (c.phi = 1, b.psi = 1)."""
        assert self._border is not None, "_set_border comes first"
        b, c = self._border
        k = len(M)
        bordered = np.zeros((k + 1, k + 1))
        bordered[:k, :k], bordered[:k, k], bordered[k, :k] = M, b, c
        rhs = np.zeros(k + 1)
        rhs[k] = 1.0
        try:
            right = np.linalg.solve(bordered, rhs)
            left = np.linalg.solve(bordered.T, rhs)
        except np.linalg.LinAlgError:
            raise CorrectionFailed("the bordered matrix is singular") from None
        return float(right[k]), right[:k], left[:k]

    def _defining(self, v: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
        key = (v.tobytes(), self._version)
        if self._cache is None or self._cache[0] != key:
            A = self.map_jacobian(v)
            self._check_size(A)
            M = defining_matrix(self.kind, A)
            if self._border is None:
                self._set_border(M, None)
                key = (v.tobytes(), self._version)
            self._cache = (key, (A, *self._bordered(M)))
        return self._cache[1]

    def residual(self, v: np.ndarray) -> np.ndarray:
        _, g, _, _ = self._defining(v)
        return np.concatenate([self.base.residual(v), [g]])

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        _, _, phi, psi = self._defining(v)
        seed = defining_seed(lambda R: defining_matrix(self.kind, self._deflated(R)), self.base.map_jacobian(v),
                             phi, psi, quadratic=not getattr(self.base, "symmetric", False))
        gradient = -self.base.map_jacobian_gradient(v, seed)
        return np.vstack([self.base.jacobian(v), gradient])

    def multipliers(self, v: np.ndarray):
        return self.base.multipliers(v)

    # -- codimension-two points ---------------------------------------------------------------

    def test_functions(self, v: np.ndarray, jac: np.ndarray, tangent: np.ndarray) -> dict[str, float]:
        """The codimension-two test functions at a point of the curve (which also moves
        the border to this point's null vectors)."""
        A, _, phi, psi = self._defining(v)
        tests = codim2_tests(self.kind, A, phi, psi, lambda shift: self.map_jacobian(v, shift),
                             self.base.normal_forms)
        self._set_border(defining_matrix(self.kind, A), self._border)  # a new version: g is recomputed
        return tests

    def crossing_veto(self, kind: str, a: Point, b: Point) -> bool:
        """Sign changes that are poles or artefacts, not zeros: the generalised period
        doubling's coefficient has a pole at a fold-flip; a fold-Neimark-Sacker needs a
        complex pair at both ends (a real pair with product 1 is a neutral saddle)."""
        if kind == "generalised_period_doubling":
            return a.tests["fold_flip"] * b.tests["fold_flip"] < 0
        if kind == "fold_neimark_sacker" and self.kind == "fold":
            return not (a.tests["complex_pairs"] and b.tests["complex_pairs"])
        return False

    def on_curve(self, v: np.ndarray) -> str:
        """What the point is: the curve's bifurcation, or ``neutral_saddle`` where the
        Neimark-Sacker condition holds for a real pair."""
        if self.kind != "neimark_sacker":
            return self.kind
        A = self.map_jacobian(v)
        mu = np.linalg.eigvals(A)
        i, _ = critical_pair(mu)
        return "neimark_sacker" if abs(mu[i].imag) > 1e-9 else "neutral_saddle"


def codim2_tests(kind: str, A: np.ndarray, phi: np.ndarray, psi: np.ndarray,
                 jacobian_at: Callable[[np.ndarray], np.ndarray], normal_forms: bool = True) -> dict[str, float]:
    """Test functions of the codimension-two points on a curve of ``kind``.

    ``A`` is the map's Jacobian at the point, ``phi`` and ``psi`` the bordered right and
    left null vectors of the defining matrix, and ``jacobian_at(shift)`` the Jacobian at
    the point displaced by ``shift``. Without ``normal_forms`` (``jacobian_at``'s
    derivatives are not the map's), cusp and generalised_period_doubling are NaN: never a
    sign change. Each function changes sign at its point:

    fold curve (multiplier mu_0 = +1)
      cusp: psi.B(phi, phi), the numerator of the fold's normal-form coefficient;
      bogdanov_takens: psi.phi, zero where +1 becomes a double multiplier (Jordan block);
      fold_flip: prod over the other multipliers of (mu + 1);
      fold_neimark_sacker: prod over the other pairs of (mu_i mu_j - 1), with a complex pair.
    period-doubling curve (mu_0 = -1)
      generalised_period_doubling: psi.[C(phi, phi, phi) + 3 B(phi, (I - A)^-1 B(phi, phi))],
        the numerator of the flip's normal-form coefficient (Kuznetsov, eq. 9.25);
      resonance_1_2: psi.phi (a double -1);
      fold_flip: prod over the other multipliers of (mu - 1).
    Neimark-Sacker curve (mu_0, mu_1 = exp(+-i theta), kappa = cos theta)
      resonance_1_1, 1_2, 1_3, 1_4: kappa - 1, kappa + 1, kappa + 1/2, kappa;
      fold_neimark_sacker: prod over the other multipliers of (mu - 1).
    """
    mu = np.linalg.eigvals(A)
    tests: dict[str, float] = {}
    if kind in ("fold", "period_doubling"):
        target = 1.0 if kind == "fold" else -1.0
        critical = int(np.argmin(np.abs(mu - target)))
        others = np.delete(mu, critical)
        tests["complex_pairs"] = float(np.sum(others.imag > 1e-9))
        orthogonality = float(psi @ phi)
        if kind == "fold":
            tests["cusp"] = float(psi @ _second(jacobian_at, A, phi, phi)) if normal_forms else math.nan
            tests["bogdanov_takens"] = orthogonality
            tests["fold_flip"] = _product(others + 1.0)
            pairs = [others[i] * others[j] - 1.0 for i in range(len(others)) for j in range(i + 1, len(others))]
            tests["fold_neimark_sacker"] = _product(pairs)
        else:
            tests["generalised_period_doubling"] = (_flip_numerator(jacobian_at, A, phi, psi) if normal_forms
                                                    else math.nan)
            tests["resonance_1_2"] = orthogonality
            tests["fold_flip"] = _product(others - 1.0)
        return tests
    i, j = critical_pair(mu)
    kappa = float(np.real(mu[i] + mu[j]) / 2)
    tests.update(kappa=kappa, resonance_1_1=kappa - 1.0, resonance_1_2=kappa + 1.0,
                 resonance_1_3=kappa + 0.5, resonance_1_4=kappa)
    tests["fold_neimark_sacker"] = _product(np.delete(mu, [i, j]) - 1.0)
    return tests


def _unit(x: np.ndarray) -> tuple[np.ndarray, float]:
    norm = float(np.linalg.norm(x))
    return (x / norm if norm else x), norm


def _second(jacobian_at, A, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """B(q, r): the map's second derivative, as d/de [A(x + e r) q] by central differences."""
    direction, size = _unit(r)
    if size == 0.0:
        return np.zeros(len(A))
    h = SECOND_DERIVATIVE_STEP
    return (jacobian_at(h * direction) - jacobian_at(-h * direction)) @ q * (size / (2 * h))


def _third(jacobian_at, A, q: np.ndarray) -> np.ndarray:
    """C(q, q, q): d^2/de^2 [A(x + e q) q] by central differences."""
    direction, size = _unit(q)
    h = THIRD_DERIVATIVE_STEP
    return (jacobian_at(h * direction) - 2 * A + jacobian_at(-h * direction)) @ q * (size**2 / h**2)


def _flip_numerator(jacobian_at, A, phi, psi) -> float:
    k = len(A)
    bqq = _second(jacobian_at, A, phi, phi)
    try:
        w = np.linalg.solve(np.eye(k) - A, bqq)
    except np.linalg.LinAlgError:
        return math.nan
    return float(psi @ (_third(jacobian_at, A, phi) + 3 * _second(jacobian_at, A, phi, w)))


def onto_curve(curve: CurveSystem, v: np.ndarray, settings: Settings) -> np.ndarray:
    """The curve's point nearest ``v``, by Gauss-Newton with the least-norm step (the
    curve may run along either parameter, so neither is held)."""
    for _ in range(4 * settings.max_newton):
        step = np.linalg.lstsq(curve.jacobian(v), -curve.residual(v), rcond=None)[0]
        v = v + step
        if np.linalg.norm(step) < 1e-10 and np.linalg.norm(curve.residual(v)) <= settings.tolerance:
            return v
    if np.linalg.norm(curve.residual(v)) <= settings.tolerance:
        return v
    raise CorrectionFailed("no point of the curve near the start")


#: The signs of the second parameter's direction in which a curve is traced from its
#: start: first towards decreasing, then increasing values.
CURVE_DIRECTIONS = (-1.0, 1.0)


def curve_start(curve: CurveSystem, v: np.ndarray, settings: Settings,
                accept: Callable[[np.ndarray], str | None] = lambda v: None) -> np.ndarray:
    """The curve's first point: ``v`` (a point near the curve) corrected onto it, and
    accepted by ``accept``; raises :class:`CorrectionFailed` otherwise."""
    start = onto_curve(curve, v, settings)
    veto = accept(start)
    if veto:
        raise CorrectionFailed(f"the curve's first point: {veto}")
    return start


def trace_half(curve: CurveSystem, start: np.ndarray, sign: float, settings: Settings,
               accept: Callable[[np.ndarray], str | None] = lambda v: None,
               progress: Callable[[int, Point], None] = lambda n, p: None,
               explain: Callable[[Branch], str] = lambda b: b.stop_reason) -> Branch:
    """The curve from its first point ``start`` one way: towards decreasing (``sign`` < 0)
    or increasing second parameter. The half is traced on a fresh copy of ``curve``, its
    border set afresh at ``start``, so that it depends on ``start`` alone: the two halves
    can be traced in either order, or at once in two processes, with the same points."""
    direction = np.zeros(len(start))
    direction[-1] = sign
    half = continue_branch(type(curve)(curve.base, curve.kind), start, direction, settings, accept=accept,
                           progress=progress)
    return replace(half, stop_reason=explain(half))


def trace_curve(curve: CurveSystem, v: np.ndarray, settings: Settings,
                accept: Callable[[np.ndarray], str | None] = lambda v: None,
                progress: Callable[[int, Point], None] = lambda n, p: None,
                explain: Callable[[Branch], str] = lambda b: b.stop_reason) -> Branch:
    """The curve through ``v`` (a point near it) traced both ways within the settings'
    ranges (:data:`CURVE_DIRECTIONS`), joined. ``accept`` may veto points (e.g. not
    verified); ``explain`` words each end's stop.

    Parameters
    ----------
    curve : CurveSystem
        The curve's equations: the fixed-point equations and the bifurcation's condition.
    v : array
        A point near the curve, in the curve's scaled coordinates.
    settings : Settings
        Steps, the two parameters' ranges and the corrector's tolerances.
    accept, progress : callable
        As :func:`baslip.numerics.continuation.continue_branch`'s.
    explain : callable
        ``explain(half)``: the words for why a half of the curve stopped.

    Returns
    -------
    Branch
        The curve's points from one end to the other.
    """
    start = curve_start(curve, v, settings, accept)
    return join(*(trace_half(curve, start, sign, settings, accept, progress, explain) for sign in CURVE_DIRECTIONS))


def stability_boundary(kind: str, A: np.ndarray) -> bool:
    """Whether a point of a curve of ``kind`` bounds a region of stable gaits: all the
    map's multipliers but the critical ones lie inside the unit circle."""
    mu = np.linalg.eigvals(A)
    if kind == "neimark_sacker":
        others = np.delete(mu, list(critical_pair(mu)))
    else:
        others = np.delete(mu, int(np.argmin(np.abs(mu - (1.0 if kind == "fold" else -1.0)))))
    return bool(np.all(np.abs(others) < 1.0))


class SmoothMap:
    """A smooth map x -> f(x, (l1, l2)) as a ``base`` of :class:`CurveSystem`, for
    testing the curves on maps whose bifurcation curves are known in closed form.

    ``f`` is a CasADi Function of (x (k), p (2)); v = (x, l1, l2), unscaled.
    """

    #: Its Jacobian's derivatives are the map's own.
    normal_forms = True

    def __init__(self, f: ca.Function):
        x, p = ca.SX.sym("x", f.size1_in(0)), ca.SX.sym("p", 2)
        y = f(x, p)
        self.size = f.size1_in(0)
        self._f = ca.Function("f", [x, p], [y])
        by_x = ca.jacobian(y, x)
        self._jac = ca.Function("J", [x, p], [by_x, ca.jacobian(y, p)])
        seed = ca.SX.sym("seed", self.size, self.size)
        self._jac_gradient = ca.Function("dJ", [x, p, seed], [ca.gradient(ca.dot(seed, by_x), ca.vertcat(x, p))])

    def _split(self, v):
        return np.asarray(v[: self.size], dtype=float), np.asarray(v[self.size :], dtype=float)

    def residual(self, v: np.ndarray) -> np.ndarray:
        x, p = self._split(v)
        return np.asarray(self._f(x, p)).ravel() - x

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        x, p = self._split(v)
        by_x, by_p = (np.asarray(m) for m in self._jac(x, p))
        return np.hstack([by_x - np.eye(self.size), by_p])

    def map_jacobian(self, v: np.ndarray, shift: np.ndarray | None = None) -> np.ndarray:
        x, p = self._split(v)
        return np.asarray(self._jac(x if shift is None else x + shift, p)[0])

    def map_jacobian_gradient(self, v: np.ndarray, seed: np.ndarray) -> np.ndarray:
        x, p = self._split(v)
        return np.asarray(self._jac_gradient(x, p, seed)).ravel()

    def multipliers(self, v: np.ndarray):
        mu = np.linalg.eigvals(self.map_jacobian(v))
        return mu, [False] * len(mu)
