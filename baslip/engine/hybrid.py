"""The stride of a described model: its return map and the map's exact Jacobian.

From the section state, each mode of the stride order is integrated by DOP853 steps
(:mod:`baslip.engine.dop853`) until its guard crosses zero in its direction, the last
step's size then solved by Newton so that the mode ends exactly on the guard; the reset
gives the next mode's start, and the last mode ends on the section's guard. Falls are
checked at every node.

Each mode is run twice: a *scout* in steps of a fixed size finds its duration T, and the
mode is then integrated in steps of T / (n - 1/2), so that every mode has n steps, its
event falling in the middle of the last one, wherever the family takes the gait: a fast
stance gets steps as short as its own time scale asks. The resolution
(:class:`Resolution`: the scout's step and n) is the caller's.

The Jacobian of the map in the section coordinates and in ``theta`` (parameters, then
controls) is that of the discrete map itself, carried through the steps: a fixed step by
its state and theta derivatives, an event step by the implicit-function theorem (the
step size moves with the state so that the guard stays at zero), a reset by its own.

Because the step size follows the scout's duration, which is smooth in the arguments, so
is the map, and Newton's method sees a smooth function; the Jacobian holds the step sizes
fixed (their own derivative moves the map only by its truncation error). The accuracy is
set by :func:`calibrated_resolution`, which doubles n until two agree, and checked by
:mod:`baslip.engine.hybrid_check`, which re-simulates with a different integrator.

The steps run in chunks of generated code, compiled to C
(:mod:`baslip.engine.hybrid_kernels`): one call takes eight steps, and Python finds the
first node where the mode fell or crossed its guard, as a loop over single steps would,
with the same numbers to the bit. A stride costs 0.5 to 3 ms instead of 8 to 43 ms one
step at a time (``benchmarks/bench_models.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from baslip.engine.hybrid_kernels import CHUNK, PhaseKernels, StrideKernels, stride_kernels
from baslip.model.symbolic import ModelFunctions, fall_names

#: The share of the tolerance two step counts must agree to for the coarser to be used.
VERIFICATION_MARGIN = 0.1
#: A mode lasts at most this many steps; a guard that has not fired by then never will.
MAX_STEPS = 5000


@dataclass(frozen=True)
class Resolution:
    """How finely a stride is integrated: the scout's step [s] and the steps per mode."""

    scout: float
    steps: int

    def to_dict(self) -> dict:
        return {"scout_s": self.scout, "steps_per_mode": self.steps}


@dataclass(frozen=True)
class Outcome:
    """One stride of a described model.

    Attributes
    ----------
    section : ndarray or None
        The section coordinates at the stride's end; None if it failed.
    failure : str
        Why it failed ("" if it did not).
    durations : tuple of float
        Each mode's duration [s], in stride order.
    jacobian_section, jacobian_theta : ndarray or None
        d(section)/d(section coordinates) and d(section)/d(theta), when asked for.
    nodes : tuple of (mode, times, states)
        The states at every step's end, by mode, when asked for.
    """

    section: np.ndarray | None
    failure: str = ""
    durations: tuple[float, ...] = ()
    jacobian_section: np.ndarray | None = None
    jacobian_theta: np.ndarray | None = None
    nodes: tuple = field(default=(), repr=False)

    @property
    def ok(self) -> bool:
        return self.section is not None

    def end(self) -> np.ndarray:
        """The section coordinates at the end; only of a stride that did not fail."""
        if self.section is None:
            raise ValueError(f"the stride failed: {self.failure}")
        return self.section

    def jacobians(self) -> tuple[np.ndarray, np.ndarray]:
        """d(section)/d(section coordinates) and d(section)/d(theta), of a stride run
        with ``jacobian=True``."""
        if self.jacobian_section is None or self.jacobian_theta is None:
            raise ValueError("the stride was run without its Jacobians")
        return self.jacobian_section, self.jacobian_theta


@dataclass(frozen=True)
class _Phase:
    """One mode of the stride, the event that ends it and its compiled pieces."""

    mode: str
    direction: int
    fall_names: tuple[str, ...]
    event: str
    kernels: PhaseKernels


class HybridMap:
    """The return map of a described model under one law (see the module's docstring).

    Its steps run in chunks of generated code (:mod:`baslip.engine.hybrid_kernels`),
    compiled to C and cached when a compiler is at hand. A map holds the buffers of its
    compiled calls: use one per thread.

    Parameters
    ----------
    functions : ModelFunctions
        The model's symbolic pieces (:func:`baslip.model.symbolic.model_functions`).
    compiled : bool or None
        Compile the stride's pieces to C: True or False, or None (the default) unless
        ``BASLIP_NO_COMPILE`` is set. Either way the values are the same.
    """

    def __init__(self, functions: ModelFunctions, compiled: bool | None = None):
        self.functions = functions
        self.compiled = compiled

    @cached_property
    def kernels(self) -> StrideKernels:
        return stride_kernels(self.functions, enabled=self.compiled)

    @cached_property
    def phases(self) -> tuple[_Phase, ...]:
        model = self.functions.model
        directions = [*self.functions.directions, model.section.direction]
        events = [t.label for t in model.stride_transitions()] + ["section"]
        return tuple(_Phase(mode, direction, fall_names(model, mode), event, kernels)
                     for mode, direction, event, kernels in zip(model.order, directions, events, self.kernels.phases))

    def stride(self, section: np.ndarray, theta: np.ndarray, resolution: Resolution, jacobian: bool = False,
               nodes: bool = False) -> Outcome:
        """One stride from the section coordinates ``section`` with ``theta`` at
        ``resolution``; with the Jacobians if ``jacobian``, the node states if ``nodes``."""
        f = self.functions
        x = f.lift(section)
        theta = np.asarray(theta, dtype=float)
        n0 = len(f.section_index)
        carried = None
        if jacobian:  # d x / d(section coordinates, theta) at the start
            carried = np.zeros((len(x), n0 + len(theta)))
            carried[f.section_index, np.arange(n0)] = 1.0
        durations: list[float] = []
        visited: list[tuple] = []
        for number, phase in enumerate(self.phases):
            scouted = self._phase(phase, x, theta, resolution.scout, None, False)
            if isinstance(scouted, str):
                return Outcome(None, scouted, tuple(durations), nodes=tuple(visited))
            step = scouted[2] / (resolution.steps - 0.5)
            run = self._phase(phase, x, theta, step, carried, nodes)
            if isinstance(run, str):
                return Outcome(None, run, tuple(durations), nodes=tuple(visited))
            x, carried, duration, trace = run
            durations.append(duration)
            if nodes:
                visited.append((phase.mode, *trace))
            if number < len(self.kernels.resets):
                reset = self.kernels.resets[number]
                if carried is None:
                    x = reset.reset(x, theta)[0].ravel()
                else:
                    after, carried = reset.reset_sens(x, carried, theta)
                    x = after.ravel()
        end = f.project(x)
        if carried is None:
            return Outcome(end, "", tuple(durations), nodes=tuple(visited))
        rows = carried[f.section_index]
        return Outcome(end, "", tuple(durations), rows[:, :n0], rows[:, n0:], tuple(visited))

    def _phase(self, phase: _Phase, x: np.ndarray, theta: np.ndarray, step: float, carried, nodes: bool):
        """Integrate ``phase`` from ``x`` to its event: (state, carried Jacobian, duration,
        (times, states)), or why it failed.

        Each chunk's nodes are searched for the first step whose start fell, whose end left
        the finite numbers or whose guard crossed zero in the mode's direction, in that
        order: the outcome of a step-by-step loop."""
        kernels, direction = phase.kernels, phase.direction
        g_old = kernels.guard(x, theta)[0].item()
        if direction * g_old > 0:
            return f"mode {phase.mode} starts past the guard of {phase.event} (it can never cross it)"
        times, states = [0.0], [x]
        for taken in range(0, MAX_STEPS, CHUNK):
            if carried is None:
                chunk, guards, falls = kernels.chunk(x, step, theta)
                carried_at = None
            else:
                chunk, carried_at, guards, falls = kernels.chunk_sens(x, carried, step, theta)
            g = np.concatenate([[g_old], guards.ravel()])
            fell = np.any(falls < 0, axis=0) if falls.size else np.zeros(CHUNK, dtype=bool)
            lost = ~np.all(np.isfinite(chunk), axis=0)
            crossed = (direction * g[1:] >= 0) & (direction * g[:-1] < 0)
            stops = np.flatnonzero(fell | lost | crossed)
            last = stops[0] if len(stops) else CHUNK
            if nodes:
                times.extend((taken + np.arange(1, last + 1)) * step)
                states.extend(chunk[:, :last].T)
            if last < CHUNK:
                return self._stop(phase, x, theta, step, taken, last, (chunk, carried_at, carried, g, falls),
                                  (fell, lost), times, states)
            x, g_old = chunk[:, -1], g[-1]
            if carried_at is not None:
                carried = carried_at[:, -carried.shape[1]:]
        return (f"the guard of {phase.event} never fired in {MAX_STEPS} steps ({MAX_STEPS * step:.3g} s) "
                f"of mode {phase.mode}")

    def _stop(self, phase: _Phase, x, theta, step, taken: int, last: int, chunk, why, times, states):
        """What ended a chunk at its step ``last``: a fall, a state lost to the infinite,
        or the event (then integrated to the guard)."""
        nodes, carried_at, carried, g, falls = chunk
        fell, lost = why
        if fell[last]:
            broken = [name for name, v in zip(phase.fall_names, falls[:, last]) if v < 0]
            return f"fell: {broken[0]} (mode {phase.mode})"
        if lost[last]:
            return f"the state left the finite numbers in mode {phase.mode}"
        if last > 0:
            x = nodes[:, last - 1]
            if carried is not None:
                width = carried.shape[1]
                carried = carried_at[:, (last - 1) * width:last * width]
        return self._event(phase, x, theta, step, g[last], g[last + 1], carried, taken + last, times, states)

    def _event(self, phase: _Phase, x, theta, step, g_old, g_new, carried, count, times, states):
        guess = step * g_old / (g_old - g_new)
        s, x_end, residual = (v for v in phase.kernels.event(x, guess, theta)[:3])
        s = s.item()
        if not (0.0 <= s <= 1.5 * step) or abs(residual.item()) > 1e-9 * max(1.0, abs(g_old)):
            return f"the event {phase.event} could not be located in mode {phase.mode}"
        x_end = x_end.ravel()
        duration = count * step + s
        if carried is not None:
            carried = phase.kernels.event_sens(x, carried, s, theta)[0]
        times.append(duration)
        states.append(x_end)
        return x_end, carried, duration, (np.array(times), np.array(states))


def calibrated_resolution(hybrid: HybridMap, section: np.ndarray, theta: np.ndarray, tolerance: float,
                          first: float = 0.02, most: int = 256) -> Resolution:
    """The fewest steps per mode, 8 * 2^i, at which a stride from ``section`` agrees with
    one at twice the steps to a tenth of ``tolerance`` (relative to max(1, |section|)).

    The scout's step is ``first`` [s], or a quarter of the shortest mode where that is
    shorter. Where the stride fails at 8 steps the count doubles until it does not (a
    stiff mode: the third hip law's trunk at omega = 360 1/s needs 32); a stride that
    fails at every count is left to the caller to report, at ``Resolution(first, 8)``.

    DOP853 is of order 8, so the finer stride's own error is about 1/256 of the
    difference, and the returned stride's own error is about the difference: a tenth of
    the tolerance, so that a fixed point of that stride leaves the independent
    verification at ``tolerance`` a factor of ten (at the tolerance itself, a human-sized
    gait of the virtual-constraint law missed it by 1.02e-10 against 1e-10). Raises
    nothing: if no count agrees, ``most`` is returned (the verification, by another
    integrator, then decides).
    """
    scout, steps = first, 8
    outcome = hybrid.stride(section, theta, Resolution(scout, steps))
    while not outcome.ok and steps < most:
        # Too few steps for a stiff mode (a large gain) can derail the stride itself.
        steps *= 2
        outcome = hybrid.stride(section, theta, Resolution(scout, steps))
    if not outcome.ok:  # the caller reports the failure; no finer scout is sought
        return Resolution(first, 8)
    scout = min(scout, min(outcome.durations) / 4)
    previous = hybrid.stride(section, theta, Resolution(scout, steps))
    while steps < most:
        finer = hybrid.stride(section, theta, Resolution(scout, 2 * steps))
        if previous.ok and finer.ok:
            size = max(1.0, float(np.max(np.abs(finer.end()))))
            if float(np.max(np.abs(previous.end() - finer.end()))) <= VERIFICATION_MARGIN * tolerance * size:
                return Resolution(scout, steps)
        steps, previous = 2 * steps, finer
    return Resolution(scout, most)
