"""Pseudo-arclength continuation of fixed points, with detection of special points.

The engine is generic: a :class:`System` gives n equations F(v) = 0 in n + 1 scaled
unknowns v = (w, lambda), their Jacobian, and the return-map multipliers at a point. From
a solution, each step predicts along the unit tangent t (the null vector of dF/dv,
oriented like the previous one) and corrects with Newton on [F(v); t.(v - v_pred)] = 0.
Steps grow after easy corrections and halve after failed ones, so the branch passes
through folds, where lambda turns back.

Special points, found by sign changes of test functions between consecutive points, and
then located by regula falsi (Illinois) on the arclength until lambda is known to 1e-7:

* ``fold``: the lambda component of the tangent changes sign *and* a multiplier crosses +1
  (the product of (mu - 1) over the non-trivial real multipliers changes sign): a
  saddle-node of the map. Without that evidence the point is a ``turning_point``: the
  path turns back in lambda, which happens when lambda is an apex coordinate (the branch
  folds over in that coordinate) without any multiplier at +1. On a branch of symmetric
  gaits (a system with ``symmetric``: a law of positions only, VPP) a second real
  multiplier crossing +1 is a ``fold`` whether or not the path turns: the symmetric
  branch passes straight through it (at 3.9 m/s in r_vpp, human scale), and it bounds
  stable gaits as a saddle-node does. Turning points are then not reported;
* ``period_doubling``: det(I + dr/dX) (a multiplier crosses -1);
* ``neimark_sacker``: the product of (|mu|^2 - 1) over the complex pairs;
* ``branch_point``: det of the bordered Jacobian [dF/dv; t].

Multipliers that are 1 by structure (energy, free spin) are never tested for crossing 1
(folds come from the tangent, not from det(dr/dX - I)), so they raise no false alarms.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from baslip.errors import RunError
from baslip.numerics.corrector import broyden_update

SPECIAL_TYPES = ("fold", "period_doubling", "neimark_sacker", "branch_point")
LOCATE_TOLERANCE = 1e-7  # on lambda (scaled units)
LOCATE_MAX_NEWTON = 60
#: A Newton step shorter than this (scaled) keeps the Jacobian for the next one.
CHORD_STEP = 1e-6
#: :func:`correct_updated`: a step with an updated Jacobian must leave at most this
#: fraction of the residual, or the Jacobian is refreshed at the iterate; its steps at
#: most; and the steps of a correction that counts as easy.
UPDATED_RATE = 0.25
UPDATED_STEPS = 24
EASY_UPDATED_STEPS = 6


class CorrectionFailed(RunError):
    """Newton did not converge (or the runner fell) at a trial point."""


class System(Protocol):
    """The equations F(v) = 0 a branch follows (v: the unknowns, the parameter last).

    A system may also set ``costly_jacobian`` (True where its Jacobian costs many
    residuals, as a curve's does: the corrector then updates the last point's, see
    :func:`correct_updated`), and define ``test_functions``, ``special_types``,
    ``parameter_count``, ``crossing_veto`` and ``symmetric``, read where they are used.
    """

    def residual(self, v: np.ndarray) -> np.ndarray: ...
    def jacobian(self, v: np.ndarray) -> np.ndarray: ...  # n x (n + 1)
    def multipliers(self, v: np.ndarray) -> tuple[np.ndarray, list[bool]]: ...  # values, trivial?


@dataclass(frozen=True)
class Settings:
    """Step control (scaled arclength) and limits of a continuation run."""

    step: float = 0.05
    min_step: float = 1e-6
    max_step: float = 0.5
    max_points: int = 200
    lam_range: tuple[float, float] = (-math.inf, math.inf)  # scaled lambda (the last unknown)
    #: Further ranges, (index of the unknown, lo, hi) in scaled units: a curve in two
    #: parameters keeps both inside their ranges.
    other_ranges: tuple[tuple[int, float, float], ...] = ()
    tolerance: float = 1e-10  # on |F|
    max_newton: int = 8


@dataclass(frozen=True)
class Point:
    """An accepted point of the branch (scaled v), its tangent and test functions."""

    v: np.ndarray
    tangent: np.ndarray
    multipliers: np.ndarray
    trivial: list[bool]
    tests: dict[str, float]
    special: str = ""
    #: dF/dv at the point, kept for the next corrector of a system whose Jacobian is
    #: costly (see :func:`correct_updated`).
    jacobian: np.ndarray | None = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class Branch:
    """The points of a traced branch, in order along it, and why the tracing stopped."""

    points: list[Point] = field(default_factory=list)
    stop_reason: str = ""

    @property
    def special(self) -> list[Point]:
        return [p for p in self.points if p.special]


def tangent_of(jac: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    """Unit null vector of the n x (n + 1) Jacobian, oriented along ``previous``."""
    _, _, vt = np.linalg.svd(jac)
    t = vt[-1]
    if previous is not None and np.dot(t, previous) < 0:
        t = -t
    return t / np.linalg.norm(t)


def test_functions(jac: np.ndarray, tangent: np.ndarray, multipliers: np.ndarray, trivial: list[bool],
                   symmetric: bool = False) -> dict[str, float]:
    """The branch's test functions at a point (see the module docstring); with
    ``symmetric`` (a law of positions only) the fold's is the +1 crossing itself."""
    nontrivial = np.array([m for m, t in zip(multipliers, trivial) if not t])
    complex_pairs = [m for m in nontrivial if m.imag > 1e-9]
    real = [m.real for m in nontrivial if abs(m.imag) <= 1e-9]
    multiplier_one = float(np.prod([m - 1.0 for m in real])) if real else math.nan
    return {
        "fold": multiplier_one if symmetric else float(tangent[-1]),
        "multiplier_one": multiplier_one,
        "period_doubling": float(np.real(np.prod(1.0 + multipliers))),
        "neimark_sacker": float(np.prod([abs(m) ** 2 - 1.0 for m in complex_pairs])) if complex_pairs else math.nan,
        "branch_point": float(np.linalg.det(np.vstack([jac, tangent]))),
        "complex_pairs": float(len(complex_pairs)),
    }


def correct(system: System, v_pred: np.ndarray, tangent: np.ndarray, settings: Settings) -> tuple[np.ndarray, int]:
    """Newton on the bordered system from ``v_pred``; returns the point and iterations.

    After a step shorter than :data:`CHORD_STEP` the Jacobian is kept (a chord step):
    there Newton has converged to about the square of that step, and the step that
    confirms it (below 1e-10) is as short with the Jacobian of the last iterate."""
    v, dv, jac = v_pred.copy(), np.full(len(v_pred), np.inf), None
    for iteration in range(1, settings.max_newton + 1):
        f = system.residual(v)
        g = np.concatenate([f, [np.dot(tangent, v - v_pred)]])
        if jac is None or np.linalg.norm(dv) >= CHORD_STEP:
            jac = np.vstack([system.jacobian(v), tangent])
        try:
            dv = np.linalg.solve(jac, -g)
        except np.linalg.LinAlgError:
            raise CorrectionFailed("singular Newton matrix") from None
        v = v + dv
        if np.linalg.norm(dv) < 1e-10 and np.linalg.norm(system.residual(v)) <= settings.tolerance:
            return v, iteration
    if np.linalg.norm(system.residual(v)) <= settings.tolerance:
        return v, settings.max_newton
    raise CorrectionFailed("Newton did not converge")


def correct_updated(system: System, v_pred: np.ndarray, tangent: np.ndarray, jacobian: np.ndarray,
                    settings: Settings) -> tuple[np.ndarray, bool]:
    """Newton on the bordered system from ``v_pred``, starting with ``jacobian`` (dF/dv at
    a point nearby, such as the last point of the branch) and updating it by Broyden's
    formula after every step, so that residuals, not Jacobians, do most of the work. A
    step that does not cut the residual to :data:`UPDATED_RATE` of what it was is taken
    again with the Jacobian at the iterate. Converged as :func:`correct` is: a step below
    1e-10 and |F| within the tolerance.

    Returns the point and whether the correction was easy (no Jacobian was needed, in at
    most :data:`EASY_UPDATED_STEPS` steps): the step control grows the step after an easy
    one.
    """
    v = v_pred.copy()
    matrix = np.vstack([jacobian, tangent])
    bordered = np.concatenate([system.residual(v), [0.0]])
    fresh, refreshes = False, 0
    for step in range(1, UPDATED_STEPS + 1):
        try:
            dv = np.linalg.solve(matrix, -bordered)
        except np.linalg.LinAlgError:
            raise CorrectionFailed("singular Newton matrix") from None
        trial = v + dv
        f = system.residual(trial)
        if np.linalg.norm(dv) < 1e-10 and np.linalg.norm(f) <= settings.tolerance:
            return trial, refreshes == 0 and step <= EASY_UPDATED_STEPS
        at_trial = np.concatenate([f, [np.dot(tangent, trial - v_pred)]])
        if not fresh and np.linalg.norm(at_trial) > UPDATED_RATE * np.linalg.norm(bordered):
            if refreshes == settings.max_newton:
                break
            matrix, fresh, refreshes = np.vstack([system.jacobian(v), tangent]), True, refreshes + 1
            continue
        matrix = broyden_update(matrix, dv, at_trial - bordered)
        v, bordered, fresh = trial, at_trial, False
    raise CorrectionFailed("Newton did not converge")


def make_point(system: System, v: np.ndarray, previous_tangent: np.ndarray | None) -> Point:
    """The point at the solution ``v``, with its tangent and test functions (the
    system's own, if it defines ``test_functions``, else those of a branch)."""
    jac = system.jacobian(v)
    t = tangent_of(jac, previous_tangent)
    multipliers, trivial = system.multipliers(v)
    tests = getattr(system, "test_functions", None)
    values = tests(v, jac, t) if tests else test_functions(jac, t, multipliers, trivial,
                                                           getattr(system, "symmetric", False))
    return Point(v, t, multipliers, trivial, values, jacobian=jac)


def special_types(system: System) -> tuple[str, ...]:
    """The special points ``system`` is searched for."""
    return getattr(system, "special_types", SPECIAL_TYPES)


def _ranges(settings: Settings) -> list[tuple[int, float, float]]:
    return [(-1, *settings.lam_range), *settings.other_ranges]


def _outside(v: np.ndarray, settings: Settings) -> tuple[int, float] | None:
    """The first range ``v`` leaves, as (index, the bound it passes), or None."""
    for index, lo, hi in _ranges(settings):
        if not lo <= v[index] <= hi:
            return index, (hi if v[index] > hi else lo)
    return None


def _inside(v: np.ndarray, settings: Settings) -> bool:
    return _outside(v, settings) is None


def continue_branch(
    system: System,
    v0: np.ndarray,
    direction: float | np.ndarray,
    settings: Settings,
    accept: Callable[[np.ndarray], str | None] = lambda v: None,
    progress: Callable[[int, Point], None] = lambda n, p: None,
) -> Branch:
    """Trace the branch from the solution ``v0`` towards increasing (direction > 0) or
    decreasing lambda, or, if ``direction`` is a vector, along the tangent that points
    with it. ``accept(v)`` may veto a point with a reason (e.g. not verified).

    Parameters
    ----------
    system : System
        The equations F(v) = 0 and their multipliers and test functions.
    v0 : array
        A solution, in the system's scaled coordinates (the parameters last).
    direction : float or array
        The sign of the first step in the (last) parameter, or a vector the first
        tangent must point with.
    settings : Settings
        Steps, ranges and the corrector's tolerances.
    accept : callable
        ``accept(v)``: None, or why the point ``v`` is refused (the step is then halved).
    progress : callable
        ``progress(count, point)``, called after each accepted point.

    Returns
    -------
    Branch
        The points in order, special points located between them, and why it stopped.
    """
    if np.isscalar(direction):
        direction = np.concatenate([np.zeros(len(v0) - 1), [direction]])
    # The test functions depend on the tangent's sign, so it is oriented before they are
    # evaluated (a flip afterwards would fake a branch point at the first step).
    points = [make_point(system, v0, np.asarray(direction, dtype=float))]
    h = settings.step
    while True:
        if len(points) >= settings.max_points:
            return Branch(points, "maximum number of points")
        here = points[-1]
        try:
            v, easy = _correct_from(system, here, here.v + h * here.tangent, here.tangent, settings)
            point = make_point(system, v, here.tangent)
        except CorrectionFailed as err:
            if h / 2 < settings.min_step:
                return Branch(points, f"step too small ({err})")
            h /= 2
            continue
        veto = accept(point.v)
        if veto:
            if h / 2 < settings.min_step:
                return Branch(points, veto)
            h /= 2
            continue
        outside = _outside(point.v, settings)
        # End exactly on the range's end, never beyond it (None: no point there).
        end = _on_bound(system, here, point, *outside, settings, accept) if outside else point
        if end is not None:
            for kind in _crossings(system, here, end):
                located = locate(system, here, end, kind, settings)
                if _inside(located.v, settings):
                    points.append(located)
            points.append(end)
            progress(len(points), end)
        if outside:
            return Branch(points, "end of range")
        h = min(h * 1.5, settings.max_step) if easy else max(h * 0.7, settings.min_step)


def _correct_from(system: System, near: Point, start: np.ndarray, tangent: np.ndarray,
                  settings: Settings) -> tuple[np.ndarray, bool]:
    """The corrector from ``start`` with the hyperplane of ``tangent``, and whether it was
    easy: :func:`correct_updated` from ``near``'s Jacobian where the system's Jacobian is
    costly (``costly_jacobian``, as a curve's second derivatives are), else
    :func:`correct` (easy in at most 3 iterations)."""
    if getattr(system, "costly_jacobian", False) and near.jacobian is not None:
        return correct_updated(system, start, tangent, near.jacobian, settings)
    v, iterations = correct(system, start, tangent, settings)
    return v, iterations <= 3


def _on_bound(system: System, here: Point, beyond: Point, index: int, bound: float, settings: Settings,
              accept) -> Point | None:
    """The branch's point with unknown ``index`` at ``bound``, between ``here`` and
    ``beyond`` (Newton with that unknown held, from the chord), if it converges, is
    accepted and lies inside the other ranges."""
    fraction = (bound - here.v[index]) / (beyond.v[index] - here.v[index])
    start = here.v + fraction * (beyond.v - here.v)
    start[index] = bound
    held = np.zeros(len(start))
    held[index] = 1.0
    try:
        v, _ = correct(system, start, held, settings)
    except CorrectionFailed:
        return None
    v[index] = bound  # exactly: Newton holds it to round-off
    if accept(v) or not _inside(v, settings):
        return None
    return make_point(system, v, here.tangent)


def join(lower: Branch, upper: Branch) -> Branch:
    """One branch from two traced from the same start in opposite directions: ``lower``'s
    points reversed, then ``upper``'s (the start once)."""
    points = list(reversed(lower.points)) + upper.points[1:]
    return Branch(points, f"lower end: {lower.stop_reason}; upper end: {upper.stop_reason}")


def switch_direction(system: System, point: Point) -> np.ndarray:
    """Unit direction of the branch that crosses ``point``'s branch at ``point``, a branch
    point of ``system``.

    There dF/dv has a two-dimensional null space, spanned by the known branch's tangent
    and the new branch's; the new direction is the null vector orthogonal to the known
    tangent. (At a period doubling of r, the branch of orbits of twice the period crosses
    the old branch this way in the equations of r^2.)
    """
    null = np.linalg.svd(system.jacobian(point.v))[2][-2:]
    along_known = null @ point.tangent
    direction = null.T @ np.array([-along_known[1], along_known[0]])
    return direction / np.linalg.norm(direction)


def switch_branch(system: System, point: Point, amplitude: float, settings: Settings) -> tuple[np.ndarray, np.ndarray]:
    """First solution on the branch that crosses at ``point``, ``amplitude`` (scaled
    arclength) along :func:`switch_direction`; returns it and that direction."""
    direction = switch_direction(system, point)
    v, _ = correct(system, point.v + amplitude * direction, direction, settings)
    return v, direction


def _crossings(system: System, a: Point, b: Point) -> list[str]:
    kinds = []
    for kind in special_types(system):
        x, y = a.tests[kind], b.tests[kind]
        if kind == "neimark_sacker" and a.tests["complex_pairs"] != b.tests["complex_pairs"]:
            continue  # a pair turned real: not a crossing of the unit circle
        veto = getattr(system, "crossing_veto", None)
        if veto and veto(kind, a, b):
            continue
        if math.isfinite(x) and math.isfinite(y) and x * y < 0:
            kinds.append(kind)
    return kinds


def locate(system: System, a: Point, b: Point, kind: str, settings: Settings) -> Point:
    """The point between a and b where test function ``kind`` vanishes.

    Regula falsi (Illinois) on s, the arclength from a along its tangent: each trial is
    the branch's point on the hyperplane orthogonal to that tangent at s. Newton starts
    from the nearest point found so far, extrapolated along its own tangent onto the
    hyperplane. Near a branch point another branch crosses close by, and a start far away
    (such as a's tangent line) can converge onto it.
    """
    span = float(np.dot(b.v - a.v, a.tangent))
    s_lo, s_hi, f_lo, f_hi = 0.0, span, a.tests[kind], b.tests[kind]
    # At a branch point the corrector's Jacobian is singular, so Newton converges only
    # linearly close to it: allow it the iterations that takes.
    settings = replace(settings, max_newton=max(settings.max_newton, LOCATE_MAX_NEWTON))
    known = [(0.0, a), (span, b)]
    # The parameters are the last unknowns: one on a branch, two on a curve.
    params = slice(-getattr(system, "parameter_count", 1), None)
    best, lam_lo, lam_hi, last_moved = b, a.v[params], b.v[params], ""
    for _ in range(60):
        s = s_lo - f_lo * (s_hi - s_lo) / (f_hi - f_lo)
        if not min(s_lo, s_hi) < s < max(s_lo, s_hi):
            s = 0.5 * (s_lo + s_hi)
        s_near, near = min(known, key=lambda k: abs(k[0] - s))
        start = near.v + (s - s_near) / np.dot(near.tangent, a.tangent) * near.tangent
        try:
            v, _ = _correct_from(system, near, start, a.tangent, settings)
        except CorrectionFailed:
            break
        best = make_point(system, v, a.tangent)
        known.append((s, best))
        value = best.tests[kind]
        # Illinois rule: when the same end moves twice running, halve the other end's
        # value, so that the bracket shrinks from both sides.
        if value * f_lo < 0:
            s_hi, f_hi, lam_hi = s, value, best.v[params]
            f_lo = f_lo / 2 if last_moved == "hi" else f_lo
            last_moved = "hi"
        else:
            s_lo, f_lo, lam_lo = s, value, best.v[params]
            f_hi = f_hi / 2 if last_moved == "lo" else f_hi
            last_moved = "lo"
        # At a fold lambda is extremal, so it settles long before s does: both must.
        if (np.max(np.abs(lam_hi - lam_lo)) < LOCATE_TOLERANCE and abs(s_hi - s_lo) < 1e-5) or value == 0.0:
            break
    turning = kind == "fold" and "multiplier_one" in a.tests and not _multiplier_crosses_one(a, b)
    return replace(best, special="turning_point" if turning else kind)


def _multiplier_crosses_one(a: Point, b: Point) -> bool:
    """Whether a non-trivial real multiplier crosses +1 between ``a`` and ``b``."""
    x, y = a.tests["multiplier_one"], b.tests["multiplier_one"]
    return math.isfinite(x) and math.isfinite(y) and x * y < 0
