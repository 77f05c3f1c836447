"""Many strides at once through the compiled engine.

The engine's functions are also compiled mapped over :data:`~baslip.stride.BATCH` strides
per call. Here the numeric driver of :mod:`baslip.engine` is done for a whole batch with
numpy: the touchdown bracket, the scout's event search, the step counts, and the checks
of the final pass. A stride that needs the careful scalar path (a fall seen by the scout,
a grazing liftoff, a stance longer than one scout call, an error estimate beyond the
finest step count) is handed to :class:`~baslip.engine.CompiledEngine` as it is, so both
paths give the same outcomes. Batches are split over threads: the compiled calls release
Python's lock, so two threads use both cores.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .control import CONTROL
from .engine import LAST_STEP_RANGE, NEWTON_CONVERGED, CompiledEngine
from .flow import DOP853
from .model import APEX, PARAMS, STANCE
from .outcome import PHASES, Fall, Stride
from .stride import (
    BATCH,
    DIAGNOSTICS,
    MAX_SCOUT_STEP_RATE,
    MAX_STEP_RATE,
    PREDICTION_MARGIN,
    SCOUT_STEPS,
    SCOUT_STEPS_PER_HALF_PERIOD,
    TIERS,
    StrideFunctions,
)

_CLEARANCE_FALLS = (Fall.COM_HITS_GROUND, Fall.HIP_HITS_GROUND, Fall.LEG_COLLAPSES)


class BatchEngine:
    """Strides of many (X, u) under one parameter vector, ``threads`` at a time."""

    def __init__(self, engine: CompiledEngine, threads: int = 2, compile: bool | None = None):
        self.engine = engine
        self._lanes = [engine.functions] + [StrideFunctions(compile) for _ in range(max(threads, 1) - 1)]

    def strides(self, X: np.ndarray, U: np.ndarray, p: np.ndarray) -> list[Stride | None]:
        """One stride from each row of ``X`` (n x 4) under the row of ``U`` (n x 5);
        None where the compiled engine cannot vouch for the stride (as for one stride)."""
        X, U = np.atleast_2d(np.asarray(X, float)), np.atleast_2d(np.asarray(U, float))
        chunks = [slice(i, min(i + BATCH, len(X))) for i in range(0, len(X), BATCH)]
        if len(self._lanes) == 1 or len(chunks) == 1:
            parts = [_Batch(self._lanes[0], self.engine, X[c], U[c], p).run() for c in chunks]
        else:
            lanes = len(self._lanes)
            work = [chunks[k::lanes] for k in range(lanes)]

            def lane(k):
                return [_Batch(self._lanes[k], self.engine, X[c], U[c], p).run() for c in work[k]]

            with ThreadPoolExecutor(lanes) as pool:
                done = list(pool.map(lane, range(lanes)))
            parts = [None] * len(chunks)
            for k in range(lanes):
                for i, result in zip(range(k, len(chunks), lanes), done[k]):
                    parts[i] = result
        return [stride for part in parts for stride in part]


class _Batch:
    """One call's worth of strides (at most BATCH), with their state as arrays."""

    def __init__(self, functions: StrideFunctions, engine: CompiledEngine, X, U, p):
        self.functions, self.engine = functions, engine
        self.X, self.U, self.p = X, U, np.asarray(p, float)
        self.n = len(X)
        self.results: list[Stride | None | str] = ["pending"] * self.n

    def run(self) -> list[Stride | None]:
        t_descent = self._precheck()
        live = self._pending()
        if live.size:
            self._stance(live, t_descent)
        for i in self._pending():  # the careful path, one by one
            self.results[i] = self.engine.stride(self.X[i], self.U[i], self.p, t_descent[i])
        return self.results

    def _pending(self) -> np.ndarray:
        return np.array([i for i, r in enumerate(self.results) if isinstance(r, str)], dtype=int)

    # -- before stance ---------------------------------------------------------------

    def _precheck(self) -> np.ndarray:
        """The closed-form falls, and the touchdown time of the rest [s]."""
        X, U, p = self.X, self.U, self.p
        z, theta_h, spin = X[:, 0], X[:, 1], X[:, 3]
        rho0, d, g = p[PARAMS.index("rho0")], p[PARAMS.index("d")], p[PARAMS.index("g")]
        theta_td = U[:, CONTROL.index("theta_td")]
        finite = np.all(np.isfinite(X), axis=1) & np.all(np.isfinite(U), axis=1) & bool(np.all(np.isfinite(p)))
        with np.errstate(invalid="ignore"):
            foot_below = z - d * np.sin(theta_h) - rho0 * np.cos(theta_td) < 0.0
            reach = np.abs(theta_td) < math.pi / 2
            t_descent = _touchdown_times(z, theta_h, spin, theta_td, d, rho0, g)
        for i in range(self.n):
            if not finite[i]:
                self.results[i] = Stride(None, {}, Fall.NOT_FINITE)
            elif foot_below[i]:
                self.results[i] = Stride(None, {}, Fall.FOOT_BELOW_GROUND)
            elif not reach[i] or not np.isfinite(t_descent[i]):
                self.results[i] = Stride(None, {}, Fall.NO_TOUCHDOWN)
        return t_descent

    # -- stance ----------------------------------------------------------------------

    def _stance(self, live: np.ndarray, t_descent: np.ndarray) -> None:
        X, U, p = self.X[live], self.U[live], self.p
        x_td, com_height, _ = _call(self.functions.batch("touchdown_state"), X.T, U.T, _columns(p, len(live)), t_descent[live])
        for k, i in enumerate(live):
            descent = {"descent": float(t_descent[i])}
            if com_height[0, k] <= 0.0:
                self.results[i] = Stride(None, descent, Fall.COM_HITS_GROUND)
            elif x_td[STANCE.index("rhodot"), k] >= 0.0:
                self.results[i] = Stride(None, descent, Fall.LEG_EXTENDING_AT_TOUCHDOWN)
        keep = np.array([isinstance(self.results[i], str) for i in live])
        live, x_td = live[keep], x_td[:, keep]
        if not live.size:
            return
        scouted = self._scout(live, x_td)
        if scouted is None:
            return
        live, bottom, liftoff, rate, h, error = scouted
        self._final(live, t_descent[live], bottom, liftoff - bottom, rate, h, error)

    def _scout(self, live, x_td):
        """One scout call per stride: event estimates for the strides whose stance it
        covers cleanly; the others stay pending for the careful path."""
        X, U, p = self.X[live], self.U[live], self.p
        rate = _stiffness_rates(X, U, p)
        half = math.pi * math.sqrt(p[PARAMS.index("m")] / p[PARAMS.index("k")])
        h = np.minimum(half / SCOUT_STEPS_PER_HALF_PERIOD, MAX_SCOUT_STEP_RATE / rate)
        theta = np.vstack([U.T, _columns(p, len(live))])
        nodes, rates, clearance, errors = _call(self.functions.batch("stance_scout"), x_td, h, theta)
        m = SCOUT_STEPS
        nodes = nodes.reshape(STANCE.size, len(live), m + 1)
        rates = rates.reshape(STANCE.size, len(live), m + 1)
        clearance = clearance.reshape(3, len(live), m)
        errors = errors.reshape(len(live), m)
        times = h[:, None] * np.arange(m + 1)[None, :]
        rhodot = nodes[STANCE.index("rhodot")]
        stretch = nodes[STANCE.index("rho")] - p[PARAMS.index("rho0")]
        j = _first_rises(rhodot)
        rows = np.arange(len(live))
        jj = np.maximum(j, 1)
        bottom = _hermite_roots(times[rows, jj - 1], times[rows, jj], rhodot[rows, jj - 1], rhodot[rows, jj],
                                rates[3, rows, jj - 1], rates[3, rows, jj])
        after = np.where(times >= bottom[:, None], stretch, -1.0)
        k = _first_rises(after)
        kk = np.maximum(k, 1)
        liftoff = _hermite_roots(times[rows, kk - 1], times[rows, kk], after[rows, kk - 1], after[rows, kk],
                                 rhodot[rows, kk - 1], rhodot[rows, kk])
        steps = np.arange(m)[None, :]
        before_liftoff = steps < (kk - 1)[:, None]
        fell = np.any(np.any(clearance <= 0.0, axis=0) & before_liftoff, axis=1)
        grazing = _grazing(after, rhodot, h) & before_liftoff
        clean = (j > 0) & (k > 0) & ~fell & ~np.any(grazing, axis=1) & np.all(np.isfinite(nodes), axis=(0, 2))
        error = np.sum(np.where(steps < (kk - 1)[:, None], errors, 0.0), axis=1)
        if not clean.any():
            return None
        return live[clean], bottom[clean], liftoff[clean], rate[clean], h[clean], error[clean]

    def _final(self, live, t_descent, t_compression, t_decompression, rate, h, error) -> None:
        """Final passes grouped by step count; a stride whose error estimate is too large
        moves to the next count."""
        longest = np.maximum(t_compression, t_decompression)
        tiers = np.array(TIERS, dtype=float)
        stable = longest[:, None] * rate[:, None] / tiers[None, :] <= MAX_STEP_RATE
        predicted = error[:, None] * (longest[:, None] / tiers[None, :] / h[:, None]) ** DOP853.order
        good = stable & (PREDICTION_MARGIN * predicted <= self.engine.tolerance)
        tier = np.where(good.any(axis=1), np.argmax(good, axis=1), np.where(stable.any(axis=1), len(TIERS) - 1, -1))
        guesses = np.vstack([t_descent, t_compression, t_decompression])
        active = tier >= 0  # no stable step count: the careful path decides
        while active.any():
            for t in np.unique(tier[active]):
                rows = np.nonzero(active & (tier == t))[0]
                outputs = _call(self.functions.batch(f"stride_{TIERS[t]}"), self.X[live[rows]].T,
                                self.U[live[rows]].T, _columns(self.p, len(rows)), guesses[:, rows])
                refine = self._judge(live[rows], *outputs)
                tier[rows[refine]] += 1
                active[rows[~refine]] = False
            active &= tier < len(TIERS)  # past the finest count: the careful path decides

    def _judge(self, rows, apex, durations, diagnostics) -> np.ndarray:
        """Set the results of settled strides; True where the error estimate asks for more
        steps. Strides the checks cannot vouch for stay pending."""
        d = {name: diagnostics[i] for i, name in enumerate(DIAGNOSTICS.names)}
        lo, hi = LAST_STEP_RANGE
        events = ((lo < d["bottom_last_step"]) & (d["bottom_last_step"] < hi)
                  & (lo < d["liftoff_last_step"]) & (d["liftoff_last_step"] < hi)
                  & (d["rhodot_max_compression"] < 0.0) & (d["stretch_max_decompression"] < 0.0)
                  & (np.abs(d["bottom_update"]) <= NEWTON_CONVERGED * durations[1])
                  & (np.abs(d["liftoff_update"]) <= NEWTON_CONVERGED * durations[2]))
        refine = np.zeros(len(rows), dtype=bool)
        for k, i in enumerate(rows):
            if not events[k]:
                continue  # pending: the careful path
            reached = dict(zip(PHASES, durations[:, k].tolist()))
            clear = [d["com_min"][k], d["hip_min"][k], d["leg_min"][k]]
            fell = next((f for c, f in zip(clear, _CLEARANCE_FALLS) if c <= 0.0), None)
            if fell is not None:
                self.results[i] = Stride(None, {"descent": reached["descent"]}, fell)
            elif d["zdot_lo"][k] <= 0.0:
                self.results[i] = Stride(None, {ph: reached[ph] for ph in PHASES[:3]}, Fall.LIFTOFF_DESCENDING)
            elif not (np.all(np.isfinite(apex[:, k])) and np.isfinite(d["error"][k])):
                continue
            elif d["error"][k] > self.engine.tolerance:
                refine[k] = True
            else:
                self.results[i] = Stride(apex[:, k].copy(), reached, None, error=float(d["error"][k]))
        return refine


def _call(kernel, *columns):
    """Call a batched kernel on the first n columns of each input (padded to BATCH by
    repeating the last column); outputs keep only their first n strides' columns."""
    n = np.atleast_2d(columns[0]).shape[1] if np.ndim(columns[0]) > 1 else len(columns[0])
    padded = [_pad(np.atleast_2d(c), n) for c in columns]
    outputs = kernel(*padded)
    return tuple(_unpad(o, n) for o in outputs)


def _pad(block: np.ndarray, n: int) -> np.ndarray:
    if block.shape[1] == BATCH:
        return block
    return np.hstack([block, np.repeat(block[:, -1:], BATCH - n, axis=1)])


def _unpad(out: np.ndarray, n: int) -> np.ndarray:
    per = out.shape[1] // BATCH
    return out[:, : n * per]


def _columns(p, n: int) -> np.ndarray:
    return np.repeat(np.asarray(p, float)[:, None], n, axis=1)


def _stiffness_rates(X, U, p) -> np.ndarray:
    """:func:`baslip.stride.stiffness_rate` for each row."""
    m, inertia, k, rho0, d = (p[PARAMS.index(n)] for n in ("m", "I", "k", "rho0", "d"))
    inertia_hip = inertia + m * d**2
    return np.max(np.vstack([
        np.full(len(X), math.sqrt(k / m)),
        np.abs(U[:, CONTROL.index("Kd")]) / inertia_hip,
        np.sqrt(np.abs(U[:, CONTROL.index("Kp")]) / inertia_hip),
        np.abs(X[:, APEX.index("theta_h_dot")]),
        np.abs(X[:, APEX.index("ydot")]) / rho0,
    ]), axis=0)


def _touchdown_times(z, theta_h, spin, theta_td, d, rho0, g) -> np.ndarray:
    """First zero of each foot height after apex [s] (NaN if none), as
    :func:`baslip.outcome.touchdown_guess`: bracketed on 256 intervals, then Newton
    kept inside the bracket, all rows at once."""
    clearance = z - rho0 * np.cos(theta_td)
    t_max = np.sqrt(2.0 * np.maximum(clearance + d, 0.0) / g) + 1e-9
    grid = t_max[:, None] * np.linspace(0.0, 1.0, 257)[None, :]
    height = clearance[:, None] - 0.5 * g * grid**2 - d * np.sin(theta_h[:, None] + spin[:, None] * grid)
    below = height[:, 1:] <= 0.0
    found = below.any(axis=1)
    first = np.argmax(below, axis=1)
    rows = np.arange(len(z))
    lo, hi = grid[rows, first], grid[rows, first + 1]
    t = 0.5 * (lo + hi)
    for _ in range(60):
        h = clearance - 0.5 * g * t * t - d * np.sin(theta_h + spin * t)
        lo, hi = np.where(h > 0.0, t, lo), np.where(h > 0.0, hi, t)
        slope = -g * t - d * spin * np.cos(theta_h + spin * t)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_new = np.where(slope < 0.0, t - h / slope, 0.5 * (lo + hi))
        t_new = np.where((t_new > lo) & (t_new < hi), t_new, 0.5 * (lo + hi))
        converged = np.abs(t_new - t) <= 1e-15 * t
        t = t_new
        if np.all(converged | ~found):
            break
    return np.where(found, t, np.nan)


def _first_rises(values: np.ndarray) -> np.ndarray:
    """Per row, the first j >= 1 with values[j] >= 0 after values[j - 1] < 0; 0 if none."""
    rises = (values[:, 1:] >= 0.0) & (values[:, :-1] < 0.0)
    return np.where(rises.any(axis=1), np.argmax(rises, axis=1) + 1, 0)


def _grazing(stretch, rhodot, h) -> np.ndarray:
    """Per row and step, as :func:`baslip.engine._first_grazing_step`: rho peaks with both
    nodes below rho0 but within reach of it."""
    peak = (rhodot[:, :-1] > 0.0) & (rhodot[:, 1:] <= 0.0) & (stretch[:, :-1] < 0.0) & (stretch[:, 1:] < 0.0)
    half = 0.5 * h[:, None]
    reach = np.maximum(stretch[:, :-1] + half * rhodot[:, :-1], stretch[:, 1:] - half * rhodot[:, 1:])
    return peak & (reach > 0.0)


def _hermite_roots(t0, t1, g0, g1, dg0, dg1) -> np.ndarray:
    """:func:`baslip.engine._hermite_root` for arrays of intervals."""
    span = t1 - t0
    m0, m1 = dg0 * span, dg1 * span
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip(g0 / (g0 - g1), 0.0, 1.0)
        for _ in range(8):
            s2, s3 = s * s, s * s * s
            value = (2 * s3 - 3 * s2 + 1) * g0 + (s3 - 2 * s2 + s) * m0 + (3 * s2 - 2 * s3) * g1 + (s3 - s2) * m1
            rate = 6 * (s2 - s) * (g0 - g1) + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1
            s = np.where(rate > 0.0, np.clip(s - value / rate, 0.0, 1.0), s)
    return t0 + span * np.nan_to_num(s)
