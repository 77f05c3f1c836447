"""Verified fixed points: NLP, Newton polish on the return map, independent check, stability.

1. IPOPT solves the multiple-shooting NLP (:mod:`baslip.gait.shooting`), whose RK4
   discretisation is accurate to about 1e-6; if IPOPT fails with the default objective
   Hessian, the exact-Hessian NLP gets a second try.
2. Gauss-Newton on the compiled return map (:mod:`baslip.gait.polish`) polishes the free
   quantities until ``r(X, u) = X`` to integrator accuracy. Quantities at an active
   bound stay there.
3. An independent return map, a different integrator (Rosenbrock) at rtol = atol = 1e-12,
   re-simulates the stride; only ``eps = |r(X) - X| / |X| <= 1e-10`` (thesis eq. 4.1) is
   reported as ``converged``.
4. Stability from the eigenvalues of dr/dX by algorithmic differentiation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from baslip.engine.codegen import FEW_CALLS
from baslip.engine.returnmap import PHASES, ReturnMap, Tolerances
from baslip.engine.setuptime import Stopwatch, setting_up, setup_seconds
from baslip.gait.diagnosis import Diagnosis, Limit, diagnose_nlp, limits_on_bounds
from baslip.gait.ipopt_report import IpoptTry, SolverReport
from baslip.gait.polish import Polish
from baslip.gait.polish import eps as _eps
from baslip.gait.shooting import FixedPointSpec, NlpSolution, ShootingNLP, ShootingOptions, torque_effort
from baslip.gait.stability import Multiplier, Stability, classify
from baslip.gait.tries import IpoptAttempt, ended, first_try, told
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import PD, HipLaw
from baslip.model.quantities import NOMINAL, STABILITY_OBJECTIVES
from baslip.status import VERIFY_EPS, Status

#: Tolerances of the independent verification map.
VERIFY_TOLERANCES = Tolerances(rtol=1e-12, atol=1e-12)
#: IPOPT outcomes whose point goes on to polish and verification ("Feasible_Point_Found"
#: is IPOPT's success for square problems, e.g. the SLIP limit at fixed energy).
ACCEPTED_IPOPT = ("Solve_Succeeded", "Solved_To_Acceptable_Level", "Feasible_Point_Found")


@dataclass(frozen=True)
class FixedPointResult:
    """A fixed-point solve: status, the gait, its residual and stability.

    ``status`` is ``converged`` (verified, eps <= 1e-10), ``not_verified`` (IPOPT succeeded
    but the independent re-simulation disagrees or falls) or ``failed`` (IPOPT failed).
    Units: SI and radians throughout.

    Attributes
    ----------
    name : str
        The problem's name.
    status : Status
        ``converged``, ``not_verified`` or ``failed``.
    message : str
        One line on how the solve ended (the re-simulation's complaint, IPOPT's status).
    solver : SolverReport
        IPOPT's return status and iterations, and the wall time [s].
    params : Params
        The model parameters.
    X : numpy.ndarray
        The apex, shape (4,): z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s].
    u : numpy.ndarray
        The controls of ``law``, shape (controls,) (see :attr:`control` for their names).
    durations : Mapping of str to float or None
        Duration [s] of each phase (``descent``, ``compression``, ``decompression``,
        ``ascent``) of the first stride (the NLP's own where the re-simulation fell or did
        not run).
    energy : float
        Total mechanical energy at the apex [J].
    residual : float or None
        eps = |r^n(X) - X| / |X| with n = ``strides`` (relative, dimensionless), or None if
        a stride falls.
    stability : Stability or None
        The multipliers and the verdict; None unless ``converged``.
    polish_iterations : int
        Gauss-Newton iterations of the polish on the return map.
    residual_source : str
        Which map measured ``residual`` (the independent re-simulation, or the return map).
    nlp_w : numpy.ndarray or None
        IPOPT's point (every NLP variable), to warm-start a neighbouring solve.
    strides : int
        The orbit's period asked for, in strides.
    orbit : numpy.ndarray or None
        The apexes of a multi-stride orbit, shape (strides, 4), ``X`` first; None for one
        stride or when the orbit falls.
    law : HipLaw
        The hip law whose controls ``u`` holds.
    diagnosis : Diagnosis or None
        Why IPOPT failed or the answer did not verify: the limits binding at IPOPT's last
        iterate and what to change; None for a verified gait.
    on_bounds : tuple of Limit
        The free design quantities the polished point sits on a bound of (empty for a
        failed solve, whose diagnosis names them).
    """

    name: str
    status: Status
    message: str
    solver: SolverReport
    params: Params
    X: np.ndarray
    u: np.ndarray
    durations: Mapping[str, float] | None
    energy: float
    residual: float | None
    stability: Stability | None
    polish_iterations: int = 0
    residual_source: str = ""  # which map measured ``residual``
    nlp_w: np.ndarray | None = None  # IPOPT's point, to warm-start a neighbouring solve
    strides: int = 1  # the orbit's period asked for, in strides
    orbit: np.ndarray | None = None  # strides x 4: the apexes of a multi-stride orbit, X first
    law: HipLaw = PD  # the hip law whose controls ``u`` holds
    diagnosis: Diagnosis | None = None  # why a failed or unverified solve is no gait
    on_bounds: tuple[Limit, ...] = ()  # free design quantities on a bound

    @property
    def converged(self) -> bool:
        """Whether the result is a verified fixed point (status ``converged``)."""
        return self.status == Status.CONVERGED

    @property
    def apex(self) -> dict[str, float]:
        """The apex state as a dict: z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s]."""
        return APEX.to_dict(self.X)

    @property
    def control(self) -> dict[str, float]:
        """The controls as a dict by the law's names, SI units and radians (under PD: Kp
        [N m/rad], Kd [N m s/rad], theta2_des [rad], theta2_dot_des [rad/s], theta_td [rad])."""
        return self.law.control_dict(self.u)

    @property
    def eigenvalues(self) -> list[complex] | None:
        """The multipliers (eigenvalues of dr/dX, dimensionless), trivial ones included; None
        without stability."""
        return None if self.stability is None else [m.value for m in self.stability.multipliers]

    @property
    def spectral_radius(self) -> float | None:
        """The largest modulus of the non-trivial multipliers (dimensionless, 0 when all are
        trivial); None without stability."""
        return None if self.stability is None else self.stability.spectral_radius

    @property
    def multipliers(self) -> tuple[Multiplier, ...]:
        """The eigenvalues of dr/dX with their trivial labels; empty when there is no
        stability (a failed or unverified solve)."""
        return () if self.stability is None else self.stability.multipliers

    @property
    def stable(self) -> bool | None:
        """Whether the gait is stable (spectral radius below 1 by a margin); None without
        stability."""
        return None if self.stability is None else self.stability.stable

    # -- for people: text, notebooks, motion and figures ---------------------------------

    def __repr__(self) -> str:
        verdict = {True: "stable", False: "unstable", None: "stability unknown"}[self.stable]
        radius = f", radius {self.spectral_radius:.4g}" if self.spectral_radius is not None else ""
        eps = f", eps {self.residual:.1e}" if self.residual is not None else ""
        return f"<FixedPointResult {self.name}: {self.status}, {verdict}{radius}{eps}>"

    def _repr_html_(self) -> str:
        from baslip.gait.describe import html_table

        return html_table(self)

    def summary(self) -> str:
        """A short human-readable account (as the command line prints it)."""
        from baslip.gait.describe import summary_text

        return summary_text(self)

    def to_dataframe(self):
        """The gait as a one-row pandas DataFrame (needs pandas): status, apex, control,
        phase durations [s], energy [J], residual and spectral radius, in SI units and radians."""
        try:
            import pandas
        except ImportError:
            raise ImportError("to_dataframe needs pandas: pip install pandas") from None
        row = {"name": self.name, "status": str(self.status), **self.apex, **self.control,
               **{f"duration_{phase}": value for phase, value in (self.durations or {}).items()},
               "energy": self.energy, "residual": self.residual, "spectral_radius": self.spectral_radius,
               "stable": self.stable}
        return pandas.DataFrame([row])

    def trajectory(self, strides: int = 1, samples: int = 100):
        """The continuous motion of the gait (:class:`baslip.engine.trajectory.Motion`):
        ``samples`` per phase over ``strides`` strides, from the verified apex.

        Parameters
        ----------
        strides : int
            The number of strides.
        samples : int
            Samples in each phase (the stance's two phases together get 2 * samples + 1).

        Returns
        -------
        Motion
            Time [s], positions [m], velocities [m/s], angles [rad], forces [N], ... per sample.

        Raises
        ------
        RunnerFell
            If a stride falls (as it can from a point that is not a verified fixed point).
        """
        from baslip.engine.returnmap import ReturnMap, Tolerances
        from baslip.engine.trajectory import motion

        return motion(ReturnMap(Tolerances(1e-10, 1e-10), compile=FEW_CALLS, law=self.law), self.X, self.u, self.params,
                      strides, samples)

    def plot(self, strides: int = 2):
        """A matplotlib Figure of the gait: CoM path, trunk angle and ground reaction force
        over ``strides`` strides. Writes nothing.

        Parameters
        ----------
        strides : int
            The number of strides drawn.
        """
        from baslip.viz.figures import gait_figure

        return gait_figure(self.trajectory(strides), self.name)

    def animate(self, strides: int = 2):
        """The gait over ``strides`` strides, animated: a
        :class:`~baslip.viz.animation.GaitAnimation`, which a notebook shows (an embedded
        GIF) and ``.save("gait.gif")`` writes, with or without IPython.

        Parameters
        ----------
        strides : int
            The number of strides animated.
        """
        from baslip.viz.animation import notebook_animation

        return notebook_animation(self.X, self.u, self.params, self.name, strides, self.law)

    def to_json_dict(self) -> dict:
        """The ``result.json`` record, plain JSON types: the documented keys but for
        ``provenance``, which the writer adds (:func:`baslip.files.atomic.write_result`):
        it describes the run, not the gait."""
        eigenvalues = self.eigenvalues
        return {
            "name": self.name,
            "status": self.status,
            "solver": {
                "return_status": self.solver.return_status,
                "iterations": self.solver.iterations,
                "time_s": self.solver.time_s,
                "compile_s": self.solver.compile_s,
                **({} if self.solver.spectral_bound is None else {"spectral_bound": self.solver.spectral_bound}),
                "tries": [t.to_json_dict() for t in self.solver.tries],
            },
            "params": self.params.to_dict(),
            "hip_law": self.law.name,
            "apex": self.apex,
            "control": self.control,
            "durations": None if self.durations is None else {k: float(v) for k, v in self.durations.items()},
            "energy": float(self.energy),
            "residual": None if self.residual is None else float(self.residual),
            "eigenvalues": None if eigenvalues is None else [[ev.real, ev.imag] for ev in eigenvalues],
            "spectral_radius": self.spectral_radius,
            "stable": self.stable,
            "on_bounds": [limit.to_json_dict() for limit in self.on_bounds],
            "diagnosis": None if self.diagnosis is None else self.diagnosis.to_json_dict(),
        } | self._orbit_json()

    def _orbit_json(self) -> dict:
        """Extra keys of a multi-stride orbit: its stride count, apexes and minimal period."""
        if self.strides == 1:
            return {}
        if self.orbit is None:  # the solve failed or the orbit falls
            return {"strides": self.strides, "orbit": None, "minimal_period": None}
        return {
            "strides": self.strides,
            "orbit": [APEX.to_dict(apex) for apex in self.orbit],
            "minimal_period": minimal_period(np.vstack([self.orbit, self.orbit[:1]])),
        }


class FixedPointSolver:
    """Builds the NLP and the return maps once; solves and verifies many problems.

    Parameters
    ----------
    options : ShootingOptions
        The NLP's discretisation (shooting nodes, substeps, Hessian) and IPOPT's options.
    law : HipLaw
        The stance hip law; every spec solved must be under this law.
    few_calls : bool
        True for one gait: its return maps compile at gcc's quickest level (same numbers; ``FEW_CALLS``).
    """

    def __init__(self, options: ShootingOptions = ShootingOptions(), law: HipLaw = PD, few_calls: bool = False):
        self.options = options
        self.law = law
        self._unreported_setup = setup_seconds()  # the set-up not yet reported with a solve
        self._compile = FEW_CALLS if few_calls else None
        with setting_up():
            # The engine first: on a first run its Jacobians compile on the other core while
            # the verification's map and the NLP compile on this one.
            self.residual_map = ReturnMap(Tolerances(1e-12, 1e-12), compile=self._compile, law=law)
            # The compiled engine's Jacobian at 1e-12 costs a few ms once per solve; a second
            # map at 1e-10 would cost a second build of the engine in every process.
            self.jacobian_map = self.residual_map
            self.verify_map = ReturnMap(VERIFY_TOLERANCES, "rosenbrock", self._compile, law)
            self.nlp = ShootingNLP(options, law=law)
        self._nlps: dict[tuple[int, str], ShootingNLP] = {}
        self._polish = Polish(self.residual_map, self.jacobian_map)

    def solve(self, spec: FixedPointSpec, name: str = "problem", w0: np.ndarray | None = None) -> FixedPointResult:
        """Solve ``spec`` from its guess (or from the NLP point ``w0``) and verify the answer.

        With the objective ``least_spectral_radius`` the stability NLP
        (:mod:`baslip.gait.monodromy`) starts from the periodic orbit nearest the guess
        (or from ``w0``) and minimises its bound on the multipliers; the verified radius
        is the compiled map's, and the NLP's own bound is in the solver report.

        Parameters
        ----------
        spec : FixedPointSpec
            What to solve: parameters, fixed values, guess, bounds [SI units, radians],
            objective and the orbit's strides.
        name : str
            The result's name.
        w0 : numpy.ndarray, optional
            An NLP point to start from (a neighbouring result's ``nlp_w``) instead of the guess.

        Returns
        -------
        FixedPointResult
            The verified gait, or a result whose status says why there is none.
        """
        if spec.objective in STABILITY_OBJECTIVES:
            return self._solve_stable(spec, name, w0)
        nlp = self.nlp_for(spec.strides)  # built once; its set-up is reported apart from the solve
        start = Stopwatch.start(self._unreported_setup)
        sol = self._run_nlp(nlp, spec, w0, attempt=first_try(nlp.options.hessian))
        if sol.return_status not in ACCEPTED_IPOPT and nlp.options.hessian != "exact":
            # The fast NLP drops the constraints' curvature; from a poor start the exact
            # Hessian sometimes succeeds where it fails (measured in docs/background/stability.md), so it gets
            # a second try, from the same start.
            nlp = self.nlp_for(spec.strides, exact=True)
            retry = self._run_nlp(nlp, spec, w0, attempt=IpoptAttempt(2, 2, "exact Hessian", ended(sol)))
            sol = replace(retry, iterations=sol.iterations + retry.iterations,
                          tries=sol.tries + retry.tries)
        if sol.return_status not in ACCEPTED_IPOPT:
            return self._result(spec, name, Status.FAILED, f"IPOPT: {sol.return_status}", sol, start, sol.X, sol.u,
                                diagnosis=diagnose_nlp(nlp, spec, sol))
        return self._polish_and_verify(spec, name, sol, start, nlp)

    def _solve_stable(self, spec: FixedPointSpec, name: str, w0: np.ndarray | None) -> FixedPointResult:
        if spec.strides != 1:
            raise ValueError(f"objective {spec.objective} is for one-stride orbits, not {spec.strides}")
        start = Stopwatch.start(self._unreported_setup)
        stable_nlp = self.stable_nlp()
        if w0 is None:
            orbit = self.solve(replace(spec, objective="nearest_guess"), name)
            if orbit.nlp_w is None or orbit.solver.return_status not in ACCEPTED_IPOPT:
                return replace(orbit, message=f"no periodic orbit to start the stability NLP from: {orbit.message}")
            w0 = orbit.nlp_w
        sol = self._run_nlp(stable_nlp, spec, w0, attempt=IpoptAttempt(1, 2, "stability NLP"))
        if sol.return_status != "Solve_Succeeded":  # a second try from the same start: STABLE_NLP_RETRY
            retry = self._run_nlp(stable_nlp, spec, w0, STABLE_NLP_RETRY,
                                  IpoptAttempt(2, 2, "stability NLP, IPOPT's own first Hessian", ended(sol)))
            sol = replace(min(sol, retry, key=_stable_nlp_rank), iterations=sol.iterations + retry.iterations,
                          tries=sol.tries + retry.tries)
        if sol.return_status not in ACCEPTED_IPOPT:
            return self._result(spec, name, Status.FAILED, f"IPOPT (stability NLP): {sol.return_status}", sol, start,
                                sol.X, sol.u, diagnosis=diagnose_nlp(stable_nlp, spec, sol))
        return self._polish_and_verify(spec, name, sol, start, stable_nlp)

    def stable_nlp(self) -> ShootingNLP:
        """The stability NLP (one stride, IPOPT's quasi-Newton Hessian: its exact Hessian
        would need third derivatives of the flow), built on first use. Its tolerance is at
        least :data:`STABLE_NLP_TOLERANCE`: the end is polished and verified on the
        compiled map anyway."""
        key = (1, "stable")
        if key not in self._nlps:
            ipopt: dict[str, object] = dict(self.options.ipopt)
            tol, acceptable = (float(str(ipopt.get(option, 0.0))) for option in ("tol", "acceptable_tol"))
            ipopt["tol"] = max(tol, STABLE_NLP_TOLERANCE)
            ipopt["acceptable_tol"] = max(acceptable, 100 * STABLE_NLP_TOLERANCE)
            ipopt.update(STABLE_NLP_FIRST_HESSIAN)
            options = replace(self.options, hessian="limited-memory", spectral_bound=True, ipopt=ipopt)
            with setting_up():
                self._nlps[key] = ShootingNLP(options, law=self.law)
        return self._nlps[key]

    def verify_point(self, spec: FixedPointSpec, X, u, name: str = "problem") -> FixedPointResult:
        """The same polish, independent re-simulation and stability as :meth:`solve`, for a
        point found some other way (IPOPT does not run; its report says so).

        Parameters
        ----------
        spec : FixedPointSpec
            The problem the point should solve (fixed values, bounds, strides).
        X : array_like
            The apex, shape (4,): z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s].
        u : array_like
            The controls of the solver's law, shape (controls,), SI units and radians.
        name : str
            The result's name.

        Returns
        -------
        FixedPointResult
            The polished and verified point, or a result whose status says why not.
        """
        if spec.law is not self.law:
            raise ValueError(f"this solver is built for hip law {self.law.name}, not {spec.law.name}")
        start = Stopwatch.start(self._unreported_setup)
        X, u = np.asarray(X, dtype=float), np.asarray(u, dtype=float)
        given = NlpSolution(X, u, np.full(len(PHASES), np.nan), "not run (point given)", 0, 0.0)
        return self._polish_and_verify(spec, name, given, start)

    def _polish_and_verify(self, spec: FixedPointSpec, name: str, sol: NlpSolution, start: Stopwatch,
                           nlp: ShootingNLP | None = None) -> FixedPointResult:
        """Polish IPOPT's point (``sol``, from ``nlp``: the NLP that explains a point that
        does not verify), re-simulate it independently and classify its stability."""
        X, u, iterations, note = self._polish.run_in_bounds(spec, sol.X, sol.u)
        check = self.verify_map.simulate(X, u, spec.params, spec.strides)
        if check.fall is not None:
            return self._result(spec, name, Status.NOT_VERIFIED, f"re-simulation falls: {check.fall.value}", sol, start, X, u, iterations,
                                diagnosis=diagnose_nlp(nlp, spec, sol))
        eps = _eps(check.apexes[-1], X)
        problem = self._violation(spec, X, u)
        if eps > VERIFY_EPS or problem:
            what = f"eps = {eps:.2e} > {VERIFY_EPS:g}" if eps > VERIFY_EPS else problem
            return self._result(spec, name, Status.NOT_VERIFIED, f"re-simulation: {what}{note}", sol, start, X, u, iterations, check,
                                diagnosis=diagnose_nlp(nlp, spec, sol))
        stability = classify(self.jacobian_map.jacobians(X, u, spec.params, spec.strides)[0], spec.params, u, self.law)
        message = "verified fixed point" if spec.strides == 1 else f"verified {spec.strides}-stride orbit"
        period = minimal_period(check.apexes)
        if period < spec.strides:
            message += f"; it repeats after {period} stride{'s' if period > 1 else ''}"
        return self._result(spec, name, Status.CONVERGED, message, sol, start, X, u, iterations, check, stability)

    def nlp_for(self, strides: int, exact: bool = False) -> ShootingNLP:
        """The NLP for orbits of ``strides`` strides, built on first use; ``exact`` gives
        its exact-Hessian variant, the second try after a failure.

        Parameters
        ----------
        strides : int
            The orbit's period in strides.
        exact : bool
            Whether to use the exact Hessian instead of the options' own.
        """
        options = replace(self.options, hessian="exact") if exact else self.options
        key = (strides, options.hessian)
        if key not in self._nlps:
            with setting_up():
                self._nlps[key] = self.nlp if key == (1, self.options.hessian) else ShootingNLP(options, strides, law=self.law)
        return self._nlps[key]

    def _run_nlp(self, nlp: ShootingNLP, spec: FixedPointSpec, w0, ipopt=None, attempt=IpoptAttempt()) -> NlpSolution:
        try:
            with told(attempt):
                return nlp.solve(spec, w0=w0, rmap=self.residual_map, ipopt=ipopt)
        except RuntimeError as err:  # CasADi could not even run IPOPT
            status = f"Error: {_first_line(err)}"
            return NlpSolution(spec.start_design()[: APEX.size], spec.start_design()[APEX.size :],
                               np.full(len(PHASES), np.nan), status, 0, 0.0, tries=(IpoptTry(nlp.try_settings(ipopt), status, 0),))

    # -- pieces --------------------------------------------------------------------------

    def _violation(self, spec: FixedPointSpec, X, u) -> str | None:
        """What the polished point breaks, if anything: a fixed energy or any bound."""
        energy = self.energy(X, spec.params)
        tolerance = VERIFY_EPS * max(1.0, abs(energy))
        if "energy" in spec.fixed and abs(energy - spec.fixed["energy"]) > tolerance:
            return f"apex energy {energy:.12g} J is off its fixed value {spec.fixed['energy']:g} J"
        lo, hi = spec.bounds.get("energy", (-np.inf, np.inf))
        if not lo - tolerance <= energy <= hi + tolerance:
            return f"apex energy {energy:.12g} J lies outside bounds [{lo:g}, {hi:g}] J"
        for name, value in zip(spec.design, np.concatenate([X, u])):
            lo, hi = spec.bounds_of(name)
            slack = 1e-9 * NOMINAL[name]
            if not lo - slack <= value <= hi + slack:
                return f"{name} = {value:.12g} lies outside its bounds [{lo:g}, {hi:g}]"
        return None

    def torque_effort(self, result: FixedPointResult) -> float:
        """Integral of tau^2 dt over the stance of a result's (first) stride [N^2 m^2 s].

        Parameters
        ----------
        result : FixedPointResult
            A result of this solver's law that has its phase durations [s].
        """
        assert result.durations is not None, "a result with a stance has its phase durations"
        durations = [result.durations[ph] for ph in PHASES]
        return torque_effort(self.nlp.interval, self.nlp.physics, result.X, result.u, durations, result.params)

    def energy(self, X, params: Params) -> float:
        """Total mechanical energy at apex ``X`` [J].

        Parameters
        ----------
        X : array_like
            The apex, shape (4,): z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s].
        params : Params
            The model parameters.
        """
        return self._polish.energy(X, params)

    def _report(self, sol: NlpSolution, start: Stopwatch) -> SolverReport:
        """IPOPT's account of ``sol``, timed from ``start``; the set-up so far is reported here."""
        solve_s, setup_s = start.split()
        self._unreported_setup = setup_seconds()
        return SolverReport(sol.return_status, sol.iterations, solve_s, sol.spectral_bound, sol.tries, setup_s)

    def _result(self, spec, name, status, message, sol, start, X, u, polish_iterations=0, check=None, stability=None,
                diagnosis=None):
        if check is not None and check.fall is None:
            durations = {ph: check.durations[0][ph] for ph in PHASES}
            residual, source = _eps(check.apexes[-1], X), f"independent re-simulation ({self.verify_map.describe()})"
            orbit = check.apexes[:-1] if spec.strides > 1 else None
        else:
            durations = dict(zip(PHASES, map(float, sol.durations)))
            probe = self.residual_map.simulate(X, u, spec.params, spec.strides)
            residual = _eps(probe.apexes[-1], X) if probe.fall is None else None
            source = f"return map ({self.residual_map.describe()})" if probe.fall is None else ""
            orbit = probe.apexes[:-1] if spec.strides > 1 and probe.fall is None else None
        return FixedPointResult(
            name=name,
            status=status,
            message=message,
            solver=self._report(sol, start),
            params=spec.params,
            X=np.asarray(X, dtype=float),
            u=np.asarray(u, dtype=float),
            durations=durations,
            energy=self.energy(X, spec.params),
            residual=residual,
            stability=stability,
            polish_iterations=polish_iterations,
            residual_source=source,
            nlp_w=sol.w,
            strides=spec.strides,
            orbit=orbit,
            law=self.law,
            diagnosis=diagnosis,
            on_bounds=() if status == Status.FAILED else limits_on_bounds(spec, X, u),
        )


#: IPOPT's tolerance for the stability NLP at the tightest: its quasi-Newton iterations
#: stalled short of 1e-10 (the orbit NLP's default) where 1e-6 was reached in 10 to 30
#: iterations, on the atlas's polished upright gaits.
STABLE_NLP_TOLERANCE = 1e-6
#: The stability NLP's first quasi-Newton Hessian: 1e-4 I (scaled variables). Its
#: objective (the bound s) is linear and the Lagrangian's curvature along the first steps
#: is often not positive, so IPOPT skips its updates and keeps its first matrix: with
#: IPOPT's own, I, the steps were gradient steps of 1e-4 to 1e-3, and under VPP 32 of
#: optimal_vpp_schur's 64 starts barely moved in 600 iterations (6 with 1e-4 I).
STABLE_NLP_FIRST_HESSIAN = {"limited_memory_initialization": "constant", "limited_memory_init_val": 1e-4}
#: IPOPT's settings for the second try from the same start, when the first does not
#: succeed: its own first Hessian, which on PD starts did better at some cells (neither
#: wins at every one); of two accepted ends the lower bound is kept (:func:`_stable_nlp_rank`).
STABLE_NLP_RETRY = {"limited_memory_initialization": "scalar1", "limited_memory_init_val": 1.0}


def _stable_nlp_rank(sol: NlpSolution) -> tuple[bool, float]:
    """Orders two ends of the stability NLP: accepted ones first, then the lower bound."""
    bound = sol.spectral_bound if sol.spectral_bound is not None and math.isfinite(sol.spectral_bound) else math.inf
    return sol.return_status not in ACCEPTED_IPOPT, bound


#: Relative distance below which two apexes of an orbit count as the same.
SAME_APEX = 1e-8


def minimal_period(apexes: np.ndarray) -> int:
    """Smallest k with apex k equal to apex 0, for the apexes X_0..X_N of a closed N-stride
    orbit (X_N = X_0); k divides N."""
    n = len(apexes) - 1
    for k in range(1, n):
        if n % k == 0 and _eps(apexes[k], apexes[0]) <= SAME_APEX:
            return k
    return n


def _first_line(err: Exception) -> str:
    lines = str(err).strip().splitlines()
    return lines[-1] if lines else type(err).__name__
