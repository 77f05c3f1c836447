"""An independent stride of a described model, for verifying its fixed points.

It shares the model's symbolic right-hand sides, guards and resets with the engine (they
are the model), but none of its integration: each mode is integrated by CVODES (SUNDIALS'
variable-order BDF method, tight tolerances) over a grid of times (the engine's step)
until the guard is seen crossing, and the event time is then found by Newton on the guard with CVODES integrating
the time-scaled flow ``x' = tau f(x)`` to ``tau``. A fixed point of the engine's map that
this map also fixes to the verification tolerance is reported; one it does not fix is not.
"""

from __future__ import annotations

from functools import cached_property

import casadi as ca
import numpy as np

from baslip.model.symbolic import ModelFunctions

#: CVODES's relative and absolute tolerances: its error over a stride is then about 1e-12
#: at the reference SLIP (at 1e-13 it was 5e-11, and DOP853 at 0.005 s held 5e-15).
TOLERANCE = 1e-14
#: Newton (or bisection) iterations on an event time, at most, and the guard's tolerance
#: (relative).
EVENT_ITERATIONS = 80
EVENT_TOLERANCE = 1e-13
#: An event time that moves by less than this fraction of the interval is found.
TIME_RESOLUTION = 1e-14
#: Grid intervals searched for a crossing, at most, per mode, and per call of CVODES.
MAX_INTERVALS = 5120
CHUNK = 32


class IndependentStride:
    """The return map by CVODES and Newton-located events (see the module's docstring)."""

    def __init__(self, functions: ModelFunctions):
        self.functions = functions
        self._rates: dict[str, ca.Function] = {}  # each guard's rate, built once

    def _flows(self, grid: np.ndarray) -> dict[str, ca.Function]:
        """By mode: the states of ``x' = tau f(x)`` from ``x0`` at the times ``grid``
        (of [0, 1]), so after ``tau`` times each."""
        flows = {}
        options = {"abstol": TOLERANCE, "reltol": TOLERANCE, "max_num_steps": 200000}
        for mode, rhs in self.functions.rhs.items():
            x = ca.SX.sym("x", rhs.size1_in(0))
            theta = ca.SX.sym("theta", rhs.size1_in(1))
            tau = ca.SX.sym("tau")
            dae = {"x": x, "p": ca.vertcat(theta, tau), "ode": tau * rhs(x, theta)}
            flows[mode] = ca.integrator(f"{mode}_cvodes", "cvodes", dae, 0.0, grid, options)
        return flows

    @cached_property
    def flows(self) -> dict[str, ca.Function]:
        """By mode: the state after ``tau`` [s] from ``x0``."""
        return self._flows(np.array([1.0]))

    @cached_property
    def chunks(self) -> dict[str, ca.Function]:
        """By mode: the states at :data:`CHUNK` equal intervals of ``tau`` [s] in all."""
        return self._flows(np.linspace(0.0, 1.0, CHUNK + 1)[1:])

    def _advance(self, mode: str, x: np.ndarray, theta: np.ndarray, tau: float) -> np.ndarray:
        return np.array(self.flows[mode](x0=x, p=np.append(theta, tau))["xf"]).ravel()

    def stride(self, section: np.ndarray, theta: np.ndarray, interval: float) -> np.ndarray | str:
        """The section coordinates after one stride from ``section``, or why it failed;
        crossings are sought on a grid of ``interval`` [s]."""
        f = self.functions
        x = f.lift(section)
        theta = np.asarray(theta, dtype=float)
        guards = [*f.guards, f.section_guard]
        directions = [*f.directions, f.model.section.direction]
        for number, mode in enumerate(f.model.order):
            x = self._to_event(mode, x, theta, guards[number], directions[number], interval)
            if isinstance(x, str):
                return x
            if number < len(f.resets):
                x = np.array(f.resets[number](x, theta)).ravel()
        return f.project(x)

    def _to_event(self, mode: str, x: np.ndarray, theta: np.ndarray, guard: ca.Function, direction: int,
                  interval: float) -> np.ndarray | str:
        rhs = self.functions.rhs[mode]
        g_old = float(guard(x, theta))
        for _ in range(MAX_INTERVALS // CHUNK):
            states = np.array(self.chunks[mode](x0=x, p=np.append(theta, CHUNK * interval))["xf"]).T
            for x_next in states:
                g_new = float(guard(x_next, theta))
                if direction * g_new >= 0 and direction * g_old < 0:
                    scale = max(1.0, abs(g_old), abs(g_new))
                    return self._locate(mode, x, theta, guard, rhs, interval, g_old, scale)
                x, g_old = x_next, g_new
        return f"no event in mode {mode} within {MAX_INTERVALS * interval:.3g} s"

    def _locate(self, mode, x, theta, guard, rhs, interval: float, g_old: float, scale: float) -> np.ndarray | str:
        """The state where the guard is zero within ``interval`` [s] of ``x``: Newton on the
        time, kept inside the bracket (a step that leaves it bisects instead), to within
        :data:`EVENT_TOLERANCE` of ``scale`` (the guard's size over the interval), or
        until the time moves by less than :data:`TIME_RESOLUTION` of the interval (where
        a stiff guard's value is all integration noise)."""
        if guard.name() not in self._rates:
            self._rates[guard.name()] = _guard_rate(guard, rhs)
        rate_of = self._rates[guard.name()]
        low, high = 0.0, interval
        tau = interval / 2
        for _ in range(EVENT_ITERATIONS):
            end = self._advance(mode, x, theta, tau)
            value = float(guard(end, theta))
            if abs(value) <= EVENT_TOLERANCE * scale:
                return end
            if (value > 0) == (g_old > 0):
                low = tau
            else:
                high = tau
            newton = tau - value / float(rate_of(end, theta))
            following = newton if low < newton < high else (low + high) / 2
            if abs(following - tau) <= TIME_RESOLUTION * interval:
                return self._advance(mode, x, theta, following)
            tau = following
        return f"the event in mode {mode} could not be located by Newton"


def _guard_rate(guard: ca.Function, rhs: ca.Function) -> ca.Function:
    """d/dt guard(x(t)) = grad(guard) . f(x)."""
    x = ca.SX.sym("x", rhs.size1_in(0))
    theta = ca.SX.sym("theta", rhs.size1_in(1))
    return ca.Function("guard_rate", [x, theta], [ca.jtimes(guard(x, theta), x, rhs(x, theta))])
