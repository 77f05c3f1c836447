"""The compiled stride engine: one apex-to-apex stride of the BA-SLIP as fixed-step
order-8 flows, generated as C and cached on disk.

How a stride is computed:

1. **Descent** is closed form; the touchdown time comes from the bracketed first root of
   the foot height (:func:`touchdown_guess`), refined by Newton inside the graph.
2. **Scout.** Stance is stepped with DOP853 at a step size set by the stiffness, in chunks
   of :data:`SCOUT_STEPS` steps, until ``rho`` passes ``rho0`` after the bottom. The
   nodes bracket the bottom (``rhodot`` rising through 0) and the liftoff
   (``rho - rho0`` rising through 0), and cubic Hermite interpolation estimates both
   times. Ground contact of the CoM or hip and a collapsing leg are seen at every stage
   point of every step, so a crossing between nodes is not missed. Where one call covers
   the stance cleanly, this search is compiled too (:func:`scout_events`, in
   ``stance_plan`` with the touchdown state); the driver's careful path handles the rest.
3. **Final pass**, a fixed-structure function per step count ``N`` (:data:`TIERS`):
   compression and decompression each take ``N - 1`` equal steps of a grid set by the
   scout's estimate, then a last step whose size solves the guard by Newton. Derivatives
   of this function are algorithmic derivatives of the discrete flow, through the event
   times by the implicit-function theorem.
4. **Checks** (the driver, :mod:`baslip.engine.driver`). A pass is accepted when its own summed
   DOP853 error estimate, or the Richardson estimate from a pass at a lower ``N``, is
   within the tolerance; otherwise a larger ``N`` is tried, and past the last one the
   stride reports that it cannot guarantee its accuracy (the caller falls back to the
   adaptive event map). Only counts with ``h * lambda`` small enough are tried, where
   ``lambda`` is the fastest rate of the stance dynamics (spring, hip damping and
   stiffness, spin).

All inputs and outputs are SI units and radians.
"""

from __future__ import annotations

import functools
import math
import pathlib
import sys

import casadi as ca
import numpy as np

from baslip.engine import codegen as _codegen
from baslip.engine import dop853 as flow
from baslip.engine import outcome as _outcome_module
from baslip.engine.background import KernelsLater
from baslip.engine.codegen import compile_kernels, compiling, library_name, module_files
from baslip.engine.native import Kernel, VirtualMachineKernel
from baslip.engine.physics import Physics, physics_modules
from baslip.engine.setuptime import setting_up
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

#: Step counts per stance phase of the compiled final pass, 1.5 apart up to 256: the
#: error scales as N^-8, so each count is 10 to 25 times more accurate than the one
#: before, and a stride is not pushed to twice the steps it needs (as with counts 2
#: apart). The few stiff strides beyond 256 steps double.
TIERS = (16, 24, 32, 48, 64, 96, 128, 192, 256, 512, 1024)
#: Stance steps per scout call.
SCOUT_STEPS = 24
#: Strides per call of the batched functions.
BATCH = 32
#: Newton iterations of each stance event step, and of the touchdown time.
EVENT_NEWTON = 3
TOUCHDOWN_NEWTON = 2
#: Newton iterations on the cubic Hermite interpolant of an event guard between two nodes.
HERMITE_NEWTON = 8

#: Watched quantities in stance, a fall when one reaches zero: CoM height, hip height and
#: the leg's length above the collapse floor [m].
CLEARANCES = ("com", "hip", "leg")
#: Guess inputs of the final pass [s]: descent, and the grid durations of the two phases.
GUESSES = Layout(("descent", "compression", "decompression"))
#: Scalar outputs of the final pass that decide whether and how it fell and whether it is
#: accurate; see :func:`_final_pass`.
DIAGNOSTICS = Layout((
    "rhodot_td", "zdot_lo", "foot_height_td", "com_height_td",
    "bottom_residual", "liftoff_residual", "bottom_update", "liftoff_update",
    "bottom_last_step", "liftoff_last_step",
    "rhodot_max_compression", "stretch_max_decompression",
    "com_min", "hip_min", "leg_min", "error",
))


def theta_layout(law: HipLaw) -> Layout:
    """Parameters of the stance flow under ``law``: its controls, then the model's."""
    return Layout(law.controls.names + PARAMS.names)


def _split_theta(theta, law: HipLaw):
    """(u, p) of a flow parameter vector ``theta`` = (u, p) under ``law``."""
    return theta[:law.controls.size], theta[law.controls.size:]


def stance_rhs(physics: Physics) -> ca.Function:
    """xdot = f(x, theta) of stance under ``physics``'s hip law, theta = (u, p): the BA-SLIP
    description's."""
    x, theta = STANCE.sym("x"), theta_layout(physics.law).sym("theta")
    xdot = physics.stance_rate(x, *_split_theta(theta, physics.law))
    return ca.Function("stance_rhs", [x, theta], [ca.cse(xdot)], ["x", "theta"], ["xdot"])


def stance_clearances(physics: Physics) -> ca.Function:
    """(x, theta) -> (CoM height, hip height, rho - collapse floor) [m] under ``physics``'s
    hip law; the runner falls at zero."""
    x, theta = STANCE.sym("x"), theta_layout(physics.law).sym("theta")
    clearances = physics.clearances(x, *_split_theta(theta, physics.law))
    return ca.Function("stance_clearances", [x, theta], [clearances], ["x", "theta"], ["clearances"])


def stance_guards(physics: Physics) -> tuple[ca.Function, ca.Function]:
    """The bottom guard rhodot [m/s] and the liftoff guard rho - rho0 [m] as Functions of
    (x, theta); each rises through zero at its event."""
    x, theta = STANCE.sym("x"), theta_layout(physics.law).sym("theta")
    u, p = _split_theta(theta, physics.law)
    return (
        ca.Function("bottom", [x, theta], [physics.guard("bottom", x, u, p)]),
        ca.Function("liftoff", [x, theta], [physics.guard("liftoff", x, u, p)]),
    )


def stiffness_rate(X, u, p, law: HipLaw = PD):
    """The fastest rate of the stance dynamics [1/s], for the step size: a number for one
    apex ``X`` and control ``u``, an array for rows of many.

    The larger of the spring's sqrt(k/m), the hip damping c/(I + m d^2), the hip
    stiffness sqrt(kappa/(I + m d^2)) (``kappa`` and ``c`` from the law's
    :meth:`~baslip.model.hiplaw.HipLaw.step_rates`; |Kp| and |Kd| under PD), the trunk
    spin |theta_h_dot| and the leg's sweep rate |ydot|/rho0 (``I + m d^2`` is the
    trunk's inertia about the hip).
    """
    m, inertia, k, rho0, d = (float(p[i]) for i in _RATE_PARAMS)
    inertia_hip = inertia + m * d**2
    hip_stiffness, hip_damping = law.step_rates(u, p)
    X = np.asarray(X, dtype=float).T  # entries first
    rates = (
        math.sqrt(k / m),
        hip_damping / inertia_hip,
        (hip_stiffness / inertia_hip) ** 0.5,
        abs(X[_SPIN]),
        abs(X[_YDOT]) / rho0,
    )
    if X.ndim == 1:
        return float(max(rates))
    return functools.reduce(np.maximum, rates)


_RATE_PARAMS = tuple(PARAMS.index(n) for n in ("m", "I", "k", "rho0", "d"))
_M, _K = PARAMS.index("m"), PARAMS.index("k")
_SPIN, _YDOT = APEX.index("theta_h_dot"), APEX.index("ydot")


def half_period(p) -> float:
    """The spring's half-period pi sqrt(m/k) [s]."""
    return math.pi * math.sqrt(float(p[_M]) / float(p[_K]))


class StanceFlow:
    """The symbolic stance flow of the runner under one hip law, built once: the
    right-hand side, one DOP853 step, loops of steps, and the steps that end on the bottom
    and liftoff guards. The compiled stride and the shooting NLP are both built from it."""

    def __init__(self, law: HipLaw = PD):
        self.law = law
        self.theta = theta_layout(law)
        self.physics = Physics.of(law)
        self.rhs = stance_rhs(self.physics)
        self.clearances = stance_clearances(self.physics)
        self.step = flow.step_function(self.rhs, self.clearances)
        bottom, liftoff = stance_guards(self.physics)
        self.bottom_step = flow.event_step(self.step, self.rhs, bottom, EVENT_NEWTON)
        self.liftoff_step = flow.event_step(self.step, self.rhs, liftoff, EVENT_NEWTON)
        self._chains: dict[int, ca.Function] = {}

    def chain(self, n: int) -> ca.Function:
        """``n`` stance steps (x0, h, theta) -> (nodes, errors, clearance minima), one
        Function per ``n`` so generated code holds it once."""
        if n not in self._chains:
            self._chains[n] = flow.chain(self.step, n)
        return self._chains[n]


#: gcc's optimisation level of the Jacobians' library. Measured on the 2-core machine: its
#: 2.84 MB of C take 21.7 s at -O1 against 38.9 s at -O3, and the Jacobian at the
#: hanging gait 1.299 ms against 1.262 ms (best of 5 runs of 200, both in one process):
#: 3 % slower, for a first run that no longer waits for the longest compile.
JACOBIAN_OPTIMISATION = "-O1"
#: gcc's optimisation level of the second derivatives' library. Measured on the 2-core
#: machine with the Hessian-vector products alone (3.96 MB of C): 28.6 s at -O1 against
#: 37.3 s at -O3, and a product at a gait of curve_downward_boundary 4.17 ms against
#: 3.90 ms (one process, 100 calls each): 7 % slower, for a compile that a run waits for.
#: With the seeded Jacobian gradients the library takes 76 s at -O1 (PD), once for every
#: step count, where the descent compiled a library of about 70 s for each one it met.
#: (Blocks of four directions in forward over reverse mode cost half as much a direction,
#: but tripled the products' compile and saved a fifth of a nearest-guess curve's time.)
HESSIAN_OPTIMISATION = "-O1"
#: Threads that share a batch of Hessian-vector products, each with its own copy of the
#: kernels (a kernel's work memory serves one call at a time); one in the virtual machine.
HESSIAN_LANES = 2


class StrideFunctions:
    """The Functions of the compiled stride, built and compiled once: the planning call
    (touchdown state, one scout call and its events), the stance scout alone (for the
    careful path) and, per tier, the final pass and its Jacobian in (X, u, p); the
    planning and the final passes also mapped over :data:`BATCH` strides.

    ``law``: the hip law; each law has its own libraries, named after it.
    ``compile``: True or False forces the C route on or off; None follows the
    environment (see :func:`baslip.engine.codegen.compile_functions`), as does
    :data:`~baslip.engine.codegen.FEW_CALLS`, for a run that calls the engine a few times.

    The Jacobians are a library of their own, compiled at :data:`JACOBIAN_OPTIMISATION`
    and, on a first run, in a thread while the process goes on (a solve first asks for
    them after IPOPT has run): they are most of the engine's C. Where they run in the
    virtual machine instead, each step count's Jacobian is built on first use."""

    def __init__(self, law: HipLaw = PD, compile: bool | str | None = None):
        self.law = law
        # The Jacobians first, so that their compile (the longest) starts at once.
        self._jacobians = KernelsLater(library_name("baslip_stride_jacobians", law), _jacobian_names(),
                                       self._all_jacobians, sources(), optimisation=JACOBIAN_OPTIMISATION,
                                       enabled=compile)
        self._virtual_jacobians: dict[int, Kernel] = {}
        self.functions = compile_kernels(library_name("baslip_stride", law), _names(), self._passes, sources(),
                                         enabled=compile)
        self.scout = self.functions["stance_scout"]
        self.plan = self.functions["stance_plan"]
        self._compile = compile

    @functools.cached_property
    def flow(self) -> StanceFlow:
        """The symbolic stance flow the functions are built from (not built where the cache
        holds them)."""
        return StanceFlow(self.law)

    def final(self, n: int) -> Kernel:
        """(X, u, p, guesses) -> (apex, durations, diagnostics) with ``n`` steps a phase."""
        return self.functions[f"stride_{n}"]

    def jacobian(self, n: int) -> Kernel:
        """(X, u, p, guesses) -> (dr/d(X, u, p) 4 x (4 + controls + 6), apex, durations, diagnostics)."""
        compiled = self._jacobians.get()
        if compiled is not None:
            return compiled[f"stride_jacobian_{n}"]
        if n not in self._virtual_jacobians:  # this step count's alone, in the virtual machine
            with setting_up():
                self._virtual_jacobians[n] = VirtualMachineKernel(self._jacobian(_final_pass(self.flow, n)))
        return self._virtual_jacobians[n]

    def hessian_vector(self, n: int, lane: int = 0) -> Kernel:
        """(X, u, p, guesses, w, s) -> H s, with H the Hessian of w . apex in (X, u, p):
        second derivatives of the final pass of ``n`` steps a phase, the copy of thread
        ``lane`` (below :attr:`hessian_lanes`). Their library is compiled on first use
        (about 80 s on a first run, then cached): only runs that ask for exact second
        derivatives (curves, nearest-guess branches, the optimal search) wait for it."""
        return self._hessians[lane][f"hessian_vector_{n}"]

    def jacobian_gradient(self, n: int) -> Kernel:
        """(X, u, p, guesses, G) -> the gradient in (X, u, p) of sum(G * d apex/dX), G 4 x 4:
        second derivatives of the final pass of ``n`` steps a phase (the library of
        :meth:`hessian_vector`, lane 0)."""
        return self._hessians[0][f"jacobian_gradient_{n}"]

    @property
    def hessian_lanes(self) -> int:
        """How many threads may call :meth:`hessian_vector` at once, one per lane."""
        return len(self._hessians)

    @functools.cached_property
    def _hessians(self) -> list[dict[str, Kernel]]:
        lanes = HESSIAN_LANES if compiling(self._compile) else 1
        return [compile_kernels(library_name("baslip_stride_hessians", self.law), _hessian_names(),
                                self._all_second_derivatives, sources(), optimisation=HESSIAN_OPTIMISATION,
                                enabled=self._compile) for _ in range(lanes)]

    def _all_second_derivatives(self) -> list[ca.Function]:
        """Every tier's Hessian-vector product and seeded Jacobian gradient, in the order
        of :func:`_hessian_names`."""
        return [kernel(f) for kernel in (hessian_vector_function, jacobian_gradient_function) for f in self._finals]

    def _scout(self) -> ca.Function:
        """(x0, h, theta) -> the M + 1 nodes from x0 (columns), their rates xdot, and each
        step's least clearances and error estimate (M columns); M = :data:`SCOUT_STEPS`."""
        chained = self.flow.chain(SCOUT_STEPS)
        x0, h, theta = ca.MX.sym("x0", STANCE.size), ca.MX.sym("h"), self.flow.theta.sym("theta", ca.MX)
        steps, errors, clearances = chained(x0, h, theta)
        nodes = ca.horzcat(x0, steps)
        rates = self.flow.rhs.map(SCOUT_STEPS + 1)(nodes, ca.repmat(theta, 1, SCOUT_STEPS + 1))
        return ca.Function("stance_scout", [x0, h, theta], [nodes, rates, clearances, errors],
                           ["x0", "h", "theta"], ["nodes", "rates", "clearance_min", "error"])

    def _plan(self, scout: ca.Function) -> ca.Function:
        """(X, u, p, t_descent, h) -> the stance state at touchdown, the CoM height there [m],
        and the events of one scout call from there with step ``h`` [s] (see
        :func:`scout_events`): the common case of a stride's planning in one call."""
        X, u, p = APEX.sym("X", ca.MX), self.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
        t_descent, h = ca.MX.sym("t_descent"), ca.MX.sym("h")
        x_td, com_height, _ = touchdown_state(self.flow.physics)(X, u, p, t_descent)
        nodes, rates, clearance, errors = scout(x_td, h, ca.vertcat(u, p))
        events = scout_events()(nodes, rates, clearance, errors, h, PARAMS.get(p, "rho0"))
        return ca.Function("stance_plan", [X, u, p, t_descent, h], [x_td, com_height, *events],
                           ["X", "u", "p", "t_descent", "h"],
                           ["x_touchdown", "com_height", "clean", "bottom", "liftoff", "error"])

    def _jacobian(self, final: ca.Function) -> ca.Function:
        """The final pass's Jacobian of the apex in (X, u, p), with its ordinary outputs."""
        X, u, p, guesses = final.mx_in()
        apex, durations, diagnostics = final(X, u, p, guesses)
        return ca.Function(
            final.name().replace("stride", "stride_jacobian"), [X, u, p, guesses],
            [ca.jacobian(apex, ca.vertcat(X, u, p)), apex, durations, diagnostics],
            ["X", "u", "p", "guesses"], ["dr_dXup", "apex", "durations", "diagnostics"],
        )

    def _passes(self) -> list[ca.Function]:
        """The engine's Functions but the Jacobians, compiled together so that the step is
        generated once for all tiers."""
        finals = self._finals
        scout = self._scout()
        batched = [self._plan(scout), *finals]  # the batch path plans and runs final passes
        batches = [f.map(f"batch_{f.name()}", "serial", BATCH, [], [], {}) for f in batched]
        return [scout, *batched, *batches]

    def _all_jacobians(self) -> list[ca.Function]:
        """The final passes' Jacobians, every tier, compiled together (their library)."""
        return [self._jacobian(f) for f in self._finals]

    @functools.cached_property
    def _finals(self) -> list[ca.Function]:
        """The final pass of every tier, built once for both libraries (on a first run)."""
        return [_final_pass(self.flow, n) for n in TIERS]

    def batch(self, name: str) -> Kernel:
        """The function ``name`` mapped over :data:`BATCH` columns (one stride each)."""
        return self.functions[f"batch_{name}"]


def _phase(stance: StanceFlow, event: ca.Function, x0, grid_duration, theta, n: int):
    """A stance phase of ``n`` steps: ``n - 1`` on the grid ``grid_duration / n``, then the
    step that ends on the event. Returns (duration, end state, event outputs, node values)."""
    h = grid_duration / n
    nodes, errors, clearances = stance.chain(n - 1)(x0, h, theta)
    x_last = nodes[:, -1]
    s, x_end, residual, update, error, clearance_end = event(x_last, h, theta)
    duration = (n - 1) * h + s
    return dict(
        duration=duration, x_end=x_end, residual=residual, update=update, last_step=s / h,
        nodes=nodes, error=ca.sum2(errors) + error,
        clearance=ca.vertcat(*[ca.mmin(ca.horzcat(clearances[i, :], clearance_end[i])) for i in range(len(CLEARANCES))]),
    )


def _final_pass(stance: StanceFlow, n: int) -> ca.Function:
    """(X, u, p, guesses) -> (next apex, durations, diagnostics) with ``n`` steps a phase."""
    X, u, p = APEX.sym("X", ca.MX), stance.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
    guesses = GUESSES.sym("guesses", ca.MX)
    theta = ca.vertcat(u, p)
    physics = stance.physics

    t_descent = _touchdown_time(X, u, p, GUESSES.get(guesses, "descent"), physics)
    at_touchdown = physics.flight(apex_to_flight(X), t_descent, u, p)
    x_td = physics.reset("touchdown", at_touchdown, u, p)

    comp = _phase(stance, stance.bottom_step, x_td, GUESSES.get(guesses, "compression"), theta, n)
    decomp = _phase(stance, stance.liftoff_step, comp["x_end"], GUESSES.get(guesses, "decompression"), theta, n)

    at_liftoff = physics.reset("liftoff", decomp["x_end"], u, p)
    zdot_lo = FLIGHT.get(at_liftoff, "zdot")
    apex_next = flight_to_apex(at_liftoff, p)
    durations = ca.vertcat(t_descent, comp["duration"], decomp["duration"], zdot_lo / PARAMS.get(p, "g"))
    clearance = ca.fmin(comp["clearance"], decomp["clearance"])
    diagnostics = DIAGNOSTICS.pack({
        "rhodot_td": physics.guard("bottom", x_td, u, p),
        "zdot_lo": zdot_lo,
        "foot_height_td": physics.guard("touchdown", at_touchdown, u, p),
        "com_height_td": FLIGHT.get(at_touchdown, "z"),
        "bottom_residual": comp["residual"],
        "liftoff_residual": decomp["residual"],
        "bottom_update": comp["update"],
        "liftoff_update": decomp["update"],
        "bottom_last_step": comp["last_step"],
        "liftoff_last_step": decomp["last_step"],
        "rhodot_max_compression": ca.mmax(STANCE.get(comp["nodes"], "rhodot")),
        "stretch_max_decompression": ca.mmax(STANCE.get(decomp["nodes"], "rho")) - PARAMS.get(p, "rho0"),
        "com_min": clearance[0],
        "hip_min": clearance[1],
        "leg_min": clearance[2],
        "error": comp["error"] + decomp["error"],
    })
    return ca.Function(
        f"stride_{n}", [X, u, p, guesses], [apex_next, durations, diagnostics],
        ["X", "u", "p", "guesses"], ["apex", "durations", "diagnostics"],
    )


def hessian_vector_function(final: ca.Function) -> ca.Function:
    """(X, u, p, guesses, w, s) -> H s for the final pass ``final``, H the Hessian of the
    scalar w . apex in z = (X, u, p): the gradient of w . (d apex/dz s), reverse over
    forward mode. By H's symmetry, H s is also the gradient in z of w . (d apex/dz) s,
    the directional derivative of a Jacobian: one product gives a whole row of second
    derivatives. ``w`` has the apex's size, ``s`` that of z."""
    X, u, p, guesses = final.mx_in()
    z = ca.vertcat(X, u, p)
    w, s = ca.MX.sym("w", APEX.size), ca.MX.sym("s", z.shape[0])
    directional = ca.jtimes(final(X, u, p, guesses)[0], z, s)
    return ca.Function(final.name().replace("stride", "hessian_vector"), [X, u, p, guesses, w, s],
                       [ca.gradient(ca.dot(w, directional), z)], ["X", "u", "p", "guesses", "w", "s"], ["Hs"])


def jacobian_gradient_function(final: ca.Function) -> ca.Function:
    """(X, u, p, guesses, G) -> the gradient in z = (X, u, p) of sum(G * d apex/dX) for the
    final pass ``final``, G a 4 x 4 seed: the Jacobian's four forward directions, then one
    reverse sweep (the sensitivities of the multipliers, and of a curve's test function)."""
    X, u, p, guesses = final.mx_in()
    seed = ca.MX.sym("G", APEX.size, APEX.size)
    dr_dX = ca.jacobian(final(X, u, p, guesses)[0], X)
    return ca.Function(final.name().replace("stride", "jacobian_gradient"), [X, u, p, guesses, seed],
                       [ca.gradient(ca.dot(seed, dr_dX), ca.vertcat(X, u, p))],
                       ["X", "u", "p", "guesses", "G"], ["gradient"])


def _touchdown_time(X, u, p, t_guess, physics: Physics):
    """The touchdown time [s]: Newton on the closed-form foot height from a converged guess,
    so that its derivative is the implicit-function-theorem one."""
    t = ca.SX.sym("t")
    Xs, us, ps = APEX.sym("X"), physics.law.controls.sym("u"), PARAMS.sym("p")
    height = physics.guard("touchdown", physics.flight(apex_to_flight(Xs), t, us, ps), us, ps)
    newton = ca.Function("touchdown_newton", [Xs, us, ps, t], [t - height / ca.jacobian(height, t)])
    for _ in range(TOUCHDOWN_NEWTON):
        t_guess = newton(X, u, p, t_guess)
    return t_guess


def touchdown_state(physics: Physics) -> ca.Function:
    """(X, u, p, t_descent) -> stance state at touchdown, CoM height there [m], foot height
    there [m] (zero at a located touchdown), for a control ``u`` of ``physics``'s hip law."""
    X, u, p, t = APEX.sym("X"), physics.law.controls.sym("u"), PARAMS.sym("p"), ca.SX.sym("t_descent")
    at_touchdown = physics.flight(apex_to_flight(X), t, u, p)
    return ca.Function(
        "touchdown_state", [X, u, p, t],
        [physics.reset("touchdown", at_touchdown, u, p), FLIGHT.get(at_touchdown, "z"),
         physics.guard("touchdown", at_touchdown, u, p)],
        ["X", "u", "p", "t_descent"], ["x_touchdown", "com_height", "foot_height"],
    )


def hermite_root(t0, t1, g0, g1, dg0, dg1):
    """The root in [t0, t1] of the cubic Hermite interpolant of g (g0 < 0 <= g1) with rates
    dg: the secant's root, then Newton on the cubic, kept in [0, 1], stopped when its rate
    is not positive or its step below 1e-14. On SX this is built in the graph; the scalar
    driver (:func:`baslip.engine.driver.hermite_root`) does the same arithmetic in the same order."""
    span = t1 - t0
    m0, m1 = dg0 * span, dg1 * span
    s = g0 / (g0 - g1)
    active = ca.SX(1)
    for _ in range(HERMITE_NEWTON):
        s2, s3 = s * s, s * s * s
        value = (2 * s3 - 3 * s2 + 1) * g0 + (s3 - 2 * s2 + s) * m0 + (3 * s2 - 2 * s3) * g1 + (s3 - s2) * m1
        rate = 6 * (s2 - s) * (g0 - g1) + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1
        active = ca.logic_and(active, ca.logic_not(rate <= 0))
        step = value / rate
        s = ca.if_else(active, ca.fmin(ca.fmax(s - step, 0), 1), s)
        active = ca.logic_and(active, ca.logic_not(ca.fabs(step) < 1e-14))
    return t0 + span * s


def _first_rise(values: list) -> tuple[ca.SX, ca.SX]:
    """(whether some j >= 1 has values[j] >= 0 after values[j - 1] < 0, the first such j;
    1 where none)."""
    found, first = ca.SX(0), ca.SX(1)
    for j in range(len(values) - 1, 0, -1):
        rise = ca.logic_and(values[j] >= 0, values[j - 1] < 0)
        found, first = ca.logic_or(found, rise), ca.if_else(rise, j, first)
    return found, first


def _at(values: list, index: ca.SX) -> ca.SX:
    """values[index] for an integer-valued SX index, by selection (no arithmetic)."""
    picked = values[0]
    for j in range(1, len(values)):
        picked = ca.if_else(index == j, values[j], picked)
    return picked


def scout_events() -> ca.Function:
    """(nodes, rates, clearance_min, step_errors, h, rho0) of one scout call from touchdown ->
    (clean, bottom [s], liftoff [s], summed error estimate up to and with the liftoff step).

    The event search of the scalar scout (:meth:`baslip.engine.driver.CompiledEngine._scout`) for
    a stance that one call covers: ``clean`` (1 or 0) where every node is finite, the
    bottom (rhodot rising through 0) and then the liftoff (rho rising through rho0) are
    bracketed by nodes, and before the liftoff's step no clearance reaches zero and rho
    does not peak just below rho0 (a possible grazing liftoff). The others take the
    scalar scout's careful path."""
    m = SCOUT_STEPS
    nodes, rates = ca.SX.sym("nodes", STANCE.size, m + 1), ca.SX.sym("rates", STANCE.size, m + 1)
    clearance, errors = ca.SX.sym("clearance_min", len(CLEARANCES), m), ca.SX.sym("step_errors", 1, m)
    h, rho0 = ca.SX.sym("h"), ca.SX.sym("rho0")
    times = [h * k for k in range(m + 1)]
    rhodot = [STANCE.get(nodes[:, k], "rhodot") for k in range(m + 1)]
    rho_rate = [STANCE.get(rates[:, k], "rhodot") for k in range(m + 1)]
    has_bottom, j = _first_rise(rhodot)
    bottom = hermite_root(_at(times, j - 1), _at(times, j), _at(rhodot, j - 1), _at(rhodot, j),
                          _at(rho_rate, j - 1), _at(rho_rate, j))
    stretch = [ca.if_else(times[k] >= bottom, STANCE.get(nodes[:, k], "rho") - rho0, -1.0) for k in range(m + 1)]
    has_liftoff, k = _first_rise(stretch)
    liftoff = hermite_root(_at(times, k - 1), _at(times, k), _at(stretch, k - 1), _at(stretch, k),
                           _at(rhodot, k - 1), _at(rhodot, k))
    blocked = ca.SX(0)  # a clearance at zero or a grazing peak of rho in a step before liftoff's
    for i in range(m):
        peak = ca.logic_and(ca.logic_and(rhodot[i] > 0, rhodot[i + 1] <= 0), ca.logic_and(stretch[i] < 0, stretch[i + 1] < 0))
        reach = ca.fmax(stretch[i] + 0.5 * h * rhodot[i], stretch[i + 1] - 0.5 * h * rhodot[i + 1])
        fell = ca.logic_or(ca.logic_or(clearance[0, i] <= 0, clearance[1, i] <= 0), clearance[2, i] <= 0)
        hit = ca.logic_or(fell, ca.logic_and(peak, reach > 0))
        blocked = ca.logic_or(blocked, ca.logic_and(i < k - 1, hit))
    finite = ca.SX(1)
    for value in ca.vertsplit(ca.vec(ca.vertcat(nodes, rates))):
        finite = ca.logic_and(finite, ca.fabs(value) < ca.inf)
    summed = [errors[0]]
    for i in range(1, m):
        summed.append(summed[-1] + errors[i])  # in order, as numpy's cumsum
    clean = ca.logic_and(ca.logic_and(finite, ca.logic_and(has_bottom, has_liftoff)), ca.logic_not(blocked))
    return ca.Function(
        "scout_events", [nodes, rates, clearance, errors, h, rho0], [clean, bottom, liftoff, _at(summed, k - 1)],
        ["nodes", "rates", "clearance_min", "step_errors", "h", "rho0"], ["clean", "bottom", "liftoff", "error"],
    )


def _names() -> list[str]:
    """Names of the engine's functions but the Jacobians, in the order
    :meth:`StrideFunctions._passes` builds them."""
    batched = ["stance_plan", *(f"stride_{n}" for n in TIERS)]
    return ["stance_scout", *batched, *(f"batch_{name}" for name in batched)]


def _jacobian_names() -> list[str]:
    """Names of the final passes' Jacobians, in the order :meth:`StrideFunctions._all_jacobians`
    builds them."""
    return [f"stride_jacobian_{n}" for n in TIERS]


def _hessian_names() -> list[str]:
    """Names of the final passes' Hessian-vector products and seeded Jacobian gradients,
    one of each per tier."""
    return [f"{kind}_{n}" for kind in ("hessian_vector", "jacobian_gradient") for n in TIERS]


def sources() -> list[pathlib.Path]:
    """The modules the engine's functions are derived from: the compiled library's key."""
    return module_files(*physics_modules(), _outcome_module, flow, sys.modules[__name__], _codegen)
