"""The periodic-stride NLP: multiple shooting in stance, solved by IPOPT.

Decision variables (all in SI units and radians):

* the apex state ``X`` (4) and the control ``u`` (5); fixed quantities have equal bounds;
* the four phase durations ``T = (descent, compression, decompression, ascent)``;
* shooting-node states in compression and decompression, ``nodes`` intervals each, every
  interval integrated by ``substeps`` classical RK4 steps of length ``T_phase/(nodes*substeps)``.

Constraints:

* continuity at the nodes; the touchdown map at the start of stance;
* each guard zero at its phase end, with its crossing direction as an inequality
  (transversality, by ``margin``);
* periodicity ``r(X, u) = X``, or for an orbit of N strides ``r^N(X, u) = X`` with the
  intermediate apexes as variables; optionally the apex energy;
* sanity: the foot above ground through descent, the leg compressing in compression and
  compressed in decompression, ``rho`` above a floor, CoM and hip above ground, rising
  liftoff, durations bounded away from zero.

The objective picks one point on the fixed-point manifold (see :data:`OBJECTIVES`).
The NLP is built once per discretisation; parameters, guess, fixed values, bounds and the
objective's weights enter as numbers, so one built solver serves every problem.
"""

from __future__ import annotations

import contextlib
import io
import time
from dataclasses import dataclass, field
from typing import Mapping

import casadi as ca
import numpy as np

from .control import CONTROL, hip_torque, touchdown_angle
from .model import (
    APEX,
    FLIGHT,
    PARAMS,
    STANCE,
    Params,
    apex_energy,
    apex_to_flight,
    ballistic_flight,
    bottom_guard,
    liftoff_guard,
    liftoff_map,
    stance_com_position,
    stance_dynamics,
    stance_hip_position,
    touchdown_guard,
    touchdown_guard_rate,
    touchdown_map,
)
from .quantities import DEFAULT_BOUNDS, DESIGN, NOMINAL, OBJECTIVES, start_value
from .returnmap import COLLAPSE_FRACTION, PHASES, ReturnMap, Stride

@dataclass(frozen=True)
class ShootingOptions:
    """Discretisation and solver settings of the NLP."""

    nodes: int = 20  # shooting intervals per stance phase
    substeps: int = 1  # RK4 steps per interval
    margin: float = 1e-3  # transversality margin on guard rates [SI]
    min_duration: float = 1e-3  # [s]
    max_duration: float = 5.0  # [s]
    ipopt: Mapping[str, object] = field(
        default_factory=lambda: {"max_iter": 300, "tol": 1e-10, "acceptable_tol": 1e-8}
    )


@dataclass(frozen=True)
class FixedPointSpec:
    """What to solve: parameters, fixed values, guess, bounds and objective."""

    params: Params
    fixed: Mapping[str, float]  # subset of QUANTITIES
    guess: Mapping[str, float]  # every design quantity that is not fixed
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    objective: str = "nearest_guess"
    strides: int = 1  # the orbit's period in strides; fixed values and guess are its first apex

    def bounds_of(self, name: str) -> tuple[float, float]:
        """Bounds of a design quantity: the problem's, inside the physical ones."""
        lo, hi = DEFAULT_BOUNDS[name]
        if name in self.bounds:
            lo, hi = max(lo, self.bounds[name][0]), min(hi, self.bounds[name][1])
        return lo, hi

    def start_design(self) -> np.ndarray:
        """Starting value of each design quantity (fixed, guessed, or default in bounds)."""
        return np.array([start_value(n, self.fixed, self.guess, self.bounds) for n in DESIGN])


@dataclass(frozen=True)
class NlpSolution:
    """IPOPT's answer: design values, durations and solver statistics."""

    X: np.ndarray
    u: np.ndarray
    durations: np.ndarray
    return_status: str
    iterations: int
    time_s: float
    w: np.ndarray | None = None  # every NLP variable, to warm-start a neighbouring solve


def _rk4_interval(substeps: int) -> ca.Function:
    """One shooting interval: ``substeps`` RK4 steps of the closed-loop stance ODE.

    Returns the end state and the integral of tau^2 [N^2 m^2 s] over the interval.
    """
    x, u, p, h = STANCE.sym("x"), CONTROL.sym("u"), PARAMS.sym("p"), ca.SX.sym("h")
    aug = ca.vertcat(x, 0)

    def rhs(a):
        xs = a[: STANCE.size]
        tau = hip_torque(xs, u)
        return ca.vertcat(stance_dynamics(xs, tau, p), tau**2)

    dt = h / substeps
    for _ in range(substeps):
        k1 = rhs(aug)
        k2 = rhs(aug + dt / 2 * k1)
        k3 = rhs(aug + dt / 2 * k2)
        k4 = rhs(aug + dt * k3)
        aug = aug + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("rk4_interval", [x, u, p, h], [aug[: STANCE.size], aug[-1]])


class ShootingNLP:
    """The periodic-orbit NLP for one discretisation and stride count, built once and
    solved many times.

    With ``strides = N`` the orbit has N strides under the same control: the apexes
    X_1..X_{N-1} after the first are decision variables too, each stride is shot as
    above, consecutive strides are joined (X_{k+1} = r(X_k)) and the last one closes the
    orbit (r(X_{N-1}) = X_0). The problem's fixed values, guess and objective refer to
    the first apex X_0.
    """

    def __init__(self, options: ShootingOptions = ShootingOptions(), strides: int = 1):
        if strides < 1:
            raise ValueError(f"strides must be at least 1, got {strides}")
        self.options = options
        self.strides = strides
        self._build()

    # -- construction ------------------------------------------------------------------

    def _build(self) -> None:
        opt = self.options
        n = opt.nodes
        # MX keeps one copy of the mapped RK4 interval (and of its derivatives) instead of
        # inlining it at every node; the small SX pieces are expanded when called.
        u, p = CONTROL.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
        guess, weights = ca.MX.sym("guess", len(DESIGN)), ca.MX.sym("weights", 2)
        self.interval = _rk4_interval(opt.substeps)

        constraints: list[tuple[ca.MX, float, float]] = []

        def constrain(expr, lo, hi):
            constraints.append((ca.vec(expr), lo, hi))

        apexes, blocks, effort, apex_next = [], [], 0, None
        for k in range(self.strides):
            X = APEX.sym(f"X{k}", ca.MX)
            T = ca.vertcat(*(ca.MX.sym(f"T{k}_{ph}") for ph in PHASES))
            comp_nodes = ca.MX.sym(f"compression_nodes{k}", STANCE.size, n)
            decomp_nodes = ca.MX.sym(f"decompression_nodes{k}", STANCE.size, n)
            if apex_next is not None:
                constrain(apex_next - X, 0, 0)  # strides join
            apex_next, stride_effort = self._stride(X, u, p, T, comp_nodes, decomp_nodes, constrain)
            effort += stride_effort
            apexes.append(X)
            # X_0 and u lead the vector so that the design is w[:len(DESIGN)] for any N.
            blocks += ([] if k == 0 else [X]) + [T, ca.vec(comp_nodes), ca.vec(decomp_nodes)]
        X0 = apexes[0]
        self._periodicity_row = sum(c[0].numel() for c in constraints)
        constrain(apex_next - X0, 0, 0)  # the orbit closes
        self._energy_row = sum(c[0].numel() for c in constraints)
        constrain(apex_energy(X0, p), -ca.inf, ca.inf)  # bounded or fixed per problem

        design = ca.vertcat(X0, u)
        scale = ca.DM([NOMINAL[name] for name in DESIGN])
        distance = ca.sumsqr((design - guess) / scale)
        objective = weights[0] * distance + weights[1] * effort

        w = ca.vertcat(X0, u, *blocks)
        self._n_w = w.numel()
        params = ca.vertcat(p, guess, weights)
        g = ca.vertcat(*(c[0] for c in constraints))
        self._lbg = np.concatenate([np.full(c[0].numel(), c[1], dtype=float) for c in constraints])
        self._ubg = np.concatenate([np.full(c[0].numel(), c[2], dtype=float) for c in constraints])
        ipopt = {"print_level": 0, "sb": "yes", **dict(opt.ipopt)}
        self._solver = ca.nlpsol(
            "periodic_orbit", "ipopt", {"x": w, "p": params, "f": objective, "g": g},
            # Expanding to SX makes each IPOPT iteration several times cheaper than MX.
            {"ipopt": ipopt, "print_time": False, "error_on_fail": False, "expand": True},
        )

    def _stride(self, X, u, p, T, comp_nodes, decomp_nodes, constrain):
        """Constrain one shot stride from apex ``X``; return its next apex and its tau^2
        integral [N^2 m^2 s]."""
        opt, n = self.options, self.options.nodes
        t_descent, t_compression, t_decompression, t_ascent = (T[i] for i in range(len(PHASES)))
        theta_td = touchdown_angle(u)
        apex_flight = apex_to_flight(X)
        # Descent: the foot stays above ground until it crosses zero, falling.
        for fraction in (0.0, 0.25, 0.5, 0.75):
            constrain(touchdown_guard(ballistic_flight(apex_flight, fraction * t_descent, p), theta_td, p), 0, ca.inf)
        at_touchdown = ballistic_flight(apex_flight, t_descent, p)
        constrain(touchdown_guard(at_touchdown, theta_td, p), 0, 0)
        constrain(touchdown_guard_rate(at_touchdown, p), -ca.inf, -opt.margin)
        x_td = touchdown_map(at_touchdown, theta_td, p)

        starts_c = ca.horzcat(x_td, comp_nodes[:, :-1])
        ends_c, effort_c = self.interval.map(n)(starts_c, u, p, t_compression / n)
        constrain(comp_nodes - ends_c, 0, 0)
        bottom = comp_nodes[:, -1]
        constrain(bottom_guard(bottom), 0, 0)
        rho_accel = STANCE.get(stance_dynamics(bottom, hip_torque(bottom, u), p), "rhodot")
        constrain(rho_accel, opt.margin, ca.inf)
        # The leg shortens from touchdown (transversally) until the bottom.
        constrain(bottom_guard(x_td), -ca.inf, -opt.margin)
        constrain(bottom_guard(comp_nodes[:, :-1]), -ca.inf, 0)

        starts_d = ca.horzcat(bottom, decomp_nodes[:, :-1])
        ends_d, effort_d = self.interval.map(n)(starts_d, u, p, t_decompression / n)
        constrain(decomp_nodes - ends_d, 0, 0)
        x_lo = decomp_nodes[:, -1]
        constrain(liftoff_guard(x_lo, p), 0, 0)
        constrain(STANCE.get(x_lo, "rhodot"), opt.margin, ca.inf)
        # The leg stays compressed until liftoff.
        constrain(liftoff_guard(starts_d[:, 1:], p), -ca.inf, 0)

        rho0 = PARAMS.get(p, "rho0")
        for nodes in (comp_nodes, decomp_nodes):
            for k in range(n):
                q = nodes[:3, k]
                constrain(STANCE.get(q, "rho") - COLLAPSE_FRACTION * rho0, 0, ca.inf)
                constrain(stance_com_position(q, p)[1], 0, ca.inf)
                constrain(stance_hip_position(q)[1], 0, ca.inf)

        at_liftoff = liftoff_map(x_lo, p)
        constrain(FLIGHT.get(at_liftoff, "zdot"), opt.margin, ca.inf)
        at_apex = ballistic_flight(at_liftoff, t_ascent, p)
        constrain(FLIGHT.get(at_apex, "zdot"), 0, 0)  # apex guard
        apex_next = ca.vertcat(*(FLIGHT.get(at_apex, name) for name in APEX.names))
        return apex_next, ca.sum2(effort_c) + ca.sum2(effort_d)

    # -- solving -----------------------------------------------------------------------

    def _durations_index(self, k: int) -> int:
        """Position of stride k's first phase duration in the NLP vector, laid out as
        (X_0, u, T_0, nodes_0, X_1, T_1, nodes_1, ...)."""
        nodes = 2 * STANCE.size * self.options.nodes
        return len(DESIGN) + k * (APEX.size + len(PHASES) + nodes)

    def _bounds(self, spec: FixedPointSpec) -> tuple[np.ndarray, np.ndarray]:
        lbx = np.full(self._n_w, -np.inf)
        ubx = np.full(self._n_w, np.inf)
        for i, name in enumerate(DESIGN):
            lo, hi = spec.bounds_of(name)
            if name in spec.fixed:
                lo = hi = spec.fixed[name]
            lbx[i], ubx[i] = lo, hi
        for k in range(self.strides):
            t0 = self._durations_index(k)
            lbx[t0 : t0 + len(PHASES)] = self.options.min_duration
            ubx[t0 : t0 + len(PHASES)] = self.options.max_duration
        return lbx, ubx

    def initial_guess(self, spec: FixedPointSpec, rmap: ReturnMap | None = None) -> np.ndarray:
        """Initial point: the guess's design, then for each stride the apex reached by
        simulating the guess (the guess itself if it falls), its durations, and nodes
        propagated by RK4 through stance."""
        design = spec.start_design()
        X, u = design[: APEX.size], design[APEX.size :]
        p = spec.params.vector()
        n = self.options.nodes
        parts = [design]
        for k in range(self.strides):
            stride = rmap.stride(X, u, spec.params) if rmap is not None else None
            durations = _guess_durations(X, u, spec.params, stride)
            x_td = np.asarray(_touchdown_state(X, u, p, durations[0])).ravel()
            nodes_c = _propagate(self.interval, x_td, u, p, durations[1], n)
            nodes_d = _propagate(self.interval, nodes_c[:, -1], u, p, durations[2], n)
            parts += ([X] if k else []) + [durations, nodes_c.T.ravel(), nodes_d.T.ravel()]
            X = stride.apex if stride is not None and stride.ok else X
        return np.concatenate(parts)

    def solve(self, spec: FixedPointSpec, w0: np.ndarray | None = None, rmap: ReturnMap | None = None) -> NlpSolution:
        """Solve the NLP from ``w0`` (default: :meth:`initial_guess`)."""
        if spec.strides != self.strides:
            raise ValueError(f"this NLP is built for {self.strides}-stride orbits, not {spec.strides}")
        if w0 is None:
            w0 = self.initial_guess(spec, rmap)
        lbx, ubx = self._bounds(spec)
        w0 = np.clip(w0, lbx, ubx)
        guess = spec.start_design()
        weights = np.array(OBJECTIVES[spec.objective])
        lbg, ubg = self._lbg.copy(), self._ubg.copy()
        energy_bounds = spec.bounds.get("energy", (-np.inf, np.inf))
        if "energy" in spec.fixed:
            energy_bounds = (spec.fixed["energy"], spec.fixed["energy"])
        lbg[self._energy_row], ubg[self._energy_row] = energy_bounds
        for name in implied_periodicity(spec):
            row = self._periodicity_row + APEX.index(name)
            lbg[row], ubg[row] = -np.inf, np.inf
        params = np.concatenate([spec.params.vector(), guess, weights])
        start = time.perf_counter()
        # CasADi warns on stderr when a trial point gives NaN; IPOPT recovers or reports a
        # failure status, which is what the caller sees.
        with contextlib.redirect_stderr(io.StringIO()):
            sol = self._solver(x0=w0, p=params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        elapsed = time.perf_counter() - start
        stats = self._solver.stats()
        w = np.asarray(sol["x"]).ravel()
        n_design = len(DESIGN)
        return NlpSolution(
            X=w[: APEX.size],
            u=w[APEX.size : n_design],
            durations=w[n_design : n_design + len(PHASES)],
            return_status=str(stats["return_status"]),
            iterations=int(stats["iter_count"]),
            time_s=elapsed,
            w=w,
        )


def implied_periodicity(spec: FixedPointSpec) -> tuple[str, ...]:
    """Apex coordinates whose periodicity follows from the others by structure.

    Without hip torque (Kp = Kd = 0 fixed) energy is conserved, so a periodic ydot and
    theta_h_dot make z periodic. With d = 0 as well, the trunk spins freely: theta_h_dot is
    always periodic, and theta_h is too when theta_h_dot is fixed at zero. These rows are
    exactly dependent on the others; the RK4 discretisation breaks the dependence by its
    truncation error, which makes IPOPT declare the problem infeasible. So the NLP leaves
    them out of the row that closes the orbit (the joins of a multi-stride orbit keep all
    four, or its intermediate apexes would float); the Newton polish and the verification
    still check all four on the exact map.
    """
    torque_free = spec.fixed.get("Kp") == 0.0 and spec.fixed.get("Kd") == 0.0
    if not torque_free:
        return ()
    implied = ["z"]
    if spec.params.d == 0.0:
        implied.append("theta_h_dot")
        if spec.fixed.get("theta_h_dot") == 0.0:
            implied.append("theta_h")
    return tuple(implied)


def torque_effort(interval: ca.Function, X, u, durations, params: Params, n: int = 200) -> float:
    """Integral of tau^2 over stance [N^2 m^2 s] for phase ``durations``, by RK4 quadrature."""
    p = params.vector()
    x = np.asarray(_touchdown_state(X, u, p, durations[0])).ravel()
    total = 0.0
    for duration in durations[1:3]:
        for _ in range(n):
            x_next, effort = interval(x, u, p, duration / n)
            x, total = np.asarray(x_next).ravel(), total + float(effort)
    return total


def _touchdown_state(X, u, p, t_descent) -> ca.DM:
    """Stance state at touchdown after ``t_descent`` seconds of descent from apex ``X``."""
    X, u, p = ca.DM(X), ca.DM(u), ca.DM(p)
    xf = ca.evalf(ballistic_flight(apex_to_flight(X), t_descent, p))
    return touchdown_map(xf, float(CONTROL.get(u, "theta_td")), p)


def _propagate(interval: ca.Function, x0, u, p, duration, n) -> np.ndarray:
    """States at the ends of ``n`` equal intervals of ``duration`` from ``x0`` (6 x n)."""
    states, x = [], np.asarray(x0, dtype=float)
    for _ in range(n):
        x = np.asarray(interval(x, u, p, duration / n)[0]).ravel()
        states.append(x)
    return np.array(states).T


def _guess_durations(X, u, params: Params, stride: Stride | None) -> np.ndarray:
    """Phase durations of the guess's simulated ``stride``, or spring-based estimates if
    it falls (or was not simulated)."""
    if stride is not None and stride.ok:
        return np.array([stride.durations[ph] for ph in PHASES])
    p = params.vector()
    t_down = ReturnMap.touchdown_guess(X, u, p) or 0.1
    quarter = 0.5 * np.pi * np.sqrt(params.m / params.k)
    return np.array([t_down, quarter, quarter, t_down])
