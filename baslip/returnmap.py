"""The apex-to-apex return map r(X, u) and multi-stride simulation.

One stride: apex -> descent (closed-form ballistic flight) -> touchdown -> compression ->
bottom -> decompression -> liftoff -> ascent (closed form) -> apex.

* The touchdown time solves the foot-height guard with a CasADi ``rootfinder`` (Newton),
  started from a bracketed numeric guess, so its derivative comes from the implicit
  function theorem.
* Stance is one CasADi ``erk`` integrator with zero-crossing events: a phase flag in the
  augmented state switches from compression to decompression at the bottom event, and
  freezes the state at liftoff or when the runner falls (CoM or hip reaching the ground,
  the leg collapsing). Forward sensitivities include those of the event times, so the
  Jacobians of ``r`` are algorithmic derivatives through the events.
* The ascent to the next apex is closed form, ``t = zdot / g``.

Falls are outcomes, not exceptions: :meth:`ReturnMap.stride` returns a :class:`Stride`
whose ``fall`` names the reason, and :meth:`ReturnMap.simulate` stops there.
"""

from __future__ import annotations

import contextlib
import io
import math
from dataclasses import dataclass, field
from enum import Enum

import casadi as ca
import numpy as np

from .control import CONTROL, hip_torque, touchdown_angle
from .layout import Layout
from .model import (
    APEX,
    FLIGHT,
    PARAMS,
    STANCE,
    apex_to_flight,
    ballistic_flight,
    bottom_guard,
    descent_foot_height,
    flight_to_apex,
    liftoff_guard,
    liftoff_map,
    stance_com_position,
    stance_dynamics,
    stance_hip_position,
    touchdown_guard,
    touchdown_map,
)

PHASES = ("descent", "compression", "decompression", "ascent")

#: Leg length below which the leg counts as collapsed, as a fraction of rho0.
COLLAPSE_FRACTION = 0.05
#: Integration horizon of stance, in spring half-periods pi*sqrt(m/k); stance that has not
#: ended by then "never ends".
STANCE_HORIZON_HALF_PERIODS = 40.0


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


@dataclass(frozen=True)
class Tolerances:
    """Integrator tolerances (relative and absolute) of a return map."""

    rtol: float = 1e-10
    atol: float = 1e-10


@dataclass(frozen=True)
class Stride:
    """Outcome of one stride: the next apex, or the reason the runner fell."""

    apex: np.ndarray | None  # next apex X [z m, theta_h rad, ydot m/s, theta_h_dot rad/s]
    durations: dict[str, float]  # phase -> duration [s]; phases not reached are absent
    fall: Fall | None = None

    @property
    def ok(self) -> bool:
        return self.fall is None


@dataclass(frozen=True)
class Simulation:
    """Apex sequence of a multi-stride run; ``fall`` is set if it ended early."""

    apexes: np.ndarray  # (n + 1) x 4, the initial apex first
    durations: list[dict[str, float]] = field(default_factory=list)
    fall: Fall | None = None
    fall_stride: int | None = None  # 0-based index of the stride that fell


def _stance_run_dynamics(s, u, p):
    """Right-hand side of the augmented stance state, with time scaled by the horizon."""
    x = s[: STANCE.size]
    phase = STANCE_RUN.get(s, "phase")
    moving = phase < 1.5
    xdot = stance_dynamics(x, hip_torque(x, u), p)
    return ca.if_else(moving, ca.vertcat(xdot, 1, 0, 0), ca.DM.zeros(STANCE_RUN.size))


def _stance_run_indicators(s, p):
    """Zero-crossing indicators in :data:`EVENTS` order; inactive ones held at +1."""
    x = s[: STANCE.size]
    phase = STANCE_RUN.get(s, "phase")
    in_compression = phase < 0.5
    in_stance = phase < 1.5
    in_decompression = ca.logic_and(in_stance, ca.logic_not(in_compression))
    q = x[:3]
    rho_floor = COLLAPSE_FRACTION * PARAMS.get(p, "rho0")
    return ca.vertcat(
        ca.if_else(in_compression, -bottom_guard(x), 1),
        ca.if_else(in_decompression, -liftoff_guard(x, p), 1),
        ca.if_else(in_stance, stance_com_position(q, p)[1], 1),
        ca.if_else(in_stance, stance_hip_position(q)[1], 1),
        ca.if_else(in_stance, STANCE.get(x, "rho") - rho_floor, 1),
    )


def _stance_run_transition():
    """Event transition: advance or freeze the phase flag, record the bottom time."""
    index = ca.SX.sym("index")
    t = ca.SX.sym("t")
    s = STANCE_RUN.sym("s")
    u_and_p = ca.SX.sym("up", CONTROL.size + PARAMS.size + 1)
    empty = ca.SX(0, 1)
    clock = STANCE_RUN.get(s, "clock")
    after_bottom = ca.vertcat(s[: STANCE.size], clock, clock, DECOMPRESSION)
    frozen = [ca.vertcat(s[: STANCE_RUN.size - 1], flag) for flag in (LIFTED_OFF, 3.0, 4.0, 5.0)]
    post = ca.conditional(index, [after_bottom] + frozen, s)
    return ca.Function(
        "stance_transition", [index, t, s, empty, u_and_p, empty], [post, empty],
        ca.event_in(), ca.event_out(),
    )


class ReturnMap:
    """The apex return map of the BA-SLIP under the PD hip law, built once per tolerance.

    >>> rmap = ReturnMap()
    >>> stride = rmap.stride(X, u, Params())     # numeric, with fall detection
    >>> A, B = rmap.jacobians(X, u, Params())    # dr/dX (4x4) and dr/du (4x5)
    >>> A2, B2 = rmap.jacobians(X, u, Params(), strides=2)   # of r(r(X, u), u)
    """

    def __init__(self, tolerances: Tolerances = Tolerances(), plugin: str = "erk"):
        self.tolerances = tolerances
        self.plugin = plugin
        self._samplers: dict = {}  # functions needed only by some users, built on first use
        with _event_notice_silenced():
            self._touchdown_time = self._build_touchdown_rootfinder()
            self._stance = self._build_stance_integrator()
            self._stride_fn = self._build_stride_function()
            X, u, p, t_guess = self._stride_fn.mx_in()
            apex_next = self._stride_fn(X, u, p, t_guess)[0]
            # One Jacobian in (X, u) together: one sensitivity sweep instead of two.
            self._jacobian_fn = ca.Function(
                "return_map_jacobian",
                [X, u, p, t_guess],
                [ca.jacobian(apex_next, ca.vertcat(X, u)), *self._stride_fn(X, u, p, t_guess)],
                ["X", "u", "p", "t_touchdown_guess"],
                ["dr_dXu", "apex", "durations", "diagnostics"],
            )

    # -- construction ------------------------------------------------------------------

    def _build_touchdown_rootfinder(self) -> ca.Function:
        t = ca.SX.sym("t")
        X, u, p = APEX.sym("X"), CONTROL.sym("u"), PARAMS.sym("p")
        foot_height = touchdown_guard(ballistic_flight(apex_to_flight(X), t, p), touchdown_angle(u), p)
        residual = ca.Function("touchdown_residual", [t, ca.vertcat(X, u, p)], [foot_height])
        return ca.rootfinder(
            "touchdown_time", "newton", residual,
            {"abstol": 1e-15, "abstolStep": 1e-16, "max_iter": 50, "error_on_fail": False},
        )

    def _build_stance_integrator(self, output_times=(1.0,)) -> ca.Function:
        """Stance over the time-scaled horizon [0, 1], with outputs at ``output_times``."""
        s = STANCE_RUN.sym("s")
        u, p, horizon = CONTROL.sym("u"), PARAMS.sym("p"), ca.SX.sym("horizon")
        dae = {
            "x": s,
            "p": ca.vertcat(u, p, horizon),
            "ode": horizon * _stance_run_dynamics(s, u, p),
            "zero": _stance_run_indicators(s, p),
        }
        opts = {
            "transition": _stance_run_transition(),
            "reltol": self.tolerances.rtol,
            "abstol": self.tolerances.atol,
            "max_events": 8,
            "max_num_steps": 100000,
        }
        return ca.integrator("stance", self.plugin, dae, 0.0, list(output_times), opts)

    def _build_stride_function(self) -> ca.Function:
        X, u, p = APEX.sym("X", ca.MX), CONTROL.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
        t_guess = ca.MX.sym("t_touchdown_guess")
        theta_td = touchdown_angle(u)
        t_descent = self._touchdown_time(t_guess, ca.vertcat(X, u, p))
        at_touchdown = ballistic_flight(apex_to_flight(X), t_descent, p)
        x_td = touchdown_map(at_touchdown, theta_td, p)
        horizon = STANCE_HORIZON_HALF_PERIODS * math.pi * ca.sqrt(PARAMS.get(p, "m") / PARAMS.get(p, "k"))
        s0 = ca.vertcat(x_td, 0, 0, COMPRESSION)
        s_end = self._stance(x0=s0, p=ca.vertcat(u, p, horizon))["xf"]
        x_lo = s_end[: STANCE.size]
        at_liftoff = liftoff_map(x_lo, p)
        apex_next = flight_to_apex(at_liftoff, p)
        t_stance, t_bottom = STANCE_RUN.get(s_end, "clock"), STANCE_RUN.get(s_end, "t_bottom")
        zdot_lo = FLIGHT.get(at_liftoff, "zdot")
        durations = ca.vertcat(t_descent, t_bottom, t_stance - t_bottom, zdot_lo / PARAMS.get(p, "g"))
        diagnostics = ca.vertcat(
            STANCE_RUN.get(s_end, "phase"), bottom_guard(x_td), zdot_lo,
            touchdown_guard(at_touchdown, theta_td, p), FLIGHT.get(at_touchdown, "z"),
        )
        return ca.Function(
            "stride", [X, u, p, t_guess], [apex_next, durations, diagnostics],
            ["X", "u", "p", "t_touchdown_guess"], ["apex", "durations", "diagnostics"],
        )

    # -- numeric use -------------------------------------------------------------------

    @staticmethod
    def touchdown_guess(X, u, p) -> float | None:
        """First zero of the foot height after apex, bracketed then bisected [s].

        Returns None when the foot cannot reach the ground. The foot height is
        h(t) = c - g t^2/2 - d sin(theta_h + w t) with c = z - rho0 cos(theta_td), so
        h < 0 for all t > sqrt(2 (c + d) / g): the first root lies in that bracket. The
        rootfinder then converges on it from this guess.
        """
        a, pr = APEX.unpack(X), PARAMS.unpack(p)
        theta_td = CONTROL.get(u, "theta_td")
        if not abs(theta_td) < math.pi / 2:
            return None

        def height(t):
            return descent_foot_height(
                t, a["z"], a["theta_h"], a["theta_h_dot"], theta_td, pr["d"], pr["rho0"], pr["g"]
            )

        clearance = a["z"] - pr["rho0"] * math.cos(theta_td)
        t_max = math.sqrt(2.0 * max(clearance + pr["d"], 0.0) / pr["g"]) + 1e-9
        grid = np.linspace(0.0, t_max, 257)
        below = np.nonzero(height(grid[1:]) <= 0.0)[0]
        if len(below) == 0:
            return None
        lo, hi = grid[below[0]], grid[below[0] + 1]
        while hi - lo > 1e-15 * hi:  # to round-off: the rootfinder then only confirms it
            mid = 0.5 * (lo + hi)
            if not lo < mid < hi:
                break
            lo, hi = (mid, hi) if height(mid) > 0 else (lo, mid)
        return 0.5 * (lo + hi)

    def _start(self, X, u, p) -> tuple[Stride | None, float | None]:
        """Checks before any integration: a fall found already, or the touchdown guess."""
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(u)) and np.all(np.isfinite(p))):
            return Stride(None, {}, Fall.NOT_FINITE), None
        a, pr = APEX.unpack(X), PARAMS.unpack(p)
        theta_td = CONTROL.get(u, "theta_td")
        if descent_foot_height(0.0, a["z"], a["theta_h"], 0.0, theta_td, pr["d"], pr["rho0"], pr["g"]) < 0.0:
            return Stride(None, {}, Fall.FOOT_BELOW_GROUND), None
        t_guess = self.touchdown_guess(X, u, p)
        if t_guess is None:
            return Stride(None, {}, Fall.NO_TOUCHDOWN), None
        return None, t_guess

    def stride(self, X, u, params) -> Stride:
        """One apex-to-apex stride from apex ``X`` under control ``u`` with ``params``."""
        X, u, p = _vec(X), _vec(u), _param_vector(params)
        fallen, t_guess = self._start(X, u, p)
        if fallen is not None:
            return fallen
        try:
            outputs = self._stride_fn(X, u, p, t_guess)
        except RuntimeError:  # CasADi reports an integrator or rootfinder failure
            return Stride(None, {}, Fall.INTEGRATION_FAILED)
        return _outcome(*(np.asarray(v).ravel() for v in outputs))

    def __call__(self, X, u, params) -> np.ndarray:
        """r(X, u): the next apex; raises :class:`RunnerFell` if the stride falls."""
        result = self.stride(X, u, params)
        if result.fall is not None:
            raise RunnerFell(result.fall)
        return result.apex

    def jacobians(self, X, u, params, strides: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """(dr/dX, dr/du) by algorithmic differentiation through the event times.

        With ``strides = n`` these are the Jacobians of the n-stride map r^n (the same
        control every stride), by the chain rule: dr^n/dX is the product of the strides'
        dr/dX. Raises :class:`RunnerFell` if a stride falls: there is no Jacobian then.
        """
        dX, du, _ = self._chained_jacobians(X, u, params, strides, with_parameters=False)
        return dX, du

    def parameter_jacobian(self, X, u, params, strides: int = 1) -> np.ndarray:
        """dr^n/dp (4 x 6) with respect to the model parameters (m, I, k, rho0, d, g)."""
        return self.all_jacobians(X, u, params, strides)[2]

    def all_jacobians(self, X, u, params, strides: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dr^n/dX, dr^n/du, dr^n/dp) from one pass over the strides."""
        return self._chained_jacobians(X, u, params, strides, with_parameters=True)

    def _chained_jacobians(self, X, u, params, strides: int, with_parameters: bool):
        """Jacobians of r^n in (X, u), and in p if asked, accumulated stride by stride."""
        X, u, p = _vec(X), _vec(u), _param_vector(params)
        dX, du = np.eye(APEX.size), np.zeros((APEX.size, CONTROL.size))
        dp = np.zeros((APEX.size, PARAMS.size))
        for _ in range(strides):
            t_guess = self._touchdown_guess_or_fall(X, u, p)
            step_X, step_u, apex_next = self._stride_jacobians(X, u, p, t_guess)
            if with_parameters:
                dp = step_X @ dp + self._stride_parameter_jacobian(X, u, p, t_guess)
            dX, du = step_X @ dX, step_X @ du + step_u
            X = apex_next
        return dX, du, dp if with_parameters else None

    def _touchdown_guess_or_fall(self, X, u, p) -> float:
        fallen, t_guess = self._start(X, u, p)
        if fallen is not None:
            raise RunnerFell(fallen.fall)
        return t_guess

    def _stride_jacobians(self, X, u, p, t_guess) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One stride's dr/dX, dr/du and next apex."""
        try:
            jac, *outputs = self._jacobian_fn(X, u, p, t_guess)
        except RuntimeError:
            raise RunnerFell(Fall.INTEGRATION_FAILED) from None
        outcome = _outcome(*(np.asarray(v).ravel() for v in outputs))
        if outcome.fall is not None:
            raise RunnerFell(outcome.fall)
        jac = np.asarray(jac)
        return jac[:, : APEX.size], jac[:, APEX.size :], outcome.apex

    def _stride_parameter_jacobian(self, X, u, p, t_guess) -> np.ndarray:
        """One stride's dr/dp; its function is built on first use."""
        if "parameter_jacobian" not in self._samplers:
            Xs, us, ps, tg = self._stride_fn.mx_in()
            with _event_notice_silenced():
                self._samplers["parameter_jacobian"] = ca.Function(
                    "return_map_parameter_jacobian", [Xs, us, ps, tg],
                    [ca.jacobian(self._stride_fn(Xs, us, ps, tg)[0], ps)],
                )
        try:
            return np.asarray(self._samplers["parameter_jacobian"](X, u, p, t_guess))
        except RuntimeError:
            raise RunnerFell(Fall.INTEGRATION_FAILED) from None

    def stance_samples(self, x_touchdown, u, params, duration: float, n: int) -> np.ndarray:
        """Stance states (6 x n) at n equal steps up to ``duration`` [s] after touchdown,
        for drawing; ``duration`` is normally the stride's stance time."""
        key = ("stance_samples", n)
        if key not in self._samplers:
            with _event_notice_silenced():
                self._samplers[key] = self._build_stance_integrator(np.linspace(0.0, 1.0, n + 1)[1:])
        s0 = np.concatenate([_vec(x_touchdown), [0.0, 0.0, COMPRESSION]])
        p = np.concatenate([_vec(u), _param_vector(params), [duration]])
        return np.asarray(self._samplers[key](x0=s0, p=p)["xf"])[: STANCE.size, :]

    def simulate(self, X0, u, params, strides: int) -> Simulation:
        """Apply ``u`` for up to ``strides`` strides from apex ``X0``."""
        apexes, durations = [_vec(X0)], []
        for n in range(strides):
            result = self.stride(apexes[-1], u, params)
            if result.fall is not None:
                return Simulation(np.array(apexes), durations, result.fall, n)
            apexes.append(result.apex)
            durations.append(result.durations)
        return Simulation(np.array(apexes), durations)


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


class RunnerFell(RuntimeError):
    """Raised by :meth:`ReturnMap.__call__` when a stride falls; carries the :class:`Fall`."""

    def __init__(self, fall: Fall):
        super().__init__(fall.value)
        self.fall = fall


@contextlib.contextmanager
def _event_notice_silenced():
    """Silence CasADi's 'Event support is experimental' notice while building integrators.

    CasADi 3.8 prints it (through Python's sys.stderr) for every integrator with events;
    the event handling is what we rely on and test, so the notice is only noise to users.
    Errors still surface as Python exceptions.
    """
    with contextlib.redirect_stderr(io.StringIO()):
        yield


def _vec(v) -> np.ndarray:
    return np.asarray(v, dtype=float).ravel()


def _param_vector(params) -> np.ndarray:
    return params.vector() if hasattr(params, "vector") else _vec(params)
