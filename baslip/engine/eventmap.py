"""The reference return-map engine: CasADi's adaptive integrators with events.

* The touchdown time solves the foot-height guard with a CasADi ``rootfinder``
  (``fast_newton``, which can be code-generated), started from the bracketed guess of
  :func:`~baslip.engine.outcome.touchdown_guess`, so its derivative comes from the implicit
  function theorem.
* Stance is one CasADi integrator (``erk``, or ``rosenbrock`` for the independent check)
  with zero-crossing events: a phase flag in the augmented state switches from
  compression to decompression at the bottom event, and freezes the state at liftoff or
  when the runner falls (CoM or hip reaching the ground, the leg collapsing). Forward
  sensitivities include those of the event times, so the Jacobians are algorithmic
  derivatives through the events.
* The ascent to the next apex is closed form, ``t = zdot / g``.

The value of a stride (integrator, events and all) is generated as C and cached on disk
like the compiled engine (:mod:`baslip.engine.codegen`), one library per plugin and tolerance:
the same numbers as CasADi's virtual machine, about ten times sooner. Jacobians and the
drawing samples, needed far less often, stay in the virtual machine, built on first use.
"""

from __future__ import annotations

import contextlib
import functools
import io
import math
import pathlib
import sys

import casadi as ca
import numpy as np

from baslip.engine import codegen as _codegen
from baslip.engine import outcome as _outcome_module
from baslip.engine.codegen import compile_kernels, library_name, module_files
from baslip.engine.native import VirtualMachineKernel
from baslip.engine.outcome import (
    PHASES,
    STANCE_HORIZON_HALF_PERIODS,
    Fall,
    Stride,
    Tolerances,
    param_vector,
    vec,
)
from baslip.engine.physics import Physics, physics_modules
from baslip.model.dynamics import (
    APEX,
    FLIGHT,
    PARAMS,
    STANCE,
    apex_to_flight,
    flight_to_apex,
)
from baslip.model.hiplaw import PD, HipLaw
from baslip.model.layout import Layout

# Augmented stance state: the mechanical state, a clock, the bottom time and a phase flag.
STANCE_RUN = Layout(STANCE.names + ("clock", "t_bottom", "phase"))
# Phase flag values; falls are frozen with their own flag.
COMPRESSION, DECOMPRESSION, LIFTED_OFF = 0.0, 1.0, 2.0
# Scalar outputs of the stride function that decide whether and how it fell.
DIAGNOSTICS = ("phase", "rhodot_td", "zdot_lo", "foot_height_td", "com_height_td")
# Event indicators, in this order; each becomes negative at its event.
EVENTS = ("bottom", "liftoff", "com_ground", "hip_ground", "collapse")
_FALL_OF_PHASE = {
    3.0: Fall.COM_HITS_GROUND,
    4.0: Fall.HIP_HITS_GROUND,
    5.0: Fall.LEG_COLLAPSES,
}


def _stance_run_dynamics(s, u, p, physics: Physics):
    """Right-hand side of the augmented stance state, with time scaled by the horizon."""
    x = s[: STANCE.size]
    phase = STANCE_RUN.get(s, "phase")
    moving = phase < 1.5
    xdot = physics.stance_rate(x, u, p)
    return ca.if_else(moving, ca.vertcat(xdot, 1, 0, 0), ca.DM.zeros(STANCE_RUN.size))


def _stance_run_indicators(s, u, p, physics: Physics):
    """Zero-crossing indicators in :data:`EVENTS` order; inactive ones held at +1."""
    x = s[: STANCE.size]
    phase = STANCE_RUN.get(s, "phase")
    in_compression = phase < 0.5
    in_stance = phase < 1.5
    in_decompression = ca.logic_and(in_stance, ca.logic_not(in_compression))
    com, hip, leg = ca.vertsplit(physics.clearances(x, u, p))
    return ca.vertcat(
        ca.if_else(in_compression, -physics.guard("bottom", x, u, p), 1),
        ca.if_else(in_decompression, -physics.guard("liftoff", x, u, p), 1),
        ca.if_else(in_stance, com, 1),
        ca.if_else(in_stance, hip, 1),
        ca.if_else(in_stance, leg, 1),
    )


def _stance_run_transition(law: HipLaw):
    """Event transition: advance or freeze the phase flag, record the bottom time."""
    index = ca.SX.sym("index")
    t = ca.SX.sym("t")
    s = STANCE_RUN.sym("s")
    u_and_p = ca.SX.sym("up", law.controls.size + PARAMS.size + 1)
    empty = ca.SX(0, 1)
    clock = STANCE_RUN.get(s, "clock")
    after_bottom = ca.vertcat(s[: STANCE.size], clock, clock, DECOMPRESSION)
    frozen = [ca.vertcat(s[: STANCE_RUN.size - 1], flag) for flag in (LIFTED_OFF, 3.0, 4.0, 5.0)]
    post = ca.conditional(index, [after_bottom] + frozen, s)
    return ca.Function(
        "stance_transition", [index, t, s, empty, u_and_p, empty], [post, empty],
        ca.event_in(), ca.event_out(),
    )


class EventMap:
    """One stride by an adaptive CasADi integrator with events, built once per tolerance.

    The reference engine: adaptive ``erk`` (or ``rosenbrock``, for the independent
    verification) at any tolerance, and the fallback of the compiled engine where that
    cannot guarantee its accuracy. Inputs are numeric vectors that passed
    :func:`~baslip.engine.outcome.precheck`; ``t_guess`` is its touchdown time guess [s].
    ``compile`` forces the C route of the stride's value on or off; None follows the
    environment (see :func:`baslip.engine.codegen.compile_kernels`), and
    :data:`~baslip.engine.codegen.IF_CACHED` compiles nothing. ``law`` is the hip law.
    """

    def __init__(self, tolerances: Tolerances, plugin: str = "erk", compile: bool | str | None = None,
                 law: HipLaw = PD):
        self.tolerances = tolerances
        self.plugin = plugin
        self.law = law
        self.physics = Physics.of(law)
        self._compile = compile
        self._samplers: dict = {}  # functions needed only by some users, built on first use
        # A warm cache loads the compiled stride without building any CasADi object.
        self._value = compile_kernels(
            library_name(f"baslip_events_{plugin}", law), ["stride"], lambda: [self._stride_fn], _sources(),
            enabled=compile, settings=f"{plugin} rtol={tolerances.rtol!r} atol={tolerances.atol!r}",
        )["stride"]

    # -- construction ------------------------------------------------------------------

    @functools.cached_property
    def _stride_fn(self) -> ca.Function:
        """(X, u, p, t_guess) -> (apex, durations, diagnostics), symbolic."""
        with _event_notice_silenced():
            return self._build_stride_function()

    @functools.cached_property
    def _jacobian_fn(self) -> ca.Function:
        """dr/d(X, u) with the stride's outputs: one sensitivity sweep instead of two."""
        X, u, p, t_guess = self._stride_fn.mx_in()
        outputs = self._stride_fn(X, u, p, t_guess)
        with _event_notice_silenced():
            return ca.Function(
                "return_map_jacobian",
                [X, u, p, t_guess],
                [ca.jacobian(outputs[0], ca.vertcat(X, u)), *outputs],
                ["X", "u", "p", "t_touchdown_guess"],
                ["dr_dXu", "apex", "durations", "diagnostics"],
            )

    def _build_touchdown_rootfinder(self) -> ca.Function:
        t = ca.SX.sym("t")
        X, u, p = APEX.sym("X"), self.law.controls.sym("u"), PARAMS.sym("p")
        foot_height = self.physics.guard("touchdown", self.physics.flight(apex_to_flight(X), t, u, p), u, p)
        residual = ca.Function("touchdown_residual", [t, ca.vertcat(X, u, p)], [foot_height])
        # From the bracketed guess Newton converges in a few steps; a guess that does not
        # converge leaves a foot height that the outcome reports as no touchdown.
        return ca.rootfinder(
            "touchdown_time", "fast_newton", residual, {"abstol": 1e-15, "abstolStep": 1e-16, "max_iter": 50},
        )

    def _build_stance_integrator(self, output_times=(1.0,)) -> ca.Function:
        """Stance over the time-scaled horizon [0, 1], with outputs at ``output_times``."""
        s = STANCE_RUN.sym("s")
        u, p, horizon = self.law.controls.sym("u"), PARAMS.sym("p"), ca.SX.sym("horizon")
        dae = {
            "x": s,
            "p": ca.vertcat(u, p, horizon),
            "ode": horizon * _stance_run_dynamics(s, u, p, self.physics),
            "zero": _stance_run_indicators(s, u, p, self.physics),
        }
        opts = {
            "transition": _stance_run_transition(self.law),
            "reltol": self.tolerances.rtol,
            "abstol": self.tolerances.atol,
            "max_events": 8,
            "max_num_steps": 100000,
        }
        return ca.integrator("stance", self.plugin, dae, 0.0, list(output_times), opts)

    def _build_stride_function(self) -> ca.Function:
        X, u, p = APEX.sym("X", ca.MX), self.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
        t_guess = ca.MX.sym("t_touchdown_guess")
        t_descent = self._build_touchdown_rootfinder()(t_guess, ca.vertcat(X, u, p))
        at_touchdown = self.physics.flight(apex_to_flight(X), t_descent, u, p)
        x_td = self.physics.reset("touchdown", at_touchdown, u, p)
        horizon = STANCE_HORIZON_HALF_PERIODS * math.pi * ca.sqrt(PARAMS.get(p, "m") / PARAMS.get(p, "k"))
        s0 = ca.vertcat(x_td, 0, 0, COMPRESSION)
        s_end = self._build_stance_integrator()(x0=s0, p=ca.vertcat(u, p, horizon))["xf"]
        x_lo = s_end[: STANCE.size]
        at_liftoff = self.physics.reset("liftoff", x_lo, u, p)
        apex_next = flight_to_apex(at_liftoff, p)
        t_stance, t_bottom = STANCE_RUN.get(s_end, "clock"), STANCE_RUN.get(s_end, "t_bottom")
        zdot_lo = FLIGHT.get(at_liftoff, "zdot")
        durations = ca.vertcat(t_descent, t_bottom, t_stance - t_bottom, zdot_lo / PARAMS.get(p, "g"))
        diagnostics = ca.vertcat(
            STANCE_RUN.get(s_end, "phase"), self.physics.guard("bottom", x_td, u, p), zdot_lo,
            self.physics.guard("touchdown", at_touchdown, u, p), FLIGHT.get(at_touchdown, "z"),
        )
        return ca.Function(
            "stride", [X, u, p, t_guess], [apex_next, durations, diagnostics],
            ["X", "u", "p", "t_touchdown_guess"], ["apex", "durations", "diagnostics"],
        )

    # -- numeric use -------------------------------------------------------------------

    def stride(self, X, u, p, t_guess) -> Stride:
        """One stride from apex ``X`` [m, rad, m/s, rad/s] under control ``u`` [SI, rad],
        parameter vector ``p``, with ``t_guess`` [s] the guess of the descent's duration
        (:func:`~baslip.engine.outcome.touchdown_guess`): the next apex and phase
        durations, or the fall."""
        try:
            outputs = self._value(X, u, p, t_guess)
        except RuntimeError:  # the integrator gave up (a CasADi error, or a C status)
            return Stride(None, {}, Fall.INTEGRATION_FAILED)
        return _outcome(*(np.asarray(v).ravel() for v in outputs))

    def stride_jacobian(self, X, u, p, t_guess, with_parameters: bool) -> tuple[np.ndarray | None, Stride]:
        """(dr/d(X, u), or dr/d(X, u, p) if ``with_parameters``, and the stride); the
        Jacobian is None if the stride falls."""
        try:
            with _failure_dump_silenced():
                jac, *outputs = self._jacobian_fn(X, u, p, t_guess)
        except RuntimeError:
            return None, Stride(None, {}, Fall.INTEGRATION_FAILED)
        outcome = _outcome(*(np.asarray(v).ravel() for v in outputs))
        if outcome.fall is not None:
            return None, outcome
        jac = np.asarray(jac)
        if with_parameters:
            jac = np.hstack([jac, self._parameter_jacobian(X, u, p, t_guess)])
        return jac, outcome

    def _parameter_jacobian(self, X, u, p, t_guess) -> np.ndarray:
        """One stride's dr/dp; its function is built on first use."""
        if "parameter_jacobian" not in self._samplers:
            Xs, us, ps, tg = self._stride_fn.mx_in()
            with _event_notice_silenced():
                self._samplers["parameter_jacobian"] = ca.Function(
                    "return_map_parameter_jacobian", [Xs, us, ps, tg],
                    [ca.jacobian(self._stride_fn(Xs, us, ps, tg)[0], ps)],
                )
        return np.asarray(self._samplers["parameter_jacobian"](X, u, p, t_guess))

    def stance_samples(self, x_touchdown, u, params, duration: float, n: int, compiled: bool = False) -> np.ndarray:
        """Stance states (6 x n) at n equal steps up to ``duration`` [s] after touchdown,
        for drawing and for the trunk's range; ``duration`` is normally the stride's stance
        time. ``compiled``: the integrator generated as C and cached, one library per ``n``
        (where this map compiles at all), for many calls (the atlas checks every chart's
        trunk range with it); else CasADi's virtual machine, which needs no compile."""
        key = ("stance_samples", n, compiled)
        if key not in self._samplers:
            if compiled:
                self._samplers[key] = compile_kernels(
                    library_name(f"baslip_stance_samples_{self.plugin}", self.law), ["stance_samples"],
                    lambda: [self._stance_samples_function(n)], _sources(), enabled=self._compile,
                    settings=f"{self.plugin} rtol={self.tolerances.rtol!r} atol={self.tolerances.atol!r} n={n}",
                )["stance_samples"]
            else:
                self._samplers[key] = VirtualMachineKernel(self._stance_samples_function(n))
        s0 = np.concatenate([vec(x_touchdown), [0.0, 0.0, COMPRESSION]])
        p = np.concatenate([vec(u), param_vector(params), [duration]])
        return np.asarray(self._samplers[key](s0, p)[0])[: STANCE.size, :]

    def _stance_samples_function(self, n: int) -> ca.Function:
        """(s0, (u, p, duration)) -> the augmented stance states at n equal steps."""
        s0 = STANCE_RUN.sym("s0", ca.MX)
        up = ca.MX.sym("p", self.law.controls.size + PARAMS.size + 1)
        with _event_notice_silenced():
            integrator = self._build_stance_integrator(np.linspace(0.0, 1.0, n + 1)[1:])
            return ca.Function("stance_samples", [s0, up], [integrator(x0=s0, p=up)["xf"]], ["s0", "p"], ["states"])


def _outcome(apex, durations, diagnostics) -> Stride:
    """Classify a stride's outputs: the next apex, or the reason the runner fell."""
    d = dict(zip(DIAGNOSTICS, diagnostics))
    reached = dict(zip(PHASES, durations.tolist()))
    descent_only = {"descent": reached["descent"]}
    if not abs(d["foot_height_td"]) <= 1e-10 or not reached["descent"] > 0.0:
        return Stride(None, {}, Fall.NO_TOUCHDOWN)
    # Descent lowers the CoM monotonically, so touchdown is its lowest point in flight;
    # an underground start would never trigger the stance's crossing events.
    if d["com_height_td"] <= 0.0:
        return Stride(None, descent_only, Fall.COM_HITS_GROUND)
    if d["rhodot_td"] >= 0.0:
        return Stride(None, descent_only, Fall.LEG_EXTENDING_AT_TOUCHDOWN)
    if d["phase"] in _FALL_OF_PHASE:
        return Stride(None, descent_only, _FALL_OF_PHASE[d["phase"]])
    if d["phase"] != LIFTED_OFF:
        return Stride(None, descent_only, Fall.STANCE_NEVER_ENDS)
    if d["zdot_lo"] <= 0.0:
        return Stride(None, {k: reached[k] for k in PHASES[:3]}, Fall.LIFTOFF_DESCENDING)
    if not np.all(np.isfinite(apex)):
        return Stride(None, reached, Fall.NOT_FINITE)
    return Stride(apex, reached, None)


@contextlib.contextmanager
def _failure_dump_silenced():
    """Keep CasADi from printing on standard error (through Python's ``sys.stderr``):
    where the touchdown rootfinder's derivative fails, far outside the design box, it
    prints the failing inputs before it raises, and the caller reports the stride as
    failed anyway."""
    with contextlib.redirect_stderr(io.StringIO()):
        yield


@contextlib.contextmanager
def _event_notice_silenced():
    """Silence CasADi's 'Event support is experimental' notice while building integrators.

    CasADi 3.8 prints it (through Python's sys.stderr) for every integrator with events;
    the event handling is what we rely on and test, so the notice is only noise to users.
    Errors still surface as Python exceptions.
    """
    with contextlib.redirect_stderr(io.StringIO()):
        yield


def _sources() -> list[pathlib.Path]:
    """The modules the event map's stride is derived from: the compiled library's key."""
    return module_files(*physics_modules(), _outcome_module, sys.modules[__name__], _codegen)
