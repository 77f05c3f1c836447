"""Many strides at once through the compiled engine.

The engine's functions are also compiled mapped over :data:`~baslip.engine.kernels.BATCH` strides
per call. Here the numeric driver of :mod:`baslip.engine.driver` is done for many strides at
once: the touchdown bracket, the compiled planning (touchdown state, one scout call and
its event search), the step counts, and the checks of the final pass. A stride that
needs the careful scalar path (a fall seen by the scout, a grazing liftoff, a stance
longer than one scout call, an error estimate beyond the finest step count) is handed
to :class:`~baslip.engine.driver.CompiledEngine` as it is, so both paths give the same
outcomes. The strides are split into one lane per thread (the
compiled calls release Python's lock, so two threads use both cores), and within a lane
the final passes of all strides with one step count share full batches: a batch call
costs its :data:`~baslip.engine.kernels.BATCH` columns however few of them are used.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from baslip.engine.driver import (
    ACCEPTED,
    REFINE,
    UNSURE,
    CompiledEngine,
    events_unsettled_many,
    first_tiers_many,
    next_tier,
    richardson_error,
    scout_step,
    stride_of_verdict,
    touchdown_fall,
    touchdown_may_fall,
)
from baslip.engine.kernels import (
    BATCH,
    DIAGNOSTICS,
    TIERS,
    StrideFunctions,
    stiffness_rate,
)
from baslip.engine.outcome import PHASES, Stride, prechecks
from baslip.model.dynamics import APEX


class BatchEngine:
    """Strides of many (X, u) under one parameter vector, ``threads`` at a time."""

    def __init__(self, engine: CompiledEngine, threads: int = 2, compile: bool | str | None = None):
        self.engine = engine
        # Each lane owns its engine and kernels, its careful path included: a compiled
        # kernel's work memory must not be shared by two threads at once.
        self._lanes = [engine] + [CompiledEngine(engine.tolerance, compile, engine.law, StrideFunctions(engine.law, compile))
                                  for _ in range(max(threads, 1) - 1)]

    def strides(self, X: np.ndarray, U: np.ndarray, p: np.ndarray) -> list[Stride | None]:
        """One stride from each row of ``X`` (n x 4) under the row of ``U`` (n x controls);
        None where the compiled engine cannot vouch for the stride (as for one stride)."""
        X, U = np.atleast_2d(np.asarray(X, float)), np.atleast_2d(np.asarray(U, float))
        # Whole batches per lane where possible, contiguous rows so results stay in order.
        lanes = max(1, min(len(self._lanes), -(-len(X) // BATCH)))
        bounds = np.linspace(0, len(X), lanes + 1).round().astype(int)
        work = [slice(bounds[k], bounds[k + 1]) for k in range(lanes)]

        def lane(k):
            return _Batch(self._lanes[k], X[work[k]], U[work[k]], p).run()

        if lanes == 1:
            return lane(0)
        with ThreadPoolExecutor(lanes) as pool:
            done = list(pool.map(lane, range(lanes)))
        return [stride for part in done for stride in part]


class _Batch:
    """The strides of one lane, with their state as arrays; each compiled call takes
    them :data:`~baslip.engine.kernels.BATCH` at a time."""

    def __init__(self, engine: CompiledEngine, X, U, p):
        self.functions, self.engine = engine.functions, engine
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
        return [r for r in self.results if not isinstance(r, str)]  # none is pending now

    def _pending(self) -> np.ndarray:
        return np.array([i for i, r in enumerate(self.results) if isinstance(r, str)], dtype=int)

    # -- before stance ---------------------------------------------------------------

    def _precheck(self) -> np.ndarray:
        """The closed-form falls, and the touchdown time of the rest [s] (NaN after a fall)."""
        falls, t_descent = prechecks(self.X, self.U, self.p)
        for i, fallen in enumerate(falls):
            if fallen is not None:
                self.results[i] = fallen
        return t_descent

    # -- stance ----------------------------------------------------------------------

    def _stance(self, live: np.ndarray, t_descent: np.ndarray) -> None:
        """The planning of :meth:`CompiledEngine._plan` for all strides at once: touchdown
        state and one scout call each in one batched call; the falls at touchdown are set,
        the strides that one scout call covers cleanly go on to their final passes, and the
        rest stay pending for the careful path."""
        X, U, p = self.X[live], self.U[live], self.p
        rate = stiffness_rate(X, U, p, self.engine.law)
        h = scout_step(p, rate)
        x_td, com_height, clean, bottom, liftoff, error = _call(
            self.functions.batch("stance_plan"), X.T, U.T, _columns(p, len(live)), t_descent[live], h)
        for k in np.nonzero(touchdown_may_fall(x_td, com_height[0]))[0]:
            fall = touchdown_fall(x_td[:, k], float(com_height[0, k]), t_descent[live[k]])
            if fall is not None:
                self.results[live[k]] = fall
        go = np.array([isinstance(self.results[i], str) for i in live]) & (clean[0] == 1.0)
        if go.any():
            self._final(live[go], t_descent[live[go]], bottom[0, go], liftoff[0, go] - bottom[0, go], rate[go], h[go],
                        error[0, go])

    def _final(self, live, t_descent, t_compression, t_decompression, rate, h, error) -> None:
        """Final passes in rounds, each grouped by step count, with the decisions of
        :meth:`CompiledEngine._final`: a pass is accepted by its own error estimate or by
        the Richardson estimate against a pass at a lower count; a stride without one runs
        the pass at the count below in the next round, and one that is still not accepted
        moves on to :func:`next_tier`."""
        tolerance, size = self.engine.tolerance, len(live)
        longest = np.maximum(t_compression, t_decompression)
        lowest, tier = first_tiers_many(longest, rate, error, h, tolerance)
        guesses = np.vstack([t_descent, t_compression, t_decompression])
        results = np.full((APEX.size + len(PHASES), size), np.nan)  # each stride's latest pass
        diagnostics = np.full((DIAGNOSTICS.size, size), np.nan)
        coarse, coarse_steps = np.full_like(results, np.nan), np.zeros(size)
        waits = np.zeros(size, dtype=bool)  # its latest pass waits for the pass at the count below
        regridded = np.zeros(size, dtype=bool)  # its guesses were reset from a pass's own durations
        active = tier < len(TIERS)  # no stable step count: the careful path decides
        while active.any():
            needed = np.where(waits, tier - 1, tier)
            for t in np.unique(needed[active]):
                rows = np.nonzero(active & (needed == t))[0]
                apex, durations, diagnosed = _call(self.functions.batch(f"stride_{TIERS[t]}"), self.X[live[rows]].T,
                                                   self.U[live[rows]].T, _columns(self.p, len(rows)), guesses[:, rows])
                stacked, partner = np.vstack([apex, durations]), waits[rows]
                results[:, rows[~partner]], diagnostics[:, rows[~partner]] = stacked[:, ~partner], diagnosed[:, ~partner]
                coarse[:, rows[partner]], coarse_steps[rows[partner]] = stacked[:, partner], TIERS[t]
            rows = np.nonzero(active)[0]
            codes = self.engine.judge_many(results[: APEX.size, rows], results[APEX.size :, rows], diagnostics[:, rows])
            steps = np.asarray(TIERS)[tier[rows]]
            richardson = np.full(len(rows), np.inf)  # inf: no lower pass yet
            compared = coarse_steps[rows] > 0
            richardson[compared] = richardson_error(results[:, rows[compared]], coarse[:, rows[compared]],
                                                    coarse_steps[rows[compared]], steps[compared])
            by_richardson = (codes == REFINE) & (richardson <= tolerance)
            codes = np.where(by_richardson, ACCEPTED, codes)
            # As the careful path does, once: a pass whose events ended off its grid (the
            # scout's guess was too far) is taken again at its count from its own durations.
            regrid = ((codes == UNSURE) & ~regridded[rows]
                      & events_unsettled_many(results[APEX.size :, rows], diagnostics[:, rows]))
            again = rows[regrid]
            guesses[:, again] = results[APEX.size : APEX.size + 3, again]
            regridded[again], coarse_steps[again], waits[again] = True, 0, False
            codes = np.where(regrid, REFINE, codes)  # active still, its tier kept
            error = np.where(by_richardson, richardson, diagnostics[DIAGNOSTICS.index("error"), rows])
            for k in np.nonzero((codes != REFINE) & (codes != UNSURE))[0]:
                self.results[live[rows[k]]] = stride_of_verdict(
                    int(codes[k]), results[: APEX.size, rows[k]], results[APEX.size :, rows[k]], error[k])
            active[rows[codes != REFINE]] = False
            refine = (codes == REFINE) & ~regrid
            waits[rows] = refine & ~compared & (tier[rows] > lowest[rows])
            moves = refine & ~waits[rows]
            coarse[:, rows[moves]], coarse_steps[rows[moves]] = results[:, rows[moves]], steps[moves]
            tier[rows[moves]] = [next_tier(i, e, tolerance) for i, e in zip(tier[rows[moves]], richardson[moves])]
            active &= tier < len(TIERS)  # past the finest count: the careful path decides


def _call(kernel, *columns):
    """Call a batched kernel on the n columns of each input, BATCH columns a call (the
    last call padded by repeating the last column); the outputs of the n strides, their
    columns side by side."""
    columns = [np.atleast_2d(c) for c in columns]
    n = columns[0].shape[1]
    parts = []
    for start in range(0, n, BATCH):
        stop = min(start + BATCH, n)
        outputs = kernel(*(_pad(c[:, start:stop], stop - start) for c in columns))
        parts.append([_unpad(o, stop - start) for o in outputs])
    return tuple(np.hstack(outs) for outs in zip(*parts))


def _pad(block: np.ndarray, n: int) -> np.ndarray:
    if block.shape[1] == BATCH:
        return block
    return np.hstack([block, np.repeat(block[:, -1:], BATCH - n, axis=1)])


def _unpad(out: np.ndarray, n: int) -> np.ndarray:
    per = out.shape[1] // BATCH
    return out[:, : n * per]


def _columns(p, n: int) -> np.ndarray:
    return np.repeat(np.asarray(p, float)[:, None], n, axis=1)
