"""The numeric driver of the compiled stride engine (:mod:`baslip.engine.kernels`).

For one stride it runs the scout, picks the step count, calls the compiled final pass (or
its Jacobian) and judges the result: an apex, a named fall, or ``None`` where the engine
cannot guarantee its accuracy, so that the caller falls back to the adaptive event map.

A final pass is accepted when either of two error estimates is within the tolerance:

* its own summed DOP853 estimate, which costs nothing more but exceeds the true error by
  a median of 270 (16 steps a phase) to 5,400 (128 steps) over the design box, or
* the Richardson estimate from a pass at a lower step count (:func:`richardson_error`),
  whose ratio to the true error is about 1.

The second costs a pass at the lower count, but often lets the stride take half the steps
or fewer, and its Jacobian, about ten passes' worth, then costs as much less.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from baslip.engine.dop853 import DOP853
from baslip.engine.kernels import (
    CLEARANCES,
    DIAGNOSTICS,
    HERMITE_NEWTON,
    SCOUT_STEPS,
    TIERS,
    StrideFunctions,
    half_period,
    stiffness_rate,
)
from baslip.engine.outcome import MAX_STANCE_STEPS, PHASES, STANCE_HORIZON_HALF_PERIODS, Fall, Stride
from baslip.engine.recent import RecentAnswers, settle_key
from baslip.model.dynamics import PARAMS, STANCE
from baslip.model.hiplaw import PD, HipLaw

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
#: Divisors of the scout's step, tried in turn while the final passes cannot vouch for
#: the events the scout planned: rho may turn back up before the bottom the scout found
#: (a brief rise between two of its nodes, which a hip torque against a fast-spinning
#: trunk can cause), or a stiff hip (Kd / I in the thousands per second) leaves the
#: scout's coarse steps far from the liftoff. The passes' own durations carry the same
#: wrong events, so only a finer scout finds them.
FINER_SCOUTS = (4, 16)
#: The event must end the phase within this many grid steps of the grid's end.
LAST_STEP_RANGE = (0.0, 2.0)
#: Scout steps per spring half-period pi sqrt(m/k), at most, and the scout's largest
#: h * lambda: the scout only brackets the events, so it needs stability, not accuracy.
SCOUT_STEPS_PER_HALF_PERIOD = 12
MAX_SCOUT_STEP_RATE = 2.0
#: Largest h * lambda of a final-pass step (DOP853 is stable to about 5). The error
#: estimates, not this rate, decide the accuracy; the rate keeps them reliable. Over the
#: design box, for passes with h * lambda from 1 to 2, the DOP853 estimate was at least 9
#: times the true error and the true error at most 3.0 times the bare Richardson estimate
#: (382 pairs above round-off), as for smaller h * lambda.
MAX_STEP_RATE = 2.0
#: Safety factor of the Richardson estimate (:func:`richardson_error`). Over 1,446 pairs of
#: final passes at random points of the design box whose error was above round-off, the
#: true error (against 1,024 steps a phase) over the bare estimate had median 1.0, 99th
#: percentile 1.4 and maximum 3.3 (a pass with h * lambda = 0.5 and an error of 2e-8).
RICHARDSON_SAFETY = 5.0
#: Factor on the error predicted from the scout (its DOP853 estimate scaled by h^8) when
#: picking the first step count. That estimate is conservative: over the design box a
#: final pass's true error was a median 10^-2.4 of it (10th to 90th percentile 10^-3.6 to
#: 10^-1.5). The first count aims at the Richardson test for a typical stride; a count
#: too low costs one more pass, a count too high a larger pass and Jacobian.
PREDICTION_MARGIN = 0.003 * RICHARDSON_SAFETY
#: The same factor where the stride can only be accepted by a pass's own DOP853 estimate:
#: measured over the design box, that estimate exceeds the prediction by a median of 2-3
#: and a 90th percentile of 6-22.
OWN_ESTIMATE_MARGIN = 10.0

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

    ``tolerance`` bounds the stride's error estimate (relative to max(1, |x|)): the summed
    DOP853 estimate of its stance integration, or the Richardson estimate of its apex and
    phase durations (see the module's text). A stride whose estimates stay above it at the
    finest step count, or whose events the scout could not bracket cleanly, returns
    ``None``.
    """

    def __init__(self, tolerance: float, compile: bool | str | None = None, law: HipLaw = PD,
                 functions: StrideFunctions | None = None):
        self.tolerance = tolerance
        self.law = law
        self.functions = StrideFunctions(law, compile) if functions is None else functions
        self.recent = RecentAnswers()  # a Jacobian after a value at the same point settles once
        self.recent_jacobians = RecentAnswers()  # and a second Jacobian there is not taken again

    def stride(self, X, u, p, t_guess) -> Stride | None:
        """The stride from apex ``X`` (which passed the pre-checks), or None."""
        settled = self._settle(X, u, p, t_guess)
        return settled[1] if isinstance(settled, tuple) else settled

    def stride_jacobian(self, X, u, p, t_guess) -> tuple[np.ndarray | None, Stride] | None:
        """(dr/d(X, u, p) as 4 x (4 + controls + 6), the stride), the Jacobian None after a fall; or None.

        The step count is settled by value passes, which cost a fraction of a Jacobian."""
        return self.recent_jacobians.answer(  # type: ignore[return-value]
            settle_key(X, u, p, t_guess), lambda: self._stride_jacobian_afresh(X, u, p, t_guess))

    def _stride_jacobian_afresh(self, X, u, p, t_guess) -> tuple[np.ndarray | None, Stride] | None:
        settled = self._settle(X, u, p, t_guess)
        if not isinstance(settled, tuple):
            return None if settled is None else (None, settled)
        n, verdict, guesses = settled
        if verdict is None or not verdict.ok:
            return None if verdict is None else (None, verdict)
        # The verdict of the value pass: a Richardson-accepted pass alone would ask to refine.
        # Its own event guesses: a pass taken again from its durations has new ones.
        return self.functions.jacobian(n)(X, u, p, guesses)[0], verdict

    def stride_hessian_vectors(self, X, u, p, t_guess, W, S) -> np.ndarray | None:
        """Column k: H_k S[:, k], with H_k the Hessian of W[:, k] . r in (X, u, p), at the
        pass :meth:`stride_jacobian` differentiates, the columns shared among the threads;
        None where there is no such pass."""
        settled = self.settled_pass(X, u, p, t_guess)
        if settled is None:
            return None
        n, guesses = settled
        columns = self._in_lanes(list(range(S.shape[1])), lambda lane, k: self.functions.hessian_vector(n, lane)(
            X, u, p, guesses, W[:, k], S[:, k])[0])
        return np.column_stack([np.asarray(column, dtype=float).ravel() for column in columns])

    def stride_jacobian_gradient(self, X, u, p, t_guess, G) -> np.ndarray | None:
        """The gradient in (X, u, p) of sum(G * dr/dX) at the pass :meth:`stride_jacobian`
        differentiates; None where there is no such pass."""
        settled = self.settled_pass(X, u, p, t_guess)
        if settled is None:
            return None
        n, guesses = settled
        return np.asarray(self.functions.jacobian_gradient(n)(X, u, p, guesses, G)[0], dtype=float).ravel()

    def _in_lanes(self, items: list, call) -> list:
        """[call(lane, item) for item in items], the items split among the lanes of the
        second derivatives' kernels in contiguous runs (results in order)."""
        lanes = min(self.functions.hessian_lanes, len(items))
        bounds = np.linspace(0, len(items), lanes + 1).round().astype(int)

        def lane(k: int) -> list:
            return [call(k, item) for item in items[bounds[k] : bounds[k + 1]]]

        if lanes == 1:
            return lane(0)
        with ThreadPoolExecutor(lanes) as pool:
            return [result for part in pool.map(lane, range(lanes)) for result in part]

    def settled_pass(self, X, u, p, t_guess) -> tuple[int, np.ndarray] | None:
        """(step count, guesses) of the final pass that :meth:`stride` accepts for a clean
        stride, to evaluate other functions of that same pass; None if there is none."""
        settled = self._settle(X, u, p, t_guess)
        if not isinstance(settled, tuple):
            return None
        n, verdict, guesses = settled
        return None if verdict is None or not verdict.ok else (n, guesses)

    # -- pieces ----------------------------------------------------------------------

    def _settle(self, X, u, p, t_guess) -> tuple[int, Stride | None, np.ndarray] | Stride | None:
        """:meth:`_settle_afresh`, or its answer for the same inputs among the last few."""
        return self.recent.answer(settle_key(X, u, p, t_guess),  # type: ignore[return-value]
                                  lambda: self._settle_afresh(X, u, p, t_guess))

    def _settle_afresh(self, X, u, p, t_guess) -> tuple[int, Stride | None, np.ndarray] | Stride | None:
        """The scout and the final passes: a fall found in planning, None, or :meth:`_final`'s
        (step count, verdict, guesses). Where the final passes cannot vouch for the events
        the scout planned, the scout is run again in finer steps (:data:`FINER_SCOUTS`) and
        the final passes follow its plan. Where they only run out of step counts, with
        clean events but an error estimate above the tolerance, a finer scout would plan
        the same passes, and none is run."""
        for finer in (1, *FINER_SCOUTS):
            plan = self._plan(X, u, p, t_guess, finer)
            if not isinstance(plan, tuple):
                return plan
            n, verdict, guesses, unsure = self._final(X, u, p, *plan)
            if verdict is not None or not unsure:
                break
        return n, verdict, guesses

    def _final(self, X, u, p, lowest: int, start: int, guesses) -> tuple[int, Stride | None, np.ndarray, bool]:
        """The final pass at the first step count whose error estimate is within the
        tolerance, from ``TIERS[start]`` up; the Richardson estimate compares it with the
        last pass at a lower count, or with one at the count below (if not below
        ``TIERS[lowest]``, the least stable one). Returns (step count, verdict, the event
        guesses of that pass, whether an unsure pass saw rho turn back up before its
        bottom), so that other functions of the same pass (its Jacobian) start from the
        same guesses."""
        i, coarse, regridded = start, None, False
        while i < len(TIERS):
            n = TIERS[i]
            apex, durations, diagnostics = (o.ravel() for o in self.functions.final(n)(X, u, p, guesses))
            verdict = self.judge(apex, durations, diagnostics)
            if verdict is None and not regridded and events_unsettled(durations, diagnostics):
                # The scout's event estimate was off by more than a grid step (a strong hip
                # torque bends rho near liftoff), or too far for the pass's few Newton
                # steps on the event to converge (a fast-swinging trunk): this pass's own
                # durations set the grid and the start of those steps.
                guesses, regridded, coarse = np.asarray(durations[:3], dtype=float), True, None
                continue
            if not isinstance(verdict, str):  # the one string verdict is "refine"
                return n, verdict, guesses, verdict is None
            result = np.concatenate([apex, durations])
            if coarse is None and i > lowest:
                below = TIERS[i - 1]
                coarse = below, np.concatenate([o.ravel() for o in self.functions.final(below)(X, u, p, guesses)[:2]])
            error = np.inf if coarse is None else float(richardson_error(result, coarse[1], coarse[0], n))
            if error <= self.tolerance:
                accepted = stride_of_verdict(ACCEPTED, apex, durations, error)
                assert isinstance(accepted, Stride)
                return n, accepted, guesses, False
            i, coarse = next_tier(i, error, self.tolerance), (n, result)
        return TIERS[-1], None, guesses, False

    def _plan(self, X, u, p, t_guess, finer: int = 1):
        """Touchdown checks and the scout, in steps ``finer`` times smaller than usual: a
        fall, None, or the indices in TIERS of the least stable and the first step count,
        and the final pass's guesses. One compiled call covers a stance that one scout
        call brackets cleanly; the others take :meth:`_scout`."""
        rate = stiffness_rate(X, u, p, self.law)
        h = scout_step(p, rate) / finer
        x_td, com_height, clean, bottom, liftoff, error = self.functions.plan(X, u, p, t_guess, h)
        x_td = x_td.ravel()
        fall = touchdown_fall(x_td, float(com_height[0, 0]), t_guess)
        if fall is not None:
            return fall
        descent = {"descent": float(t_guess)}
        scouted: Scouted | Fall | None
        if clean[0, 0]:
            scouted = Scouted(float(bottom[0, 0]), float(liftoff[0, 0]), rate, h, float(error[0, 0]))
        else:
            scouted = self._scout(x_td, np.concatenate([u, p]), rate, h, p)
        if not isinstance(scouted, Scouted):
            return scouted if scouted is None else Stride(None, descent, scouted)
        compression, decompression = scouted.bottom, scouted.liftoff - scouted.bottom
        lowest, start = first_tiers(max(compression, decompression), scouted.rate, scouted.error,
                                    scouted.step, self.tolerance)
        if start >= len(TIERS):
            return None
        return lowest, start, np.array([t_guess, compression, decompression])

    def _scout(self, x0, theta, rate: float, h: float, p) -> Scouted | Fall | None:
        """Step stance from touchdown state ``x0`` in chunks of steps ``h`` [s] until liftoff:
        the event estimates, a fall, or None. The careful path of the planning: as often
        as needed, finer steps after a blow-up, grazing peaks and falls resolved."""
        horizon = STANCE_HORIZON_HALF_PERIODS * half_period(p)
        rho0 = float(p[_RHO0])
        t0, bottom, error, x_td, refinements = 0.0, None, 0.0, x0, SCOUT_REFINEMENTS
        steps = 0
        while t0 < horizon:
            steps += SCOUT_STEPS
            if steps > MAX_STANCE_STEPS:  # the work limit: a far too stiff hip would run on for hours
                return Fall.WORK_LIMIT
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
                assert bottom is not None  # the liftoff is searched for only after the bottom
                liftoff = hermite_root(times[k - 1 : k + 1], stretch[k - 1 : k + 1], rhodot[k - 1 : k + 1])
                # Summed in order, as the compiled planning sums (np.sum pairs terms otherwise).
                return Scouted(bottom, liftoff, rate, h, error + float(np.cumsum(errors[0])[k - 1]))
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


def events_unsettled(durations, diagnostics) -> bool:
    """Whether a final pass, clear of falls with finite, positive durations, ended a stance
    event's step more than :data:`LAST_STEP_RANGE` grid steps from its grid's end or left
    the event's Newton update unconverged: its grid and event start, not its accuracy,
    are in doubt, and a pass from its own durations settles them."""
    return bool(_unsettled(DIAGNOSTICS.to_dict(diagnostics), np.asarray(durations, dtype=float)))


def events_unsettled_many(durations, diagnostics) -> np.ndarray:
    """:func:`events_unsettled` of many final passes at once (one column each)."""
    d = dict(zip(DIAGNOSTICS.names, np.asarray(diagnostics, dtype=float)))
    return np.asarray(_unsettled(d, np.asarray(durations, dtype=float)), dtype=bool)


def _unsettled(d, durations):
    """The rule of :func:`events_unsettled`, on numbers (one pass) or rows (many): only
    numpy's logical functions, which work on both."""
    lo, hi = LAST_STEP_RANGE
    on_grid = np.logical_and.reduce([lo < d["bottom_last_step"], d["bottom_last_step"] < hi,
                                     lo < d["liftoff_last_step"], d["liftoff_last_step"] < hi])
    converged = np.logical_and(abs(d["bottom_update"]) <= NEWTON_CONVERGED * durations[_COMPRESSION],
                               abs(d["liftoff_update"]) <= NEWTON_CONVERGED * durations[_DECOMPRESSION])
    clear = np.logical_and.reduce([d[f"{name}_min"] > 0.0 for name in CLEARANCES] + [d["zdot_lo"] > 0.0])
    positive = np.logical_and(np.isfinite(durations).all(axis=0), (durations[:3] > 0.0).all(axis=0))
    return np.logical_not(np.logical_and(on_grid, converged)) & clear & positive


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


def scout_step(p, rate):
    """The scout's step [s] for the stiffness rate ``rate`` [1/s] (a number or an array):
    at most 1/:data:`SCOUT_STEPS_PER_HALF_PERIOD` of the spring's half-period, and
    h * rate at most :data:`MAX_SCOUT_STEP_RATE`."""
    return np.minimum(half_period(p) / SCOUT_STEPS_PER_HALF_PERIOD, MAX_SCOUT_STEP_RATE / rate)


def first_tiers(longest: float, rate: float, error: float, step: float, tolerance: float) -> tuple[int, int]:
    """Where the final passes of a stride start, as indices in :data:`TIERS`: (the least
    step count with h * lambda <= MAX_STEP_RATE, the first count to try); len(TIERS) for
    both where no count is stable. ``longest`` is the longer phase [s], ``rate`` lambda
    [1/s], ``error`` the scout's DOP853 estimate at its step ``step`` [s].

    Each count's error is predicted from the scout's estimate by the order (error ~ h^8).
    Two plans compete, and the one with fewer steps in all is taken (the pair on a tie,
    for its cheaper Jacobian): the least count above the least stable one that the
    Richardson test would likely accept (predicted error times :data:`PREDICTION_MARGIN`
    within ``tolerance``) with the pass at the count below, or the least count whose own
    DOP853 estimate will likely do (the prediction times :data:`OWN_ESTIMATE_MARGIN`)."""
    stable = [i for i, n in enumerate(TIERS) if longest * rate / n <= MAX_STEP_RATE]
    if not stable:
        return len(TIERS), len(TIERS)
    def predicted(i: int) -> float:
        return error * (longest / TIERS[i] / step) ** DOP853.order

    pair = next((i for i in stable[1:] if PREDICTION_MARGIN * predicted(i) <= tolerance), stable[-1])
    alone = next((i for i in stable if OWN_ESTIMATE_MARGIN * predicted(i) <= tolerance), stable[-1])
    return stable[0], alone if TIERS[alone] < TIERS[pair - 1] + TIERS[pair] else pair


def first_tiers_many(longest, rate, error, step, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`first_tiers` of many strides (arrays of equal length) at once, with the same
    arithmetic, so each stride's plan is the single one."""
    counts = np.asarray(TIERS, dtype=float)
    longest, rate, error, step = (np.asarray(v, dtype=float)[:, None] for v in (longest, rate, error, step))
    stable = longest * rate / counts <= MAX_STEP_RATE
    predicted = error * (longest / counts / step) ** DOP853.order
    last = len(TIERS) - 1 - np.argmax(stable[:, ::-1], axis=1)  # the finest stable count
    above_lowest = stable & (np.cumsum(stable, axis=1) > 1)
    pair = _first_or(above_lowest & (PREDICTION_MARGIN * predicted <= tolerance), last)
    alone = _first_or(stable & (OWN_ESTIMATE_MARGIN * predicted <= tolerance), last)
    start = np.where(counts[alone] < counts[pair - 1] + counts[pair], alone, pair)
    none = ~stable.any(axis=1)
    return np.where(none, len(TIERS), np.argmax(stable, axis=1)), np.where(none, len(TIERS), start)


def _first_or(holds: np.ndarray, default: np.ndarray) -> np.ndarray:
    """Each row's first column where ``holds``, else ``default``."""
    return np.where(holds.any(axis=1), np.argmax(holds, axis=1), default)


def richardson_error(result, coarse_result, coarse_steps, steps):
    """The Richardson estimate of the error of a final pass of ``steps`` steps a phase, from
    a pass of fewer, ``coarse_steps``: with errors ~ h^8, the share q / (1 - q) of their
    difference is left in the finer pass, q = (coarse_steps / steps)^8. The difference is
    the largest over the next apex and the phase durations (``result``, stacked), relative
    to max(1, |x|); the estimate is scaled by :data:`RICHARDSON_SAFETY`. A vector per pass,
    or columns of many passes (the counts then rows); inf where not finite."""
    q = (np.asarray(coarse_steps, dtype=float) / steps) ** DOP853.order
    gap = np.max(np.abs(result - coarse_result) / np.maximum(1.0, np.abs(result)), axis=0)
    estimate = RICHARDSON_SAFETY * q / (1.0 - q) * gap
    return np.where(np.isfinite(estimate), estimate, np.inf)


def next_tier(i: int, error: float, tolerance: float) -> int:
    """The index in :data:`TIERS` to try after the pass at ``TIERS[i]`` estimated ``error``
    above ``tolerance``: the first finer count whose error, scaled by h^8 from this one, is
    within it, else the next one (len(TIERS) after the finest)."""
    fits = (j for j in range(i + 1, len(TIERS)) if error * (TIERS[i] / TIERS[j]) ** DOP853.order <= tolerance)
    return next(fits, i + 1)


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


def touchdown_may_fall(x_touchdown: np.ndarray, com_height: np.ndarray) -> np.ndarray:
    """Which columns of touchdown states (and their CoM heights [m]) :func:`touchdown_fall`
    would call a fall: its tests for many strides at once, so that a batch builds a
    stride's fall only where there is one."""
    return (com_height <= 0.0) | (x_touchdown[_RHODOT] >= 0.0)


def first_rise(values: np.ndarray) -> int | None:
    """The first index j >= 1 with values[j] >= 0 after values[j - 1] < 0, or None."""
    rises = np.nonzero((values[1:] >= 0.0) & (values[:-1] < 0.0))[0]
    return int(rises[0]) + 1 if len(rises) else None


def first_fall_step(clearance: np.ndarray, last_step: int | None) -> int | None:
    """The earliest step (up to the liftoff step) in which a clearance reaches zero."""
    steps = clearance.shape[1] if last_step is None else last_step
    hit = np.nonzero(np.any(clearance[:, :steps] <= 0.0, axis=0))[0]
    return int(hit[0]) if len(hit) else None


def hermite_root(t, g, dg) -> float:
    """The root in [t0, t1] of the cubic Hermite interpolant of g (g0 < 0 <= g1), in plain
    floats for the careful path: the arithmetic of :func:`baslip.engine.kernels.hermite_root`,
    which the compiled planning builds in its graph, step by step (tested to the bit)."""
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
