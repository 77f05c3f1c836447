"""The numeric driver of the compiled stride engine (:mod:`baslip.stride`).

For one stride it runs the scout, picks the step count, calls the compiled final pass (or
its Jacobian) and judges the result: an apex, a named fall, or ``None`` where the engine
cannot guarantee its accuracy, so that the caller falls back to the adaptive event map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import PARAMS, STANCE
from .outcome import PHASES, STANCE_HORIZON_HALF_PERIODS, Fall, Stride
from .flow import DOP853
from .stride import (
    CLEARANCES,
    DIAGNOSTICS,
    MAX_SCOUT_STEP_RATE,
    MAX_STEP_RATE,
    PREDICTION_MARGIN,
    SCOUT_STEPS,
    SCOUT_STEPS_PER_HALF_PERIOD,
    TIERS,
    StrideFunctions,
    half_period,
    stiffness_rate,
)

_CLEARANCE_FALLS = {
    "com": Fall.COM_HITS_GROUND,
    "hip": Fall.HIP_HITS_GROUND,
    "leg": Fall.LEG_COLLAPSES,
}
#: Newton on an event step is converged when its last update is below this fraction of
#: the phase duration.
NEWTON_CONVERGED = 1e-13
#: Times the scout starts again with a quarter of its step after its state blows up.
SCOUT_REFINEMENTS = 2
#: The event must end the phase within this many grid steps of the grid's end.
LAST_STEP_RANGE = (0.0, 2.0)
#: Newton iterations on the cubic Hermite interpolant of an event guard.
HERMITE_NEWTON = 8

_RHO, _RHODOT = STANCE.index("rho"), STANCE.index("rhodot")
_RHO0 = PARAMS.index("rho0")
_SCOUT_NODES = np.arange(SCOUT_STEPS + 1)


@dataclass(frozen=True)
class Scouted:
    """Estimated stance event times [s] after touchdown, the stride's step rate [1/s], the
    scout's step [s] and its summed error estimate up to liftoff."""

    bottom: float
    liftoff: float
    rate: float
    step: float
    error: float


class CompiledEngine:
    """One stride by the compiled fixed-step engine, at a stated error bound.

    ``tolerance`` bounds the summed DOP853 error estimate of the stance integration
    (relative to max(1, |x|)); a stride whose estimate stays above it at the finest step
    count, or whose events the scout could not bracket cleanly, returns ``None``.
    """

    def __init__(self, tolerance: float, compile: bool | None = None):
        self.tolerance = tolerance
        self.functions = StrideFunctions(compile)

    def stride(self, X, u, p, t_guess) -> Stride | None:
        """The stride from apex ``X`` (which passed the pre-checks), or None."""
        plan = self._plan(X, u, p, t_guess)
        if not isinstance(plan, tuple):
            return plan
        return self._final(X, u, p, *plan)[1]

    def stride_jacobian(self, X, u, p, t_guess) -> tuple[np.ndarray | None, Stride] | None:
        """(dr/d(X, u, p) as 4 x 15, the stride), the Jacobian None after a fall; or None.

        The step count is settled by value passes, which cost a fraction of a Jacobian."""
        plan = self._plan(X, u, p, t_guess)
        if not isinstance(plan, tuple):
            return None if plan is None else (None, plan)
        n, verdict = self._final(X, u, p, *plan)
        if verdict is None or not verdict.ok:
            return None if verdict is None else (None, verdict)
        jac, *outputs = self.functions.jacobian(n)(X, u, p, plan[1])
        return jac, self.judge(*outputs)

    def settled_pass(self, X, u, p, t_guess) -> tuple[int, np.ndarray] | None:
        """(step count, guesses) of the final pass that :meth:`stride` accepts for a clean
        stride, to evaluate other functions of that same pass; None if there is none."""
        plan = self._plan(X, u, p, t_guess)
        if not isinstance(plan, tuple):
            return None
        n, verdict = self._final(X, u, p, *plan)
        return None if verdict is None or not verdict.ok else (n, plan[1])

    # -- pieces ----------------------------------------------------------------------

    def _final(self, X, u, p, tiers, guesses) -> tuple[int, Stride | None]:
        """The final pass at the first tier whose error estimate is within the tolerance."""
        for n in tiers:
            verdict = self.judge(*self.functions.final(n)(X, u, p, guesses))
            if verdict != "refine":
                return n, verdict
        return tiers[-1], None

    def _plan(self, X, u, p, t_guess):
        """Touchdown checks and the scout: a fall, None, or (tiers to try, guesses)."""
        x_td, com_height, _ = (np.asarray(v).ravel() for v in self.functions.touchdown_state(X, u, p, t_guess))
        fall = touchdown_fall(x_td, float(com_height[0]), t_guess)
        if fall is not None:
            return fall
        descent = {"descent": float(t_guess)}
        scouted = self._scout(x_td, np.concatenate([u, p]), X, u, p)
        if not isinstance(scouted, Scouted):
            return scouted if scouted is None else Stride(None, descent, scouted)
        tiers = self._tiers(scouted)
        if not tiers:
            return None
        return tiers, np.array([t_guess, scouted.bottom, scouted.liftoff - scouted.bottom])

    def _tiers(self, scouted: Scouted) -> list[int]:
        """Step counts to try, finest last: within the rate limit, and starting at the first
        whose error, extrapolated from the scout's estimate with the method's order
        (error ~ h^8), is within the tolerance."""
        longest = max(scouted.bottom, scouted.liftoff - scouted.bottom)
        stable = [n for n in TIERS if longest * scouted.rate / n <= MAX_STEP_RATE]
        predicted = [scouted.error * (longest / n / scouted.step) ** DOP853.order for n in stable]
        first = next((i for i, e in enumerate(predicted) if PREDICTION_MARGIN * e <= self.tolerance), len(stable) - 1)
        return stable[max(first, 0):]

    def _scout(self, x0, theta, X, u, p) -> Scouted | Fall | None:
        """Step stance in chunks until liftoff: the event estimates, a fall, or None."""
        rate = stiffness_rate(X, u, p)
        h = min(half_period(p) / SCOUT_STEPS_PER_HALF_PERIOD, MAX_SCOUT_STEP_RATE / rate)
        horizon = STANCE_HORIZON_HALF_PERIODS * half_period(p)
        rho0 = float(p[_RHO0])
        t0, bottom, error, x_td, refinements = 0.0, None, 0.0, x0, SCOUT_REFINEMENTS
        while t0 < horizon:
            nodes, rates, clearance, errors = self.functions.scout(x0, h, theta)
            if not (np.all(np.isfinite(nodes)) and np.all(np.isfinite(rates))):
                # Unstable steps: the stiffness estimate missed a faster rate. Finer steps
                # from touchdown, a few times; garbage before the blow-up is never read.
                if refinements == 0:
                    return None
                refinements, h, t0, x0, bottom, error = refinements - 1, h / 4, 0.0, x_td, None, 0.0
                continue
            times = t0 + h * _SCOUT_NODES
            rhodot = nodes[_RHODOT]
            if bottom is None:
                j = first_rise(rhodot)
                if j is not None:
                    bottom = hermite_root(times[j - 1 : j + 1], rhodot[j - 1 : j + 1], rates[_RHODOT, j - 1 : j + 1])
            liftoff_step = None
            if bottom is not None:
                stretch = np.where(times >= bottom, nodes[_RHO] - rho0, -1.0)
                liftoff_step = first_rise(stretch)
                graze = first_grazing_step(stretch, rhodot, h)
                if graze is not None and (liftoff_step is None or graze < liftoff_step - 1):
                    fall_step = first_fall_step(clearance, graze)
                    if fall_step is not None:
                        return self._fall_in_step(nodes[:, fall_step], h, theta)
                    liftoff = self._liftoff_in_step(nodes[:, graze], times[graze], h, theta, rho0)
                    if liftoff is not None:
                        return Scouted(bottom, liftoff, rate, h, error + float(np.sum(errors[0, : graze + 1])))
            # The liftoff step itself is left to the final pass, whose last step ends on
            # the event: the runner may touch the ground after leaving it.
            fall_step = first_fall_step(clearance, None if liftoff_step is None else liftoff_step - 1)
            if fall_step is not None:
                return self._fall_in_step(nodes[:, fall_step], h, theta)
            if liftoff_step is not None:
                k = liftoff_step
                liftoff = hermite_root(times[k - 1 : k + 1], stretch[k - 1 : k + 1], rhodot[k - 1 : k + 1])
                return Scouted(bottom, liftoff, rate, h, error + float(np.sum(errors[0, :k])))
            error += float(np.sum(errors))
            x0, t0 = nodes[:, -1], times[-1]
        return Fall.STANCE_NEVER_ENDS

    def _liftoff_in_step(self, x0, t0: float, h: float, theta, rho0: float, depth: int = 3) -> float | None:
        """The first liftoff time [s] inside a step where rho peaks just below rho0 at the
        nodes: the step is re-scouted in finer steps, as often as ``depth`` times, since
        rho may cross rho0 and fall back between two nodes."""
        fine = h / SCOUT_STEPS
        nodes = self.functions.scout(x0, fine, theta)[0]
        times = t0 + fine * np.arange(SCOUT_STEPS + 1)
        stretch, rhodot = STANCE.get(nodes, "rho") - rho0, STANCE.get(nodes, "rhodot")
        k = first_rise(stretch)
        if k is not None:
            return hermite_root(times[k - 1 : k + 1], stretch[k - 1 : k + 1], rhodot[k - 1 : k + 1])
        graze = first_grazing_step(stretch, rhodot, fine)
        if graze is None or depth <= 1:
            return None
        return self._liftoff_in_step(nodes[:, graze], times[graze], fine, theta, rho0, depth - 1)

    def _fall_in_step(self, x0, h, theta, depth: int = 3) -> Fall | None:
        """Which clearance reaches zero first in the step of size ``h`` from ``x0``, by
        re-scouting the step in finer steps (again, as often as ``depth`` times, while
        several clearances fall in one step). None if the finer steps see no fall: the
        coarse step's stage states, rough for fast motion, raised a false alarm, and the
        careful path decides."""
        fine = h / SCOUT_STEPS
        nodes, _, clearance, _ = self.functions.scout(x0, fine, theta)
        if not np.all(np.isfinite(nodes)):
            return None
        step = first_fall_step(clearance, None)
        if step is None:
            return None
        hit = clearance[:, step] <= 0.0
        if np.count_nonzero(hit) > 1 and depth > 1:
            return self._fall_in_step(nodes[:, step], fine, theta, depth - 1)
        return _CLEARANCE_FALLS[CLEARANCES[int(np.argmax(hit))]]

    def judge(self, apex, durations, diagnostics) -> Stride | str | None:
        """The stride, "refine" (error estimate too large) or None (cannot vouch for it)."""
        apex, durations = np.asarray(apex).ravel(), np.asarray(durations).ravel()
        d = DIAGNOSTICS.to_dict(diagnostics)
        code = next((code for holds, code in verdict_rules(d, durations, apex, self.tolerance) if holds), ACCEPTED)
        return stride_of_verdict(int(code), apex, durations, d["error"])

    def judge_many(self, apex, durations, diagnostics) -> np.ndarray:
        """:meth:`judge`'s verdict codes of many final passes (outputs side by side, one
        column each) at once; :func:`stride_of_verdict` turns a code into the result."""
        d = dict(zip(DIAGNOSTICS.names, np.asarray(diagnostics)))
        rules = verdict_rules(d, durations, apex, self.tolerance)
        return np.select([holds for holds, _ in rules], [code for _, code in rules], ACCEPTED)


#: Verdict codes of a final pass: accepted, more steps needed, cannot vouch for it (the
#: caller falls back), liftoff descending, and a fall of clearance i at FELL + i.
ACCEPTED, REFINE, UNSURE, LIFTOFF_DESCENDING, FELL = 0, 1, 2, 3, 4
_COMPRESSION, _DECOMPRESSION = PHASES.index("compression"), PHASES.index("decompression")


def verdict_rules(d, durations, apex, tolerance: float):
    """(condition, verdict code) pairs in the order they are tried; the first that holds
    decides, and a pass that meets none is accepted. ``d`` maps the DIAGNOSTICS names to
    numbers (one pass) or to rows (many passes, one per column, as are ``durations`` and
    ``apex``): only operators that work on both are used."""
    lo, hi = LAST_STEP_RANGE
    # Each stance event ends its phase's last step, converged, with no earlier crossing.
    events_clean = (
        (lo < d["bottom_last_step"]) & (d["bottom_last_step"] < hi)
        & (lo < d["liftoff_last_step"]) & (d["liftoff_last_step"] < hi)
        & (d["rhodot_max_compression"] < 0.0) & (d["stretch_max_decompression"] < 0.0)
        & (abs(d["bottom_update"]) <= NEWTON_CONVERGED * durations[_COMPRESSION])
        & (abs(d["liftoff_update"]) <= NEWTON_CONVERGED * durations[_DECOMPRESSION])
    )
    fell = [d[f"{name}_min"] <= 0.0 for name in CLEARANCES]
    fallen = sum(1 * f for f in fell)
    which = sum(i * f for i, f in enumerate(fell))  # the one that fell, when one did
    finite = np.isfinite(apex).all(axis=0) & np.isfinite(d["error"])
    return (
        (~np.asarray(events_clean), UNSURE),
        (fallen > 1, UNSURE),  # the pass knows which clearances fell, not which fell first
        (fallen == 1, FELL + which),
        (d["zdot_lo"] <= 0.0, LIFTOFF_DESCENDING),
        (~finite, UNSURE),
        (d["error"] > tolerance, REFINE),
    )


def stride_of_verdict(code: int, apex, durations, error: float) -> Stride | str | None:
    """The result a verdict code stands for: the stride, "refine" or None."""
    reached = dict(zip(PHASES, np.asarray(durations, dtype=float).tolist()))
    if code == ACCEPTED:
        return Stride(np.array(apex, dtype=float), reached, None, error=float(error))
    if code == REFINE:
        return "refine"
    if code == LIFTOFF_DESCENDING:
        return Stride(None, {k: reached[k] for k in PHASES[:3]}, Fall.LIFTOFF_DESCENDING)
    if code >= FELL:
        return Stride(None, {"descent": reached["descent"]}, _CLEARANCE_FALLS[CLEARANCES[code - FELL]])
    return None


def first_grazing_step(stretch: np.ndarray, rhodot: np.ndarray, h: float) -> int | None:
    """The first step where rho peaks (rhodot falls through 0) with both nodes below rho0
    but within the rise that the step's speed allows: rho may touch rho0 in between."""
    steps = np.nonzero(grazing_steps(stretch, rhodot, h))[0]
    return int(steps[0]) if len(steps) else None


def grazing_steps(stretch: np.ndarray, rhodot: np.ndarray, h) -> np.ndarray:
    """Which steps (between nodes along the last axis) may hide a grazing liftoff: rho
    peaks with both nodes below rho0, within the rise the step's speed allows."""
    before, after = stretch[..., :-1], stretch[..., 1:]
    rate_before, rate_after = rhodot[..., :-1], rhodot[..., 1:]
    peak = (rate_before > 0.0) & (rate_after <= 0.0) & (before < 0.0) & (after < 0.0)
    reach = np.maximum(before + 0.5 * h * rate_before, after - 0.5 * h * rate_after)
    return peak & (reach > 0.0)


def touchdown_fall(x_touchdown, com_height: float, t_descent: float) -> Stride | None:
    """The fall seen at touchdown: the CoM already below ground, where no crossing in
    stance could see it, or the leg extending (rhodot >= 0); else None."""
    descent = {"descent": float(t_descent)}
    if com_height <= 0.0:
        return Stride(None, descent, Fall.COM_HITS_GROUND)
    if STANCE.get(x_touchdown, "rhodot") >= 0.0:
        return Stride(None, descent, Fall.LEG_EXTENDING_AT_TOUCHDOWN)
    return None


def first_rise(values: np.ndarray) -> int | None:
    """The first index j >= 1 with values[j] >= 0 after values[j - 1] < 0, or None."""
    rises = np.nonzero((values[1:] >= 0.0) & (values[:-1] < 0.0))[0]
    return int(rises[0]) + 1 if len(rises) else None


def first_rises(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`first_rise` of each row: (whether it has one, its index; 1 where none)."""
    rises = (values[:, 1:] >= 0.0) & (values[:, :-1] < 0.0)
    return rises.any(axis=1), np.argmax(rises, axis=1) + 1


def first_fall_step(clearance: np.ndarray, last_step: int | None) -> int | None:
    """The earliest step (up to the liftoff step) in which a clearance reaches zero."""
    steps = clearance.shape[1] if last_step is None else last_step
    hit = np.nonzero(np.any(clearance[:, :steps] <= 0.0, axis=0))[0]
    return int(hit[0]) if len(hit) else None


def hermite_roots(t0, t1, g0, g1, dg0, dg1) -> np.ndarray:
    """:func:`hermite_root` of many brackets at once (arrays of equal length), with the
    same arithmetic step by step, so each root is the scalar one to the bit."""
    t0, span = np.asarray(t0, dtype=float), np.asarray(t1, dtype=float) - t0
    g0, g1 = np.asarray(g0, dtype=float), np.asarray(g1, dtype=float)
    m0, m1 = dg0 * span, dg1 * span
    with np.errstate(divide="ignore", invalid="ignore"):  # rows without a bracket are never read
        s = g0 / (g0 - g1)
        active = np.ones(s.shape, dtype=bool)
        for _ in range(HERMITE_NEWTON):
            s2, s3 = s * s, s * s * s
            value = (2 * s3 - 3 * s2 + 1) * g0 + (s3 - 2 * s2 + s) * m0 + (3 * s2 - 2 * s3) * g1 + (s3 - s2) * m1
            rate = 6 * (s2 - s) * (g0 - g1) + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1
            active &= ~(rate <= 0.0)
            step = value / rate
            s = np.where(active, np.minimum(np.maximum(s - step, 0.0), 1.0), s)
            active &= ~(np.abs(step) < 1e-14)
            if not active.any():
                break
    return t0 + span * s



def hermite_root(t, g, dg) -> float:
    """The root in [t0, t1] of the cubic Hermite interpolant of g (g0 < 0 <= g1)."""
    t0, span = float(t[0]), float(t[1] - t[0])
    g0, g1 = float(g[0]), float(g[1])
    m0, m1 = float(dg[0]) * span, float(dg[1]) * span
    s = g0 / (g0 - g1)  # the secant's root, then Newton on the cubic, kept in [0, 1]
    for _ in range(HERMITE_NEWTON):
        s2, s3 = s * s, s * s * s
        value = (2 * s3 - 3 * s2 + 1) * g0 + (s3 - 2 * s2 + s) * m0 + (3 * s2 - 2 * s3) * g1 + (s3 - s2) * m1
        rate = 6 * (s2 - s) * (g0 - g1) + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1
        if rate <= 0.0:
            break
        step = value / rate
        s = min(max(s - step, 0.0), 1.0)
        if abs(step) < 1e-14:
            break
    return t0 + span * s
