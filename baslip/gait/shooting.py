"""The periodic-stride NLP: phase-level multiple shooting over the compiled stance flow,
solved by IPOPT.

Decision variables (all in SI units and radians):

* the apex state ``X`` (4) and the control ``u`` (the hip law's); fixed quantities have
  equal bounds;
* the four phase durations ``T = (descent, compression, decompression, ascent)``;
* shooting-node states in compression and decompression, ``nodes`` intervals each, every
  interval integrated by ``substeps`` DOP853 steps of the stance flow of
  :mod:`baslip.engine.kernels`, of length ``T_phase / (nodes * substeps)``.

Constraints:

* continuity at the nodes; the touchdown map at the start of stance;
* each guard zero at its phase end, with its crossing direction as an inequality
  (transversality, by ``margin``);
* periodicity ``r(X, u) = X``, or for an orbit of N strides ``r^N(X, u) = X`` with the
  intermediate apexes as variables; optionally the apex energy;
* sanity: the foot above ground through descent, the leg compressing in compression and
  compressed in decompression, CoM, hip and leg clear of the ground at every stage point,
  rising liftoff, durations bounded away from zero.

The objective picks one point on the fixed-point manifold (see :data:`OBJECTIVES`).
The NLP is built once per discretisation; parameters, guess, fixed values, bounds and the
objective's weights enter as numbers, so one built solver serves every problem. Its
functions are compiled to C like the stride engine, so IPOPT's iterations run in C.
"""

from __future__ import annotations

import contextlib
import functools
import io
import pathlib
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from baslip.engine.codegen import cached_library, compile_library, library_name, module_files
from baslip.engine.kernels import StanceFlow
from baslip.engine.kernels import sources as kernel_sources
from baslip.engine.physics import Physics
from baslip.engine.returnmap import PHASES, ReturnMap, Stride
from baslip.engine.sidecar import read_facts, write_facts
from baslip.gait import monodromy as _monodromy
from baslip.gait import nlpfunctions as _nlpfunctions
from baslip.gait import shot_stride as _shot_stride
from baslip.gait.ipopt_report import IpoptTry
from baslip.gait.ipopt_threads import pin_ipopt_threads
from baslip.gait.monodromy import (
    SCHUR,
    ShotStrideJacobian,
    accuracy_constraints,
    schur_constraints,
    schur_start,
    structural_multipliers,
)
from baslip.gait.nlpfunctions import NLP_FUNCTIONS, nlp_functions
from baslip.gait.shot_stride import RowLabel, RowValues, named, row_labels, shoot_stride
from baslip.model import quantities as _quantities
from baslip.model.dynamics import (
    APEX,
    PARAMS,
    STANCE,
    Params,
    apex_energy,
    apex_to_flight,
)
from baslip.model.hiplaw import PD, HipLaw
from baslip.model.quantities import (
    NOMINAL,
    OBJECTIVES,
    UNITS,
    design_names,
    physical_range,
    start_value,
)
from baslip.model.quantities import implied_periodicity as structurally_implied
from baslip.problem.solver import SolverSettings

#: Hessians IPOPT can be given: ``exact``, the Hessian of the Lagrangian through the
#: intervals; ``objective``, the objective's Hessian alone (the constraints' curvature
#: dropped; Gauss-Newton for the torque term); or IPOPT's ``limited-memory`` BFGS. The
#: table of docs/background/engine.md measures them; ``objective`` is the default, with ``exact`` as the
#: second try after a failure (see :class:`baslip.gait.fixedpoint.FixedPointSolver`).
HESSIANS = ("exact", "objective", "limited-memory")


#: gcc's optimisation level of the NLP's library (objective, constraints, derivatives).
#: Measured on the 2-core machine: the one-stride NLP's 1.1 MB of C take 4.2 s at -O1
#: against 12.3 s at -O3, and a whole solve (IPOPT, polish, verification) of the shipped
#: gaits 0.2 to 0.8 % longer (best of 15 alternating runs in one process).
NLP_OPTIMISATION = "-O1"


@dataclass(frozen=True)
class ShootingOptions:
    """Discretisation and solver settings of the NLP."""

    nodes: int = SolverSettings.nodes  # shooting intervals per stance phase
    substeps: int = SolverSettings.substeps  # steps of the scheme per interval
    hessian: str = "objective"  # see HESSIANS
    scheme: str = "rk4"  # the interval's steps: "rk4" or "dop853" (see docs/background/engine.md)
    margin: float = 1e-3  # transversality margin on guard rates [SI]
    # Bound the multipliers inside the NLP by a Schur form of the shot stride's dr/dX and
    # minimise the bound (:mod:`baslip.gait.monodromy`); one-stride orbits only.
    spectral_bound: bool = False
    min_duration: float = 1e-3  # [s]
    max_duration: float = 5.0  # [s]
    ipopt: Mapping[str, object] = field(default_factory=lambda: ipopt_options(SolverSettings()))


def ipopt_options(settings: SolverSettings) -> dict[str, object]:
    """IPOPT's options for a problem's solver settings (iterations, tolerances, verbosity)."""
    return {"max_iter": settings.max_iter, "tol": settings.tol, "acceptable_tol": max(settings.tol, 1e-8),
            "print_level": settings.print_level}


@dataclass(frozen=True)
class FixedPointSpec:
    """What to solve: parameters, hip law, fixed values, guess, bounds and objective."""

    params: Params
    fixed: Mapping[str, float]  # subset of the law's quantities (design and energy)
    guess: Mapping[str, float]  # every design quantity that is not fixed
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    objective: str = "nearest_guess"
    strides: int = 1  # the orbit's period in strides; fixed values and guess are its first apex
    law: HipLaw = PD

    @property
    def design(self) -> tuple[str, ...]:
        """The design quantities: the apex state, then the law's controls."""
        return design_names(self.law)

    def bounds_of(self, name: str) -> tuple[float, float]:
        """Bounds of a design quantity: the problem's, inside the physical ones (the thesis
        body's scaled to this body, :func:`baslip.model.quantities.body_scale`)."""
        lo, hi = physical_range(name, self.params)
        if name in self.bounds:
            lo, hi = max(lo, self.bounds[name][0]), min(hi, self.bounds[name][1])
        return lo, hi

    def start_design(self) -> np.ndarray:
        """Starting value of each design quantity (fixed, guessed, or the body's default in
        bounds)."""
        return np.array([start_value(n, self.fixed, self.guess, self.bounds, self.params) for n in self.design])


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
    spectral_bound: float | None = None  # the stability NLP's bound on the multipliers' moduli
    tries: tuple[IpoptTry, ...] = ()  # the runs of IPOPT that led here: this one, after any earlier tries


def _rk4_interval(substeps: int, physics: Physics) -> ca.Function:
    """One shooting interval: ``substeps`` RK4 steps of the closed-loop stance ODE.

    Returns the end state and the integral of tau^2 [N^2 m^2 s] over the interval.
    """
    law = physics.law
    x, u, p, h = STANCE.sym("x"), law.controls.sym("u"), PARAMS.sym("p"), ca.SX.sym("h")
    aug = ca.vertcat(x, 0)

    def rhs(a):
        xs = a[: STANCE.size]
        return ca.vertcat(physics.stance_rate(xs, u, p), law.torque(xs, u, p) ** 2)

    dt = h / substeps
    for _ in range(substeps):
        k1 = rhs(aug)
        k2 = rhs(aug + dt / 2 * k1)
        k3 = rhs(aug + dt / 2 * k2)
        k4 = rhs(aug + dt * k3)
        aug = aug + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    # One derivative direction per generated function keeps the compiled NLP's exact
    # Hessian (second derivatives through every interval) to a 30 s compile, not 160 s.
    return ca.Function("rk4_interval", [x, u, p, h], [aug[: STANCE.size], aug[-1]], {"max_num_dir": 1})


class ShootingNLP:
    """The periodic-orbit NLP for one step count and stride count, built once and solved
    many times.

    Decision variables per stride: the apex (after the first stride), the four phase
    durations and the shooting nodes of compression and decompression, each interval
    ``substeps`` DOP853 steps of the stance flow (time scaled by the phase duration). With
    ``strides = N`` consecutive strides are joined (X_{k+1} = r(X_k)) and the last closes
    the orbit.

    The NLP's functions (objective and constraints, their gradient and Jacobian, and the
    Hessian, see :data:`HESSIANS`) are generated as C and cached like the stride engine.
    """

    def __init__(self, options: ShootingOptions = ShootingOptions(), strides: int = 1, compile: bool | None = None,
                 law: HipLaw = PD):
        if strides < 1:
            raise ValueError(f"strides must be at least 1, got {strides}")
        if options.hessian not in HESSIANS:
            raise ValueError(f"hessian must be one of {HESSIANS}, got {options.hessian!r}")
        if options.spectral_bound and strides != 1:
            raise ValueError(f"the multipliers are bounded for one-stride orbits only, not {strides}")
        self.options = options
        self.strides = strides
        self.law = law
        self.design = design_names(law)
        if not self._load(compile):  # no graph to build where the cache holds library and facts
            self._build(compile)
        self._solvers: dict[tuple, ca.Function] = {(): self._nlpsol(self.functions, {})}

    # -- construction ------------------------------------------------------------------

    @functools.cached_property
    def interval(self) -> ca.Function:
        """One RK4 step of stance with its tau^2 integral, for :func:`torque_effort`."""
        return _rk4_interval(1, self.physics)

    @functools.cached_property
    def physics(self) -> Physics:
        """The BA-SLIP description's physics under the NLP's law."""
        return Physics.of(self.law)

    @functools.cached_property
    def _stance(self) -> StanceFlow:
        return StanceFlow(self.law)

    @functools.cached_property
    def _library(self) -> str:
        """The name of the NLP's compiled library (its discretisation, law and Hessian)."""
        o = self.options
        return (library_name("baslip_nlp", self.law) + f"_{self.strides}_{o.nodes}x{o.substeps}_{o.scheme}_"
                f"{o.hessian.replace('-', '_')}{'_stable' if o.spectral_bound else ''}")

    def _load(self, compile: bool | None) -> bool:
        """Whether the cache holds the NLP's library and its sizes, bounds and row names beside it, now
        loaded (:mod:`baslip.engine.sidecar`); the stability NLP's pieces need its graph."""
        if self.options.spectral_bound:
            return False
        facts = read_facts(self._library, NLP_FUNCTIONS, _nlp_sources(), optimisation=NLP_OPTIMISATION, enabled=compile)
        if facts is None or facts.get("margin") != self.options.margin or "rows" not in facts:  # the bounds hold the margin
            return False
        functions = cached_library(self._library, NLP_FUNCTIONS, _nlp_sources(), optimisation=NLP_OPTIMISATION)
        if functions is None:
            return False
        self.functions = functions
        self._n_w, self._n_orbit = facts["n_w"], facts["n_orbit"]
        self._periodicity_row, self._energy_row = facts["periodicity_row"], facts["energy_row"]
        self._lbg, self._ubg = np.array(facts["lbg"], dtype=float), np.array(facts["ubg"], dtype=float)
        self.row_labels = tuple(RowLabel(name, unit) for name, unit in facts["rows"])
        return True

    def _shooting_interval(self) -> ca.Function:
        """One shooting interval, ``substeps`` steps of the scheme: (x0, h, theta) -> end state."""
        n_u = self.law.controls.size
        x0, h, theta = STANCE.sym("x0", ca.MX), ca.MX.sym("h"), ca.MX.sym("theta", n_u + PARAMS.size)
        if self.options.scheme == "rk4":
            end = _rk4_interval(self.options.substeps, self.physics)(x0, theta[:n_u], theta[n_u:], h)[0]
        else:
            end = self._stance.chain(self.options.substeps)(x0, h, theta)[0][:, -1]
        return ca.Function("shooting_interval", [x0, h, theta], [end])

    def _build(self, compile: bool | None) -> None:
        self._interval = self._shooting_interval()
        u, p = self.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
        guess, weights = ca.MX.sym("guess", len(self.design)), ca.MX.sym("weights", 2)
        constraints: list[tuple[ca.MX, float, float]] = []
        labels: list[RowLabel] = []

        def constrain(expr, lo, hi, name: str | tuple[str, ...] = "a row of the stability NLP",
                      unit: str | tuple[str, ...] = ""):
            expr = ca.vec(expr)
            constraints.append((expr, lo, hi))
            labels.extend(row_labels(name, unit, expr.numel()))

        apexes, blocks, effort, apex_next, shot = [], [], [], None, []
        for k in range(self.strides):
            X = APEX.sym(f"X{k}", ca.MX)
            T = ca.MX.sym(f"T{k}", len(PHASES))
            comp_nodes = ca.MX.sym(f"compression_nodes{k}", STANCE.size, self.options.nodes)
            decomp_nodes = ca.MX.sym(f"decompression_nodes{k}", STANCE.size, self.options.nodes)
            if apex_next is not None:
                constrain(apex_next - X, 0, 0, tuple(f"join of strides {k} and {k + 1} in {n}" for n in APEX.names),
                          APEX_UNITS)
            stride = f"stride {k + 1}: " if self.strides > 1 else ""
            apex_next, stride_effort = shoot_stride(self._stance, self._interval, self.options.margin, X, u, p, T,
                                                     comp_nodes, decomp_nodes, named(constrain, stride))
            effort.append(stride_effort)
            apexes.append(X)
            shot.append((T, comp_nodes, decomp_nodes))
            # X_0 and u lead the vector so that the design is w[:len(self.design)] for any N.
            blocks += ([] if k == 0 else [X]) + [T, ca.vec(comp_nodes), ca.vec(decomp_nodes)]
        X0 = apexes[0]
        self._periodicity_row = sum(c[0].numel() for c in constraints)
        constrain(apex_next - X0, 0, 0, tuple(f"periodicity of {n}" for n in APEX.names), APEX_UNITS)  # the orbit closes
        self._energy_row = sum(c[0].numel() for c in constraints)
        constrain(apex_energy(X0, p), -ca.inf, ca.inf, "apex energy", "J")  # bounded or fixed per problem

        design = ca.vertcat(X0, u)
        scale = ca.DM([NOMINAL[name] for name in self.design])
        distance = ca.sumsqr((design - guess) / scale)
        w = ca.vertcat(X0, u, *blocks)
        self._n_orbit = w.numel()  # the orbit's variables; the stability NLP's follow
        bound = ca.MX(0)
        if self.options.spectral_bound:
            bound, stability = self._stability(w, X0, u, p, shot[0], constraints, constrain)
            w = ca.vertcat(w, stability)
        self._n_w = w.numel()
        params = ca.vertcat(p, guess, weights)
        g = ca.vertcat(*(c[0] for c in constraints))
        self._lbg = np.concatenate([np.full(c[0].numel(), c[1], dtype=float) for c in constraints])
        self._ubg = np.concatenate([np.full(c[0].numel(), c[2], dtype=float) for c in constraints])
        self.row_labels = tuple(labels)
        self.functions = compile_library(  # objective, constraints and derivatives
            self._library, NLP_FUNCTIONS,
            lambda: nlp_functions(w, params, weights, distance, ca.vertcat(*effort), bound, g, self.options.hessian),
            _nlp_sources(), enabled=compile, optimisation=NLP_OPTIMISATION,
        )
        if not self.options.spectral_bound:
            write_facts(self._library, NLP_FUNCTIONS, _nlp_sources(), {
                "margin": self.options.margin, "n_w": self._n_w, "n_orbit": self._n_orbit,
                "periodicity_row": self._periodicity_row, "energy_row": self._energy_row,
                "lbg": self._lbg.tolist(), "ubg": self._ubg.tolist(),
                "rows": [[label.name, label.unit] for label in self.row_labels]}, optimisation=NLP_OPTIMISATION)

    def _stability(self, w, X0, u, p, shot, constraints, constrain):
        """The stability NLP's part (:mod:`baslip.gait.monodromy`): the sensitivity nodes
        and their joins, every interval's h * rate within the limit, and the Schur form
        with its bound; returns (the bound s, the new variables)."""
        self._sensitivity = ShotStrideJacobian(self._interval, self.options.nodes, self.law)
        sensitivities = ca.MX.sym("sensitivities", self._sensitivity.size)
        schur = ca.MX.sym("schur", SCHUR.size)
        first_row = sum(c[0].numel() for c in constraints)
        A = self._sensitivity.jacobian(X0, u, p, *shot, sensitivities, constrain)
        self.sensitivity_rows = slice(first_row, sum(c[0].numel() for c in constraints))
        durations = shot[0]
        for phase in (1, 2):  # compression and decompression
            step = durations[phase] / (self.options.nodes * self.options.substeps)
            for expr, lo, hi in accuracy_constraints(self.law, u, p, step):
                constrain(expr, lo, hi)
        for expr, lo, hi in schur_constraints(A, schur, structural_multipliers(self.law)):
            constrain(expr, lo, hi)
        self._shot_jacobian = ca.Function("shot_stride_jacobian", [w, sensitivities, p], [A])
        return SCHUR.unpack(schur)[-1], ca.vertcat(sensitivities, schur)

    def shot_jacobian(self, w: np.ndarray, params: Params) -> np.ndarray:
        """dr/dX of the shot stride at the stability NLP's point ``w`` (its orbit and
        sensitivity nodes; the Schur variables, if present, are ignored)."""
        if not self.options.spectral_bound:
            raise ValueError("only the stability NLP (spectral_bound) carries the shot stride's dr/dX")
        w = np.asarray(w, dtype=float)
        sensitivities = w[self._n_orbit : self._n_orbit + self._sensitivity.size]
        return np.asarray(self._shot_jacobian(w[: self._n_orbit], sensitivities, params.vector()))

    def _nlpsol(self, functions: dict[str, ca.Function], changed: Mapping[str, object]) -> ca.Function:
        """IPOPT over the (compiled) NLP functions, with the options' IPOPT settings and
        ``changed`` over them; CasADi differentiates nothing itself."""
        w, params = ca.MX.sym("w", self._n_w), ca.MX.sym("P", functions["nlp_fg"].size1_in(1))
        f, g = functions["nlp_fg"](w, params)
        ipopt = {"print_level": 0, "sb": "yes", **dict(self.options.ipopt), **dict(changed)}
        # lam_p would need derivatives of the compiled functions that IPOPT never uses.
        options = {"ipopt": ipopt, "print_time": False, "error_on_fail": False, "calc_lam_p": False, "no_nlp_grad": True,
                   "grad_f": functions["nlp_grad_f"], "jac_g": functions["nlp_jac_g"]}
        if self.options.hessian == "limited-memory":
            ipopt["hessian_approximation"] = "limited-memory"
        else:
            options["hess_lag"] = functions["nlp_hess_l"]
        # CasADi's stubs list SX only; nlpsol takes MX expressions as well.
        return ca.nlpsol("periodic_orbit", "ipopt", {"x": w, "p": params, "f": f, "g": g}, options)  # type: ignore[dict-item, arg-type]

    # -- solving -----------------------------------------------------------------------

    @property
    def variable_count(self) -> int:
        """How many variables the NLP has (the length of a point ``w``)."""
        return self._n_w

    @property
    def _bound_index(self) -> int:
        """Position of the stability NLP's bound s: the last variable."""
        return self._n_w - 1

    def _durations_index(self, k: int) -> int:
        """Position of stride k's first phase duration in the NLP vector, laid out as
        (X_0, u, T_0, nodes_0, X_1, T_1, nodes_1, ...)."""
        nodes = 2 * STANCE.size * self.options.nodes
        return len(self.design) + k * (APEX.size + len(PHASES) + nodes)

    def _bounds(self, spec: FixedPointSpec) -> tuple[np.ndarray, np.ndarray]:
        lbx = np.full(self._n_w, -np.inf)
        ubx = np.full(self._n_w, np.inf)
        for i, name in enumerate(self.design):
            lo, hi = spec.bounds_of(name)
            if name in spec.fixed:
                lo = hi = spec.fixed[name]
            lbx[i], ubx[i] = lo, hi
        for k in range(self.strides):
            t0 = self._durations_index(k)
            lbx[t0 : t0 + len(PHASES)] = self.options.min_duration
            ubx[t0 : t0 + len(PHASES)] = self.options.max_duration
        if self.options.spectral_bound:
            lbx[self._bound_index] = 0.0
        return lbx, ubx

    def initial_guess(self, spec: FixedPointSpec, rmap: ReturnMap | None = None) -> np.ndarray:
        """Initial point: the guess's design, then for each stride the apex reached by
        simulating the guess (the guess itself if it falls), its durations, and nodes
        propagated through stance by the NLP's own steps."""
        design = spec.start_design()
        X, u = design[: APEX.size], design[APEX.size :]
        p = spec.params.vector()
        parts = [design]
        for k in range(self.strides):
            stride = rmap.stride(X, u, spec.params) if rmap is not None else None
            durations = _guess_durations(X, u, spec.params, stride)
            comp, decomp = (np.asarray(v) for v in self._guess_nodes()(X, u, p, durations[:3]))
            parts += ([X] if k else []) + [durations, comp.T.ravel(), decomp.T.ravel()]
            X = stride.apex if stride is not None and stride.apex is not None else X
        return self._with_stability_start(np.concatenate(parts), spec)

    def _with_stability_start(self, w: np.ndarray, spec: FixedPointSpec) -> np.ndarray:
        """``w`` with the stability variables appended, if this NLP has them and ``w`` has
        not: the sensitivity nodes that join at ``w``'s orbit, and the Schur form of the
        shot stride's dr/dX there."""
        if not self.options.spectral_bound or len(w) == self._n_w:
            return w
        orbit, p = np.asarray(w, dtype=float)[: self._n_orbit], spec.params.vector()
        n_design, n = len(self.design), STANCE.size * self.options.nodes
        T = orbit[n_design : n_design + len(PHASES)]
        comp = orbit[n_design + len(PHASES) :][:n].reshape(-1, STANCE.size).T
        decomp = orbit[n_design + len(PHASES) + n :][:n].reshape(-1, STANCE.size).T
        X, u = orbit[: APEX.size], orbit[APEX.size : n_design]
        sensitivities = self._sensitivity.start_values(X, u, p, T, comp, decomp)
        A = np.asarray(self._shot_jacobian(orbit, sensitivities, p))
        return np.concatenate([orbit, sensitivities, schur_start(A, structural_multipliers(self.law))])

    def _guess_nodes(self) -> ca.Function:
        """(X, u, p, (t_descent, t_compression, t_decompression)) -> the nodes of both
        stance phases (6 x nodes each), propagated without the bottom guard (built on
        first use)."""
        if not hasattr(self, "_guess_nodes_fn"):
            X, u, p = APEX.sym("X", ca.MX), self.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
            T = ca.MX.sym("T", 3)
            n, steps = self.options.nodes, self.options.substeps
            x_td = self._stance.physics.reset("touchdown", self._stance.physics.flight(apex_to_flight(X), T[0], u, p), u, p)
            chain = self._stance.chain(n * steps)
            comp = chain(x_td, T[1] / (n * steps), ca.vertcat(u, p))[0][:, steps - 1 :: steps]
            decomp = chain(comp[:, -1], T[2] / (n * steps), ca.vertcat(u, p))[0][:, steps - 1 :: steps]
            self._guess_nodes_fn = ca.Function("guess_nodes", [X, u, p, T], [comp, decomp])
        return self._guess_nodes_fn

    def _constraint_bounds(self, spec: FixedPointSpec) -> tuple[np.ndarray, np.ndarray]:
        """(lbg, ubg) of the constraints for ``spec``: its energy bound or value, and the
        periodicity rows that structure implies left free."""
        lbg, ubg = self._lbg.copy(), self._ubg.copy()
        energy_bounds = spec.bounds.get("energy", (-np.inf, np.inf))
        if "energy" in spec.fixed:
            energy_bounds = (spec.fixed["energy"], spec.fixed["energy"])
        lbg[self._energy_row], ubg[self._energy_row] = energy_bounds
        for name in implied_periodicity(spec):
            row = self._periodicity_row + APEX.index(name)
            lbg[row], ubg[row] = -np.inf, np.inf
        return lbg, ubg

    def _parameters(self, spec: FixedPointSpec) -> np.ndarray:
        """The NLP's parameter vector for ``spec``: model parameters, guess and objective weights."""
        return np.concatenate([spec.params.vector(), spec.start_design(), np.array(OBJECTIVES[spec.objective])])

    def rows_at(self, spec: FixedPointSpec, w: np.ndarray) -> RowValues:
        """Every constraint row and variable bound of the NLP for ``spec`` at the point ``w``
        (IPOPT's last iterate, say), with their names and limits."""
        g = np.asarray(self.functions["nlp_fg"](np.asarray(w, dtype=float), self._parameters(spec))[1]).ravel()
        lbg, ubg = self._constraint_bounds(spec)
        lbx, ubx = self._bounds(spec)
        return RowValues(self.row_labels, g, lbg, ubg, self._variable_labels(), np.asarray(w, dtype=float), lbx, ubx)

    def _variable_labels(self) -> tuple[RowLabel, ...]:
        """Name and unit of every NLP variable whose bound can bind: the design quantities
        and the phase durations (the shooting nodes and stability variables are unbounded)."""
        labels = [RowLabel(name, UNITS[name]) for name in self.design]
        labels += [RowLabel("", "")] * (self._n_w - len(labels))
        for k in range(self.strides):
            t0 = self._durations_index(k)
            stride = f" of stride {k + 1}" if self.strides > 1 else ""
            labels[t0 : t0 + len(PHASES)] = [RowLabel(f"{phase} duration{stride}", "s") for phase in PHASES]
        return tuple(labels)

    def try_settings(self, ipopt: Mapping[str, object] | None = None) -> dict[str, object]:
        """What sets a run of IPOPT with ``ipopt`` over the options' settings apart: the
        Hessian, and those settings."""
        return {"hessian": self.options.hessian, **dict(ipopt or {})}

    def _solver(self, changed: Mapping[str, object]) -> ca.Function:
        """IPOPT with ``changed`` over the options' settings, built on first use."""
        key = tuple(sorted(changed.items()))
        if key not in self._solvers:
            self._solvers[key] = self._nlpsol(self.functions, changed)
        return self._solvers[key]

    def solve(self, spec: FixedPointSpec, w0: np.ndarray | None = None, rmap: ReturnMap | None = None,
              ipopt: Mapping[str, object] | None = None) -> NlpSolution:
        """Solve the NLP from ``w0`` (default: :meth:`initial_guess`), with IPOPT's
        settings ``ipopt`` over the options' (default: theirs)."""
        if spec.strides != self.strides:
            raise ValueError(f"this NLP is built for {self.strides}-stride orbits, not {spec.strides}")
        if spec.law is not self.law:
            raise ValueError(f"this NLP is built for hip law {self.law.name}, not {spec.law.name}")
        w0 = self.initial_guess(spec, rmap) if w0 is None else self._with_stability_start(np.asarray(w0, dtype=float), spec)
        lbx, ubx = self._bounds(spec)
        w0 = np.clip(w0, lbx, ubx)
        lbg, ubg = self._constraint_bounds(spec)
        params = self._parameters(spec)
        start = time.perf_counter()
        # CasADi warns on stderr when a trial point gives NaN; IPOPT recovers or reports a
        # failure status, which is what the caller sees.
        with contextlib.redirect_stderr(io.StringIO()):
            solver = self._solver(ipopt or {})
            pin_ipopt_threads()  # the same iterates on every machine (see the module)
            sol = solver(x0=w0, p=params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        elapsed = time.perf_counter() - start
        stats = solver.stats()
        w = np.asarray(sol["x"]).ravel()
        n_design = len(self.design)
        return NlpSolution(
            X=w[: APEX.size],
            u=w[APEX.size : n_design],
            durations=w[n_design : n_design + len(PHASES)],
            return_status=str(stats["return_status"]),
            iterations=int(stats["iter_count"]),
            time_s=elapsed,
            w=w,
            tries=(IpoptTry(self.try_settings(ipopt), str(stats["return_status"]), int(stats["iter_count"])),),
            spectral_bound=float(w[self._bound_index]) if self.options.spectral_bound else None,
        )


#: The unit of each apex coordinate, for the names of the rows that join and close the orbit.
APEX_UNITS = tuple(UNITS[name] for name in APEX.names)


def implied_periodicity(spec: FixedPointSpec) -> tuple[str, ...]:
    """Apex coordinates whose periodicity follows from the others by structure
    (:func:`baslip.model.quantities.implied_periodicity`).

    These rows are exactly dependent on the others; the discretisation breaks the
    dependence by its truncation error, which makes IPOPT declare the problem infeasible.
    So the NLP leaves them out of the row that closes the orbit (the joins of a
    multi-stride orbit keep all four, or its intermediate apexes would float); the Newton
    polish and the verification still check all four on the exact map.
    """
    return structurally_implied(spec.fixed, spec.params, spec.law)


def torque_effort(interval: ca.Function, physics: Physics, X, u, durations, params: Params, n: int = 200) -> float:
    """Integral of tau^2 over stance [N^2 m^2 s] for phase ``durations``, by RK4 quadrature."""
    p = params.vector()
    x = np.asarray(_touchdown_state(physics, X, u, p, durations[0])).ravel()
    total = 0.0
    for duration in durations[1:3]:
        for _ in range(n):
            x_next, effort = interval(x, u, p, duration / n)
            x, total = np.asarray(x_next).ravel(), total + float(effort)
    return total


def _touchdown_state(physics: Physics, X, u, p, t_descent) -> ca.DM:
    """Stance state at touchdown after ``t_descent`` seconds of descent from apex ``X``."""
    X, u, p = ca.DM(X), ca.DM(u), ca.DM(p)
    xf = physics.flight(apex_to_flight(X), t_descent, u, p)
    return physics.reset("touchdown", xf, u, p)


def _guess_durations(X, u, params: Params, stride: Stride | None) -> np.ndarray:
    """Phase durations of the guess's simulated ``stride``, or spring-based estimates if
    it falls (or was not simulated)."""
    if stride is not None and stride.ok:
        return np.array([stride.durations[ph] for ph in PHASES])
    p = params.vector()
    t_down = ReturnMap.touchdown_guess(X, u, p) or 0.1
    quarter = 0.5 * np.pi * np.sqrt(params.m / params.k)
    return np.array([t_down, quarter, quarter, t_down])


def _nlp_sources() -> list[pathlib.Path]:
    """The modules the NLP is derived from: the compiled library's key."""
    return [*kernel_sources(), *module_files(_quantities, _monodromy, _nlpfunctions, _shot_stride, sys.modules[__name__])]
