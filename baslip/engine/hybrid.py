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
controls) is that of the discrete map itself, swept back from the stride's end to its
start once the stride is run (an adjoint per section coordinate): through a fixed step by
its state and theta derivatives, an event step by the implicit-function theorem (the step
size moves with the state so that the guard stays at zero), a reset by its own.

Because the step size follows the scout's duration, which is smooth in the arguments, so
is the map, and Newton's method sees a smooth function; the Jacobian holds the step sizes
fixed (their own derivative moves the map only by its truncation error). The accuracy is
set by :func:`calibrated_resolution`, which doubles n until two agree, and checked by
:mod:`baslip.engine.hybrid_check`, which re-simulates with a different integrator.

The steps run in generated code, compiled to C (:mod:`baslip.engine.hybrid_kernels`). One
call takes the whole stride: each mode's scout, its run and their events, each loop
stopping at the first step where the mode fell, was lost or crossed its guard, as a loop
over single steps would, with the same numbers to the bit. From a mode too long for that
call (its scout over 64 steps) on, each mode takes a call for its run and one for every
eight steps of its scout instead. A stride costs 0.1 to 0.3 ms instead of 8 to 43 ms one
step at a time (``benchmarks/bench_models.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from baslip.engine.hybrid_kernels import CHUNK, RUN_STEPS, PhaseKernels, StrideKernels, stride_kernels
from baslip.model.symbolic import ModelFunctions, fall_names

#: The share of the tolerance two step counts must agree to for the coarser to be used.
VERIFICATION_MARGIN = 0.1
#: Relative difference between the strides at n and 2n steps below which a difference
#: that stops falling is the strides' rounding, not their truncation error: DOP853's
#: truncation error falls 256-fold a doubling, their rounding grows with the steps.
ROUNDING_FLOOR = 1e-11
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
    flows: bool  # the mode has a closed-form flow, whose steps cost next to nothing

    @property
    def scout_steps(self) -> int:
        """Steps the scout's first call takes: for a mode with a flow the longest run, as
        its steps cost next to nothing (the scout's step is at most a quarter of the
        shortest mode, so a long mode takes many), for the others a chunk."""
        return RUN_STEPS[-1] if self.flows else CHUNK


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
        return tuple(_Phase(mode, direction, fall_names(model, mode), event, kernels, mode in self.functions.flows)
                     for mode, direction, event, kernels in zip(model.order, directions, events, self.kernels.phases))

    def stride(self, section: np.ndarray, theta: np.ndarray, resolution: Resolution, jacobian: bool = False,
               nodes: bool = False) -> Outcome:
        """One stride from the section coordinates ``section`` with ``theta`` at
        ``resolution``; with the Jacobians if ``jacobian``, the node states if ``nodes``."""
        f = self.functions
        x = f.lift(section)
        theta = np.asarray(theta, dtype=float)
        durations: list[float] = []
        passages: list[_Passage] = []
        whole = self.kernels.strides.get(resolution.steps)
        outputs = whole(x, resolution.scout, theta) if whole is not None else None
        for number, phase in enumerate(self.phases):
            passage = None
            if outputs is not None:
                per_mode = len(outputs) // len(self.phases)
                passage = self._whole(phase, outputs[number * per_mode:(number + 1) * per_mode], x, resolution.scout,
                                      jacobian or nodes)
            if passage is None:  # this mode, and so those after it, did not fit the call's steps
                outputs = None
                passage = self._by_calls(phase, x, theta, resolution, jacobian or nodes)
            if isinstance(passage, str):
                return Outcome(None, passage, tuple(durations), nodes=_visited(passages, nodes))
            durations.append(passage.duration)
            passages.append(passage)
            x = passage.after
        end = x[f.section_index]
        visited = _visited(passages, nodes)
        if not jacobian:
            return Outcome(end, "", tuple(durations), nodes=visited)
        by_section, by_theta = self._swept_back(passages, theta)
        return Outcome(end, "", tuple(durations), by_section, by_theta, visited)

    def _swept_back(self, passages: list[_Passage], theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d(section at the end) / d(section coordinates, theta) of the stride that took
        ``passages``, by the adjoint sweep from its end back to its start: A holds one column
        per section coordinate at the end, G gathers A^T d x_end / d theta."""
        index = self.functions.section_index
        adjoint = np.zeros((len(passages[-1].end), len(index)))
        adjoint[index, np.arange(len(index))] = 1.0
        gathered = np.zeros((len(theta), len(index)))
        for number in reversed(range(len(passages))):
            passage, kernels = passages[number], self.phases[number].kernels
            if number < len(self.kernels.resets):
                adjoint, added = self.kernels.resets[number].reset_adjoint(passage.end, adjoint, theta)
                gathered = gathered + added
            event = 1.0  # the first call goes through the event's step too
            starts = passage.states[-3::-1]  # the fixed steps' start states, the last step first
            for kernel, width, count in kernels.adjoint_calls(len(starts)):
                columns = np.repeat(passage.states[:1].T, width, axis=1)  # skipped columns: a finite state
                columns[:, :count] = starts[:count].T
                active = (np.arange(width) < count).astype(float)
                adjoint, gathered = kernel(adjoint, gathered, passage.states[-2], passage.last_step, event, columns,
                                           active, passage.step, theta)
                starts, event = starts[count:], 0.0
        return adjoint[index].T, gathered.T

    def _by_calls(self, phase: _Phase, x: np.ndarray, theta: np.ndarray, resolution: Resolution,
                  record: bool) -> _Passage | str:
        """Integrate ``phase`` from ``x``: its scout, then its run of ``resolution.steps``
        steps (see the module's docstring), in calls of eight steps, or of a run."""
        scouted = self._phase(phase, x, theta, resolution.scout, False, phase.scout_steps)
        if isinstance(scouted, str):
            return scouted
        return self._phase(phase, x, theta, scouted.duration / (resolution.steps - 0.5), record, resolution.steps)

    def _whole(self, phase: _Phase, outputs: tuple, x: np.ndarray, scout: float, record: bool) -> _Passage | str | None:
        """The passage through ``phase`` from ``x``, as the whole stride's call gave it (the
        mode's ``outputs``), or why it failed, or None where the mode's scout or run did not
        stop within the call's steps."""
        g_start, *stopping, step, x_end, after, nodes = outputs
        if phase.direction * g_start.item() > 0:
            return f"mode {phase.mode} starts past the guard of {phase.event} (it can never cross it)"
        scouted, run = stopping[:7], stopping[7:]  # each: stopped, count, falls, end, s, residual, g_old
        for (stopped, _, falls, end, s, residual, g_old), size in ((scouted, scout), (run, step.item())):
            if not stopped.item():
                return None
            why = _stopped_why(phase, falls.ravel(), end.ravel()) or _unlocated(phase, s.item(), size, residual.item(),
                                                                                g_old.item())
            if why:
                return why
        count = int(run[1].item())
        states = np.vstack([x, nodes[:, :count].T, x_end.T]) if record else x_end.T
        return _Passage(phase.mode, step.item(), count, run[4].item(), states, after.ravel())

    def _phase(self, phase: _Phase, x: np.ndarray, theta: np.ndarray, step: float, record: bool,
               count: int) -> _Passage | str:
        """Integrate ``phase`` from ``x`` in steps of ``step`` to its event: the passage, with
        every node's state if ``record``, or why it failed. The first call takes ``count``
        steps if the library has a kernel for that many (a run's n), the others a chunk
        each."""
        kernels = phase.kernels
        states = [x] if record else []
        taken = 0
        while taken < MAX_STEPS:
            chunk = _Chunk.of(x, (kernels.steps(count) if taken == 0 else kernels.chunk)(x, step, theta))
            if taken == 0 and phase.direction * chunk.guards[0] > 0:
                return f"mode {phase.mode} starts past the guard of {phase.event} (it can never cross it)"
            length, last = chunk.length, chunk.stop
            if record:
                states.extend(chunk.nodes[:, :last].T)
            if last < length:
                why = _stopped_why(phase, chunk.falls[:, last], chunk.nodes[:, last])
                if why:
                    return why
                return self._event(phase, chunk.start_of(last), theta, step, chunk.guards[last],
                                   chunk.guards[last + 1], taken + last, states)
            x, taken = chunk.start_of(length), taken + length
        return (f"the guard of {phase.event} never fired in {MAX_STEPS} steps ({MAX_STEPS * step:.3g} s) "
                f"of mode {phase.mode}")

    def _event(self, phase: _Phase, x, theta, step, g_old, g_new, count, states) -> _Passage | str:
        guess = step * g_old / (g_old - g_new)
        s, x_end, residual, *_, after = phase.kernels.event(x, guess, theta)
        s = s.item()
        why = _unlocated(phase, s, step, residual.item(), g_old)
        if why:
            return why
        states.append(x_end.ravel())
        return _Passage(phase.mode, step, count, s, np.array(states), after.ravel())


def _stopped_why(phase: _Phase, falls: np.ndarray, end: np.ndarray) -> str:
    """Why the step that stopped ``phase`` failed, the falls at its start and its end given:
    it fell, or it left the finite numbers; "" if it crossed the guard."""
    broken = [name for name, v in zip(phase.fall_names, falls) if v < 0]
    if broken:
        return f"fell: {broken[0]} (mode {phase.mode})"
    if not np.all(np.isfinite(end)):
        return f"the state left the finite numbers in mode {phase.mode}"
    return ""


def _unlocated(phase: _Phase, s: float, step: float, residual: float, g_old: float) -> str:
    """Why the event step of size ``s`` (the steps' size ``step``), whose guard ended at
    ``residual`` from ``g_old`` at its start, does not locate the event; "" if it does."""
    if not (0.0 <= s <= 1.5 * step) or abs(residual) > 1e-9 * max(1.0, abs(g_old)):
        return f"the event {phase.event} could not be located in mode {phase.mode}"
    return ""


@dataclass(frozen=True)
class _Passage:
    """How a stride passed through one mode: its steps' size ``step`` [s], the count of
    them, the last step's size ``last_step`` [s] (the one that ends on the guard, after
    ``count``) and the states at every node from the mode's start to its end (rows), or the
    end's alone where they were not recorded; ``after``, the state after the transition's
    reset (the end itself after the stride's last mode)."""

    mode: str
    step: float
    count: int
    last_step: float
    states: np.ndarray
    after: np.ndarray

    @property
    def end(self) -> np.ndarray:
        return self.states[-1]

    @property
    def duration(self) -> float:
        return self.count * self.step + self.last_step

    @property
    def times(self) -> np.ndarray:
        """The time [s] at each recorded node, from the mode's start."""
        return np.append(np.arange(self.count + 1) * self.step, self.duration)


def _visited(passages: list[_Passage], asked: bool) -> tuple:
    """The nodes of the modes passed, if ``asked``: (mode, times, states) each, as
    :class:`Outcome` holds them."""
    return tuple((p.mode, p.times, p.states) for p in passages) if asked else ()


@dataclass(frozen=True)
class _Chunk:
    """Steps from ``start``, as one call of a chunk (or run) kernel returned them.

    ``nodes`` holds the state after each step (columns), ``guards`` the guard at the start
    and at each node, ``falls`` the mode's falls at each step's start, ``stop`` the first
    step that stopped the mode (the length if none did): step k (from 0) stops it if it
    *fell* (a fall negative at its start), is *lost* (its end not finite) or *crossed* the
    guard (passed zero in the mode's direction), which the kernel finds."""

    start: np.ndarray
    nodes: np.ndarray
    guards: np.ndarray
    falls: np.ndarray
    stop: int

    @classmethod
    def of(cls, start, outputs: tuple) -> _Chunk:
        """From a chunk kernel's outputs: (nodes, guards, falls, the guard at the start, stop)."""
        nodes, guards, falls, g_start, stop = outputs
        return cls(start, nodes, np.concatenate([g_start.ravel(), guards.ravel()]), falls, int(stop.item()))

    @property
    def length(self) -> int:
        return self.nodes.shape[1]

    def start_of(self, k: int) -> np.ndarray:
        """The state step ``k`` starts from (k = the length: the end)."""
        return self.start if k == 0 else self.nodes[:, k - 1]


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
    gait of the virtual-constraint law missed it by 1.02e-10 against 1e-10).

    Below about 1e-12 the differences reach the strides' rounding, which grows with the
    steps: at the BA-SLIP's upward gait they fall to 1.9e-13 (16 against 32 steps) and
    2.1e-13 (32 against 64), then rise to 1.3e-12 (128 against 256) and 3.6e-12. Once a difference below :data:`ROUNDING_FLOOR`
    stops falling, the count with the least difference is returned, the most accurate
    there is. Raises nothing: if no count agrees otherwise, ``most`` is returned (the
    verification, by another integrator, then decides).
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
    best, least = Resolution(scout, most), math.inf  # the count with the least difference, and that
    while steps < most:
        finer = hybrid.stride(section, theta, Resolution(scout, 2 * steps))
        if previous.ok and finer.ok:
            size = max(1.0, float(np.max(np.abs(finer.end()))))
            difference = float(np.max(np.abs(previous.end() - finer.end()))) / size
            if difference <= VERIFICATION_MARGIN * tolerance:
                return Resolution(scout, steps)
            if difference >= least and least <= ROUNDING_FLOOR:
                return best  # the differences are the strides' rounding, which more steps only grow
            if difference < least:
                best, least = Resolution(scout, steps), difference
        steps, previous = 2 * steps, finer
    return Resolution(scout, most)
