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
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np

from baslip.engine.dop853 import DOP853, event_step, step_function
from baslip.model.symbolic import ModelFunctions, fall_names

#: Newton iterations of an event step (unrolled in its graph).
EVENT_ITERATIONS = 8
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


def _sensitivities(step: ca.Function) -> ca.Function:
    """The step with its derivatives in the state, theta and the step size."""
    x = ca.SX.sym("x", step.size1_in(0))
    h = ca.SX.sym("h")
    theta = ca.SX.sym("theta", step.size1_in(2))
    x_next = step(x, h, theta)[0]
    return ca.Function(f"{step.name()}_sens", [x, h, theta],
                       [x_next, ca.jacobian(x_next, x), ca.jacobian(x_next, theta), ca.jacobian(x_next, h)])


def _guard_sensitivities(guard: ca.Function) -> ca.Function:
    x = ca.SX.sym("x", guard.size1_in(0))
    theta = ca.SX.sym("theta", guard.size1_in(1))
    g = guard(x, theta)
    return ca.Function(f"{guard.name()}_sens", [x, theta], [g, ca.jacobian(g, x), ca.jacobian(g, theta)])


def _reset_sensitivities(reset: ca.Function) -> ca.Function:
    x = ca.SX.sym("x", reset.size1_in(0))
    theta = ca.SX.sym("theta", reset.size1_in(1))
    after = reset(x, theta)
    return ca.Function(f"{reset.name()}_sens", [x, theta], [after, ca.jacobian(after, x), ca.jacobian(after, theta)])


@dataclass(frozen=True)
class _Phase:
    """One mode of the stride and the event that ends it."""

    mode: str
    step: ca.Function
    step_sens: ca.Function
    guard: ca.Function
    guard_sens: ca.Function
    direction: int
    to_event: ca.Function
    falls: ca.Function | None
    fall_names: tuple[str, ...]
    event: str


class HybridMap:
    """The return map of a described model under one law (see the module's docstring).

    Parameters
    ----------
    functions : ModelFunctions
        The model's symbolic pieces (:func:`baslip.model.symbolic.model_functions`).
    """

    def __init__(self, functions: ModelFunctions):
        self.functions = functions

    @cached_property
    def phases(self) -> tuple[_Phase, ...]:
        f = self.functions
        model = f.model
        guards = [*f.guards, f.section_guard]
        directions = [*f.directions, model.section.direction]
        events = [t.label for t in model.stride_transitions()] + ["section"]
        phases = []
        for mode, guard, direction, event in zip(model.order, guards, directions, events):
            step = step_function(f.rhs[mode], tableau=DOP853)
            phases.append(_Phase(mode, step, _sensitivities(step), guard, _guard_sensitivities(guard), direction,
                                 event_step(step, f.rhs[mode], guard, EVENT_ITERATIONS), f.falls.get(mode),
                                 fall_names(model, mode), event))
        return tuple(phases)

    @cached_property
    def resets(self) -> tuple[ca.Function, ...]:
        return tuple(_reset_sensitivities(r) for r in self.functions.resets)

    def stride(self, section: np.ndarray, theta: np.ndarray, resolution: Resolution, jacobian: bool = False,
               nodes: bool = False) -> Outcome:
        """One stride from the section coordinates ``section`` with ``theta`` at
        ``resolution``; with the Jacobians if ``jacobian``, the node states if ``nodes``."""
        f = self.functions
        x = f.lift(section)
        theta = np.asarray(theta, dtype=float)
        n0, nt = len(x), len(theta)
        carried = np.hstack([np.eye(n0), np.zeros((n0, nt))]) if jacobian else None
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
            if number < len(self.resets):
                after, rx, rt = (np.array(v) for v in self.resets[number](x, theta))
                x = after.ravel()
                if carried is not None:
                    carried = rx @ carried + np.hstack([np.zeros((len(x), n0)), rt])
        end = f.project(x)
        if carried is None:
            return Outcome(end, "", tuple(durations), nodes=tuple(visited))
        rows = carried[f.section_index]
        return Outcome(end, "", tuple(durations), rows[:, f.section_index], rows[:, n0:], tuple(visited))

    def _phase(self, phase: _Phase, x: np.ndarray, theta: np.ndarray, step: float, carried, nodes: bool):
        """Integrate ``phase`` from ``x`` to its event: (state, carried Jacobian, duration,
        (times, states)), or why it failed."""
        g_old = float(phase.guard(x, theta))
        if phase.direction * g_old > 0:
            return f"mode {phase.mode} starts past the guard of {phase.event} (it can never cross it)"
        times, states = [0.0], [x]
        for count in range(MAX_STEPS):
            fault = self._fell(phase, x, theta)
            if fault:
                return fault
            if carried is None:
                x_next = np.array(phase.step(x, step, theta)[0]).ravel()
            else:
                x_next, a, b, _ = (np.array(v) for v in phase.step_sens(x, step, theta))
                x_next = x_next.ravel()
            if not np.all(np.isfinite(x_next)):
                return f"the state left the finite numbers in mode {phase.mode}"
            g_new = float(phase.guard(x_next, theta))
            if phase.direction * g_new >= 0 and phase.direction * g_old < 0:
                return self._event(phase, x, theta, step, g_old, g_new, carried, count, times, states, nodes)
            if carried is not None:
                carried = a @ carried + np.hstack([np.zeros((len(x), carried.shape[1] - len(theta))), b])
            x, g_old = x_next, g_new
            if nodes:
                times.append((count + 1) * step)
                states.append(x)
        return (f"the guard of {phase.event} never fired in {MAX_STEPS} steps ({MAX_STEPS * step:.3g} s) "
                f"of mode {phase.mode}")

    def _fell(self, phase: _Phase, x: np.ndarray, theta: np.ndarray) -> str:
        if phase.falls is None:
            return ""
        values = np.array(phase.falls(x, theta)).ravel()
        broken = [name for name, v in zip(phase.fall_names, values) if v < 0]
        return f"fell: {broken[0]} (mode {phase.mode})" if broken else ""

    def _event(self, phase: _Phase, x, theta, step, g_old, g_new, carried, count, times, states, nodes):
        guess = step * g_old / (g_old - g_new)
        s, x_end, residual = (np.array(v) for v in phase.to_event(x, guess, theta)[:3])
        s = s.item()
        if not (0.0 <= s <= 1.5 * step) or abs(residual.item()) > 1e-9 * max(1.0, abs(g_old)):
            return f"the event {phase.event} could not be located in mode {phase.mode}"
        x_end = x_end.ravel()
        duration = count * step + s
        if carried is not None:
            _, a, b, c = (np.array(v) for v in phase.step_sens(x, s, theta))
            _, gx, gt = (np.array(v) for v in phase.guard_sens(x_end, theta))
            n0 = carried.shape[1] - len(theta)
            moved = a @ carried + np.hstack([np.zeros((len(x), n0)), b])
            slope = (gx @ c).item()
            ds = -(gx @ moved + np.hstack([np.zeros((1, n0)), gt])) / slope
            carried = moved + c @ ds
        if nodes:
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
