"""What a stride can end in, shared by every return-map engine.

A stride ends at the next apex or in a named :class:`Fall`; falls are outcomes, not
exceptions. :func:`precheck` finds the falls visible before any integration and brackets
the touchdown time, in closed form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from baslip.errors import RunError
from baslip.model.dynamics import APEX, PARAMS, descent_foot_height

_RHO0, _D, _G = PARAMS.index("rho0"), PARAMS.index("d"), PARAMS.index("g")
#: theta_td is the last control under every hip law (:mod:`baslip.model.hiplaw`).
_THETA_TD = -1
_Z, _THETA_H, _SPIN = APEX.index("z"), APEX.index("theta_h"), APEX.index("theta_h_dot")

PHASES = ("descent", "compression", "decompression", "ascent")

#: Stance that has not ended after this many spring half-periods pi*sqrt(m/k) "never ends".
STANCE_HORIZON_HALF_PERIODS = 40.0
#: The work limit of one stride: the most fixed steps the compiled engine's scout takes
#: to find the stance's events. A stride of the design box takes a few hundred to some
#: ten thousand; one whose hip is far stiffer than its spring (Kd = 1e9 N m s/rad) would
#: take about 1e10, and ends as :attr:`Fall.WORK_LIMIT` instead.
MAX_STANCE_STEPS = 1_000_000


class Fall(str, Enum):
    """Named reasons a stride does not reach the next apex."""

    FOOT_BELOW_GROUND = "foot below ground at apex"
    NO_TOUCHDOWN = "no touchdown (leg cannot reach the ground)"
    LEG_EXTENDING_AT_TOUCHDOWN = "leg extending at touchdown (rhodot >= 0)"
    COM_HITS_GROUND = "CoM touches the ground"
    HIP_HITS_GROUND = "hip touches the ground"
    LEG_COLLAPSES = "leg collapses (rho below floor)"
    STANCE_NEVER_ENDS = "stance never ends"
    LIFTOFF_DESCENDING = "liftoff with zdot <= 0"
    NOT_FINITE = "non-finite state"
    INTEGRATION_FAILED = "integration failed"
    WORK_LIMIT = f"work limit reached (stance needs more than {MAX_STANCE_STEPS:,} integration steps)"


@dataclass(frozen=True)
class Tolerances:
    """Integrator tolerances (relative and absolute) of a return map.

    Attributes
    ----------
    rtol : float
        Relative tolerance (dimensionless).
    atol : float
        Absolute tolerance, in the integrated states' SI units and radians. The compiled
        engine holds its error estimate to the smaller of the two.
    """

    rtol: float = 1e-10
    atol: float = 1e-10


@dataclass(frozen=True)
class Stride:
    """Outcome of one stride: the next apex, or the reason the runner fell.

    Attributes
    ----------
    apex : numpy.ndarray or None
        The next apex X, shape (4,): z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s];
        None after a fall.
    durations : dict of str to float
        Duration [s] of each phase reached (``descent``, ``compression``,
        ``decompression``, ``ascent``); phases not reached are absent.
    fall : Fall or None
        Why the runner fell, or None if the stride reached the next apex.
    error : float or None
        The engine's error estimate of the stance integration, if it has one.
    """

    apex: np.ndarray | None  # next apex X [z m, theta_h rad, ydot m/s, theta_h_dot rad/s]
    durations: dict[str, float]  # phase -> duration [s]; phases not reached are absent
    fall: Fall | None = None
    error: float | None = None  # the engine's error estimate of the stance integration, if it has one

    @property
    def ok(self) -> bool:
        """Whether the stride reached the next apex (no fall)."""
        return self.fall is None

    def __repr__(self) -> str:
        if self.fall is not None:
            return f"<Stride fell: {self.fall.value}>"
        assert self.apex is not None
        time = sum(self.durations.values())
        return f"<Stride to z = {self.apex[0]:.6g} m, ydot = {self.apex[2]:.6g} m/s in {time:.4g} s>"

    def _repr_html_(self) -> str:
        return repr(self).replace("<", "&lt;").replace(">", "&gt;")


@dataclass(frozen=True)
class Simulation:
    """Apex sequence of a multi-stride run; ``fall`` is set if it ended early.

    Attributes
    ----------
    apexes : numpy.ndarray
        The apexes reached, shape (n + 1, 4) after n strides, the initial apex first; each
        row z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s].
    durations : list of dict of str to float
        Per completed stride, the duration [s] of each phase.
    fall : Fall or None
        Why the run ended early, or None if every stride reached its apex.
    fall_stride : int or None
        0-based index of the stride that fell, or None.
    """

    apexes: np.ndarray  # (n + 1) x 4, the initial apex first
    durations: list[dict[str, float]] = field(default_factory=list)
    fall: Fall | None = None
    fall_stride: int | None = None  # 0-based index of the stride that fell

    def __repr__(self) -> str:
        strides = len(self.apexes) - 1
        end = f", then fell in stride {self.fall_stride}: {self.fall.value}" if self.fall is not None else ""
        return f"<Simulation: {strides} strides{end}>"

    def _repr_html_(self) -> str:
        return repr(self).replace("<", "&lt;").replace(">", "&gt;")


class RunnerFell(RunError):
    """Raised by :meth:`ReturnMap.__call__` when a stride falls; carries the :class:`Fall`."""

    def __init__(self, fall: Fall):
        super().__init__(fall.value)
        self.fall = fall


class NoSecondDerivatives(RunError):
    """The compiled engine cannot vouch for this stride, so it has no second derivatives."""


def touchdown_guess(X, u, p) -> float | None:
    """First zero of the foot height after apex, bracketed then refined to round-off [s].

    Returns None when the foot cannot reach the ground. The foot height is
    h(t) = c - g t^2/2 - d sin(theta_h + w t) with c = z - rho0 cos(theta_td), so
    h < 0 for all t > sqrt(2 (c + d) / g): the first root lies in that bracket. It is
    found on a grid of :data:`TOUCHDOWN_GRID` points over the bracket, then refined to
    round-off; the rootfinders of the engines converge on it from this guess.
    :func:`touchdown_guesses` gives the same numbers for many apexes at once.
    """
    z, theta_h, spin = float(X[_Z]), float(X[_THETA_H]), float(X[_SPIN])
    rho0, d, g = float(p[_RHO0]), float(p[_D]), float(p[_G])
    theta_td = float(u[_THETA_TD])
    if not abs(theta_td) < math.pi / 2:
        return None
    clearance = z - rho0 * math.cos(theta_td)
    grid = _descent_bound(clearance, d, g) * _GRID_FRACTIONS
    below = np.nonzero(descent_foot_height(grid[1:], z, theta_h, spin, theta_td, d, rho0, g) <= 0.0)[0]
    if len(below) == 0:
        return None
    return _refine_root(grid[below[0]], grid[below[0] + 1], theta_h, spin, clearance, d, g)


#: Points of the grid that brackets the first touchdown root.
TOUCHDOWN_GRID = 257
_GRID_FRACTIONS = np.linspace(0.0, 1.0, TOUCHDOWN_GRID)


def touchdown_guesses(X: np.ndarray, U: np.ndarray, p) -> np.ndarray:
    """:func:`touchdown_guess` from each apex (rows of X, n x 4) under the rows of U
    (n x controls), the grid search done for all rows at once; NaN where the foot cannot reach
    the ground."""
    X, U, p = np.asarray(X, dtype=float), np.asarray(U, dtype=float), np.asarray(p, dtype=float)
    found, lo, hi = _touchdown_brackets(X, U, p)
    clearance = X[:, _Z] - float(p[_RHO0]) * np.cos(U[:, _THETA_TD])
    guesses = np.full(len(X), np.nan)
    rows = np.nonzero(found)[0]
    guesses[rows] = _refine_roots(lo[rows], hi[rows], X[rows, _THETA_H], X[rows, _SPIN], clearance[rows],
                                  float(p[_D]), float(p[_G]))
    return guesses


#: Grid intervals searched at a time for the first touchdown root, per row.
BRACKET_CHUNK = 32
#: Fraction of the time t_low = sqrt(2 (c - |d|) / g) before which the grid is not searched:
#: there the foot height is at least (1 - 0.9^2) (c - |d|) > 0, far above round-off.
SURELY_ABOVE = 0.9


def _touchdown_brackets(X: np.ndarray, U: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The grid search of :func:`touchdown_guess` for the rows of X under the rows of U:
    whether the foot reaches the ground, and the times [s] that bracket each row's first
    root. Each row's grid is searched :data:`BRACKET_CHUNK` intervals at a time, from
    where a root becomes possible (:data:`SURELY_ABOVE`) until its first root: the heights
    are those of the whole grid, computed alike, so the brackets are the same."""
    z, theta_h, spin = X[:, _Z], X[:, _THETA_H], X[:, _SPIN]
    rho0, d, g = float(p[_RHO0]), float(p[_D]), float(p[_G])
    theta_td = U[:, _THETA_TD]
    clearance = z - rho0 * np.cos(theta_td)
    bound = _descent_bound(clearance, d, g)
    intervals = TOUCHDOWN_GRID - 1
    start = _first_possible_interval(clearance, z, bound, d, rho0, g)
    first, found = np.zeros(len(X), dtype=int), np.zeros(len(X), dtype=bool)
    pending = np.arange(len(X))
    for offset in range(0, intervals, BRACKET_CHUNK):
        j = start[pending, None] + offset + np.arange(BRACKET_CHUNK)  # intervals, ending at grid point j + 1
        t = bound[pending, None] * _GRID_FRACTIONS[np.minimum(j, intervals - 1) + 1]
        height = descent_foot_height(t, z[pending, None], theta_h[pending, None], spin[pending, None],
                                     theta_td[pending, None], d, rho0, g)
        below = (height <= 0.0) & (j < intervals)
        hit = below.any(axis=1)
        first[pending[hit]] = j[hit, np.argmax(below[hit], axis=1)]
        found[pending[hit]] = True
        pending = pending[~hit & (j[:, -1] < intervals - 1)]
        if not pending.size:
            break
    reaches = np.abs(theta_td) < math.pi / 2
    return reaches & found, bound * _GRID_FRACTIONS[first], bound * _GRID_FRACTIONS[first + 1]


def _first_possible_interval(clearance, z, bound, d: float, rho0: float, g: float) -> np.ndarray:
    """Per row, the first grid interval that may hold the touchdown root: the grid points
    before it lie before SURELY_ABOVE t_low, where h(t) >= c - |d| - g t^2 / 2 > 0. Rows
    whose margin c - |d| is not far above round-off are searched from the start."""
    margin = clearance - abs(d)
    safe = margin > 1e-12 * (1.0 + np.abs(z) + rho0 + abs(d))
    t_low = np.sqrt(2.0 * np.maximum(margin, 0.0) / g)
    last_above = np.searchsorted(_GRID_FRACTIONS, SURELY_ABOVE * t_low / bound, side="right") - 1
    return np.where(safe, np.clip(last_above, 0, TOUCHDOWN_GRID - 2), 0)


def strides_can_start(X: np.ndarray, U: np.ndarray, p) -> np.ndarray:
    """Whether :func:`precheck` finds no fall from each apex (rows of X, n x 4) under the
    rows of U (n x controls), without refining the touchdown times: the cheap test of many
    points at once."""
    X, U, p = np.asarray(X, dtype=float), np.asarray(U, dtype=float), np.asarray(p, dtype=float)
    X, U, _, above = _apex_checks(X, U, p)
    return above & _touchdown_brackets(X, U, p)[0]


def _apex_checks(X: np.ndarray, U: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(X, U with non-finite rows zeroed, which rows are finite, which of those have the
    foot above ground at the apex): the checks before the touchdown search."""
    finite = np.isfinite(X).all(axis=1) & np.isfinite(U).all(axis=1) & bool(np.isfinite(p).all())
    if not finite.all():  # keep non-finite rows out of the trigonometry (no warnings)
        X, U = np.where(finite[:, None], X, 0.0), np.where(finite[:, None], U, 0.0)
    above = finite & (_foot_height_at_apex(X[:, _Z], X[:, _THETA_H], U[:, _THETA_TD], p) >= 0.0)
    return X, U, finite, above


def _descent_bound(clearance, d: float, g: float):
    """Time after apex [s] past which the foot is surely below ground (numbers or arrays)."""
    return np.sqrt(2.0 * np.maximum(clearance + d, 0.0) / g) + 1e-9


def _refine_root(lo: float, hi: float, theta_h: float, w: float, clearance: float, d: float, g: float) -> float:
    """The root of h(t) = clearance - g t^2/2 - d sin(theta_h + w t) in [lo, hi] (h(lo) > 0
    >= h(hi)), to round-off: Newton, with a bisection whenever it would leave the bracket."""
    t = 0.5 * (lo + hi)
    for _ in range(60):
        height = clearance - 0.5 * g * t * t - d * math.sin(theta_h + w * t)
        if height > 0.0:
            lo = t
        else:
            hi = t
        slope = -g * t - d * w * math.cos(theta_h + w * t)
        t_new = t - height / slope if slope < 0.0 else 0.5 * (lo + hi)
        # Converged before the bracket test: a Newton update that rounds to nothing lands
        # on the bracket's end, which would otherwise force a needless bisection.
        if abs(t_new - t) <= 1e-15 * t or hi - lo <= 1e-15 * hi:
            return t_new if lo <= t_new <= hi else t
        if not lo < t_new < hi:
            t_new = 0.5 * (lo + hi)
        t = t_new
    return t


def _refine_roots(lo: np.ndarray, hi: np.ndarray, theta_h: np.ndarray, w: np.ndarray, clearance: np.ndarray,
                  d: float, g: float) -> np.ndarray:
    """:func:`_refine_root` of each entry of the arrays at once, with the same arithmetic in
    the same order, so that each root is the single one to the bit; each entry stops at
    its own convergence."""
    lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
    t = 0.5 * (lo + hi)
    roots = t.copy()
    live = np.arange(len(t))
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(60):
            if not live.size:
                break
            t_now, lower, upper = t[live], lo[live], hi[live]
            angle = theta_h[live] + w[live] * t_now
            height = clearance[live] - 0.5 * g * t_now * t_now - d * np.sin(angle)
            lower, upper = np.where(height > 0.0, t_now, lower), np.where(height > 0.0, upper, t_now)
            slope = -g * t_now - d * w[live] * np.cos(angle)
            t_new = np.where(slope < 0.0, t_now - height / slope, 0.5 * (lower + upper))
            done = (np.abs(t_new - t_now) <= 1e-15 * t_now) | (upper - lower <= 1e-15 * upper)
            roots[live[done]] = np.where((lower <= t_new) & (t_new <= upper), t_new, t_now)[done]
            t_new = np.where((lower < t_new) & (t_new < upper), t_new, 0.5 * (lower + upper))
            lo[live], hi[live], t[live] = lower, upper, t_new
            live = live[~done]
    roots[live] = t[live]
    return roots


def precheck(X, u, p) -> tuple[Stride | None, float | None]:
    """Checks before any integration: a fall found already, or the touchdown time guess [s].
    :func:`prechecks` does the same for many apexes at once."""
    if not (np.isfinite(X).all() and np.isfinite(u).all() and np.isfinite(p).all()):
        return Stride(None, {}, Fall.NOT_FINITE), None
    if _foot_height_at_apex(X[_Z], X[_THETA_H], u[_THETA_TD], p) < 0.0:
        return Stride(None, {}, Fall.FOOT_BELOW_GROUND), None
    t_guess = touchdown_guess(X, u, p)
    if t_guess is None:
        return Stride(None, {}, Fall.NO_TOUCHDOWN), None
    return None, t_guess


def _foot_height_at_apex(z, theta_h, theta_td, p):
    """Foot height [m] at the apex, with the leg at its touchdown angle (numbers or arrays)."""
    return z - p[_D] * np.sin(theta_h) - p[_RHO0] * np.cos(theta_td)


def prechecks(X: np.ndarray, U: np.ndarray, p) -> tuple[list[Stride | None], np.ndarray]:
    """:func:`precheck` of each row of X (n x 4) under the rows of U (n x controls): the falls
    found before any integration (None for the rest) and the touchdown time guesses [s]
    (NaN after a fall)."""
    X, U, p = np.asarray(X, dtype=float), np.asarray(U, dtype=float), np.asarray(p, dtype=float)
    falls: list[Stride | None] = [None] * len(X)
    X, U, finite, above = _apex_checks(X, U, p)
    guesses = np.full(len(X), np.nan)
    guesses[above] = touchdown_guesses(X[above], U[above], p)
    for i in np.nonzero(~finite)[0]:
        falls[i] = Stride(None, {}, Fall.NOT_FINITE)
    for i in np.nonzero(finite & ~above)[0]:
        falls[i] = Stride(None, {}, Fall.FOOT_BELOW_GROUND)
    for i in np.nonzero(above & np.isnan(guesses))[0]:
        falls[i] = Stride(None, {}, Fall.NO_TOUCHDOWN)
    return falls, guesses


def vec(v) -> np.ndarray:
    """``v`` (a number, sequence or array) as a flat float array."""
    return np.asarray(v, dtype=float).ravel()


def param_vector(params) -> np.ndarray:
    """The parameter vector (m, I, k, rho0, d, g) of a :class:`~baslip.model.dynamics.Params`
    or of a sequence already in that order."""
    return params.vector() if hasattr(params, "vector") else vec(params)
