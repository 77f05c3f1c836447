"""Branches of BA-SLIP fixed points: the fixed-point equations as a continuation system.

A fixed point here is one of the N-stride map r^N when the problem asks for orbits of
N strides (``FixedPointSpec.strides``); its multipliers are those of r^N.

The unknowns are the free design quantities and the continuation parameter lambda, which
is a fixed quantity of the problem (a state, a control, the apex energy) or a model
parameter (m, I, k, rho0, d, g). The equations are the periodicity rows r(X, u) - X that
structure does not already imply (see :func:`baslip.gait.shooting.implied_periodicity`), plus
the apex energy when it is fixed. A branch is a curve only if there are as many free
quantities as equations; otherwise the problem must fix more (or fewer) of them.

Unknowns are scaled by :data:`baslip.model.quantities.NOMINAL` (model parameters by a tenth of
their value), so that arclength steps are balanced.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import casadi as ca
import numpy as np

from baslip.engine.returnmap import NoSecondDerivatives, ReturnMap, RunnerFell
from baslip.gait.fixedpoint import VERIFY_EPS, minimal_period
from baslip.gait.shooting import FixedPointSpec, implied_periodicity
from baslip.gait.stability import classify
from baslip.model.dynamics import APEX, PARAMS, Params, apex_energy
from baslip.model.quantities import NOMINAL
from baslip.numerics.continuation import CorrectionFailed, Point
from baslip.problem.continuation import BranchError, branch_shape, check_branch, check_parameter

#: A phase lasting less than this fraction of its flight (descent) or stance (compression,
#: decompression) counts as grazing: the branch is about to lose or gain an event.
GRAZING_FRACTION = 0.02
#: Step (scaled unknowns) of the central differences that stand in for second
#: derivatives where the stride has none (orbits of several strides; strides the
#: compiled engine cannot vouch for).
CURVATURE_STEP = 1e-6


def grazing_phase(durations: Mapping[str, float], z: float, stride: int = 1) -> str | None:
    """Which phase of a stride (``durations`` [s] by phase, from the apex at height ``z``
    [m]) is vanishing, named with its duration, or None: the whole flight (under
    :data:`GRAZING_FRACTION` of the stride: the runner barely leaves the ground), the
    descent or the ascent (under that fraction of the flight: the apex at the touchdown or
    liftoff height), or a stance phase (under that fraction of the stance)."""
    flight = durations["descent"] + durations["ascent"]
    stance = durations["compression"] + durations["decompression"]
    if flight < GRAZING_FRACTION * (flight + stance):
        return (f"grazing: the flight of stride {stride} vanishes (descent {_ms(durations['descent'])} and ascent "
                f"{_ms(durations['ascent'])} of a {_ms(flight + stance)} stride)")
    if durations["descent"] < GRAZING_FRACTION * flight:
        return (f"grazing: the apex of stride {stride} (z = {z:.6g} m) is at the touchdown height "
                f"(descent {_ms(durations['descent'])} of a {_ms(flight)} flight)")
    if durations["ascent"] < GRAZING_FRACTION * flight:
        return (f"grazing: the liftoff of stride {stride} is at the apex height: the ascent vanishes "
                f"(ascent {_ms(durations['ascent'])} of a {_ms(flight)} flight)")
    for phase in ("compression", "decompression"):
        if durations[phase] < GRAZING_FRACTION * stance:
            return f"grazing: the {phase} of stride {stride} lasts {_ms(durations[phase])} of a {_ms(stance)} stance"
    return None


#: A foot this close to the ground at apex (a fraction of rho0) touches it there: the
#: descent has vanished, and the stride may fall where the event cannot be resolved.
TOUCHING_FRACTION = 1e-9


def _touching_at_apex(X: np.ndarray, theta_td: float, params: Params) -> str | None:
    """The grazing of an orbit whose stride falls because its foot is at the ground at
    apex (clearance z - d sin(theta_h) - rho0 cos(theta_td) within
    :data:`TOUCHING_FRACTION` of rho0), or None."""
    clearance = X[0] - params.d * np.sin(X[1]) - params.rho0 * np.cos(theta_td)
    if abs(clearance) > TOUCHING_FRACTION * params.rho0:
        return None
    return f"grazing: the foot is at the ground at the apex of stride 1 (clearance {clearance:.2g} m): the descent vanishes (0 ms)"


def _ms(seconds: float) -> str:
    """A duration in milliseconds, for people."""
    return f"{1e3 * seconds:.3g} ms"


def branch_system(spec: FixedPointSpec, parameter: str, residual_map: ReturnMap, jacobian_map: ReturnMap,
                  second: str | None = None, exact: bool = True):
    """The continuation system of the problem's fixed points: :class:`FixedPointSystem`
    when the equations fix the free quantities, :class:`NearestGuessSystem` when the
    problem leaves more free and its objective picks among them. ``exact=False`` takes
    second derivatives as differences of the AD Jacobian (for cross-checks and benchmarks)."""
    _check(spec, parameter, "continuation.parameter", square=True)
    if second is not None:
        _check(spec, second, "continuation.second", square=True)
    free, equations = branch_shape(spec.fixed, spec.params, spec.law)
    if len(free) == equations:
        return FixedPointSystem(spec, parameter, residual_map, jacobian_map, second, exact=exact)
    return NearestGuessSystem(spec, parameter, residual_map, jacobian_map, second, exact=exact)


def _check(spec: FixedPointSpec, parameter: str, key: str, square: bool) -> None:
    """The problem reader's checks of a branch parameter: that it can vary, and for a
    square system that the equations fix the free quantities."""
    if square:
        check_branch(spec.fixed, spec.params, spec.objective, parameter, key, spec.law)
    else:
        check_parameter(spec.fixed, parameter, key, spec.law)


class FixedPointSystem:
    """F(v) = 0 for v = (free design quantities, lambda), all scaled.

    With a ``second`` parameter, v = (free design quantities, lambda_1, lambda_2): the
    fixed points then form a surface, on which a bifurcation curve is one more equation
    (:mod:`baslip.analysis.bifurcation`). The Jacobian has one column per parameter.

    Second derivatives (:meth:`residual_hessian`, :meth:`map_jacobian_gradient`) are
    algorithmic; with ``exact=False``, central differences of the AD Jacobian.
    """

    def __init__(self, spec: FixedPointSpec, parameter: str, residual_map: ReturnMap, jacobian_map: ReturnMap,
                 second: str | None = None, square: bool = True, exact: bool = True):
        _check(spec, parameter, "continuation.parameter", square)
        if second is not None:
            if second == parameter:
                raise BranchError("continuation.second", f"the second parameter must differ from the first ({parameter})")
            _check(spec, second, "continuation.second", square)
        self.spec, self.parameter, self.exact = spec, parameter, exact
        self.parameters = (parameter,) if second is None else (parameter, second)
        self.residual_map, self.jacobian_map = residual_map, jacobian_map
        self.design = spec.design
        self.free = [n for n in self.design if n not in spec.fixed and n not in self.parameters]
        self.rows = [n for n in APEX.names if n not in implied_periodicity(spec)]
        #: Whether the map has a multiplier 1 by the gaits' symmetry (a law of positions
        #: only), which a curve deflates from map_jacobian before it looks for its own.
        self.symmetric = spec.law.positional
        #: Whether the curves' Jacobian's derivatives are the map's own, as the normal-form
        #: coefficients need: not where a symmetry multiplier is deflated from it.
        self.normal_forms = not self.symmetric
        self.energy_row = "energy" in spec.fixed
        self.lam_scales = [self._scale_of(name) for name in self.parameters]
        self.lam_scale = self.lam_scales[0]
        self.scale = np.array([NOMINAL[n] for n in self.free] + self.lam_scales)
        X, p = APEX.sym("X"), PARAMS.sym("p")
        energy = apex_energy(X, p)
        self._energy = ca.Function("E", [X, p], [energy])
        self._energy_gradient = ca.Function("dE", [X, p], [ca.gradient(energy, X), ca.gradient(energy, p)])
        self._energy_hessian = ca.Function("d2E", [X, p], [ca.hessian(energy, ca.vertcat(X, p))[0]])
        # The lift's share of a curve's second derivatives (see map_jacobian_gradient): the
        # gradient in (X, p) of -c . dE/dX / (dE/dz), the z row of the lift contracted with c.
        c = APEX.sym("c")
        by_X = ca.gradient(energy, X)
        lifted = -ca.dot(c, by_X) / APEX.get(by_X, "z")
        self._lift_gradient = ca.Function("dlift", [X, p, c], [ca.gradient(lifted, ca.vertcat(X, p))])
        self._cache: tuple[bytes, tuple] | None = None

    def _scale_of(self, name: str) -> float:
        if name in PARAMS.names:
            value = self.start_value(name)
            return 0.1 * abs(value) if value else 0.01
        if name == "energy":  # a percent of the energy: a robot of 1 kg or a runner of 80 kg
            value = self.start_value(name)
            return 0.01 * abs(value) if value else 0.1
        return NOMINAL.get(name, 1.0)

    # -- unknowns -------------------------------------------------------------------------

    def start_value(self, name: str | None = None) -> float:
        """The problem's own value of parameter ``name`` (the first one by default)."""
        name = name or self.parameter
        if name in PARAMS.names:
            return float(getattr(self.spec.params, name))
        return float(self.spec.fixed[name])

    def pack(self, X, u, *lams: float) -> np.ndarray:
        """Scaled unknowns from an apex, a control and the parameters' values."""
        design = dict(zip(self.design, np.concatenate([X, u])))
        return np.array([design[n] for n in self.free] + list(lams)) / self.scale

    def values(self, v: np.ndarray) -> dict[str, float]:
        """The parameters' values at ``v``, by name."""
        count = len(self.parameters)
        return dict(zip(self.parameters, (float(x) for x in (v * self.scale)[-count:])))

    def unpack(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, Params, float]:
        """(apex, control, model parameters, value of the first parameter) at ``v``."""
        physical = v * self.scale
        values = dict(self.spec.fixed)
        values.update(zip(self.free, physical[: len(self.free)]))
        params = self.spec.params
        for name, value in self.values(v).items():
            if name in PARAMS.names:
                params = replace(params, **{name: value})
            elif name != "energy":
                values[name] = value
        design = np.array([values[n] for n in self.design])
        return design[: APEX.size], design[APEX.size :], params, self.values(v)[self.parameter]

    # -- equations ------------------------------------------------------------------------

    def energy(self, X, params: Params) -> float:
        """Apex energy [J]."""
        return float(self._energy(X, params.vector()))

    def _energy_target(self, v: np.ndarray) -> float:
        return self.values(v).get("energy", self.spec.fixed.get("energy", 0.0))

    def residual(self, v: np.ndarray) -> np.ndarray:
        X, u, params, _ = self.unpack(v)
        orbit = self.residual_map.simulate(X, u, params, self.spec.strides)
        if orbit.fall is not None:
            raise CorrectionFailed(f"the runner falls ({orbit.fall.value})")
        periodic = orbit.apexes[-1] - X
        rows = [periodic[APEX.index(n)] for n in self.rows]
        if self.energy_row:
            rows.append(self.energy(X, params) - self._energy_target(v))
        return np.array(rows)

    def _jacobians(self, v: np.ndarray):
        key = v.tobytes()
        if self._cache is None or self._cache[0] != key:
            X, u, params, _ = self.unpack(v)
            self._cache = (key, (X, u, params, *self._map_jacobians(X, u, params)))
        return self._cache[1]

    def _map_jacobians(self, X, u, params):
        """(dr^N/dX, dr^N/du, dr^N/dp or None) at (X, u, params)."""
        try:
            strides = self.spec.strides
            if any(name in PARAMS.names for name in self.parameters):  # one pass gives all three
                return self.jacobian_map.all_jacobians(X, u, params, strides)
            return (*self.jacobian_map.jacobians(X, u, params, strides), None)
        except RunnerFell as err:
            raise CorrectionFailed(f"the runner falls ({err.fall.value})") from None

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        """dF/dv, scaled: one column per free quantity, then one per parameter."""
        X, u, params, dr_dX, dr_du, dr_dp = self._jacobians(v)
        full = np.hstack([dr_dX - np.eye(APEX.size), dr_du])  # d(r - X)/d(X, u)
        rows = [APEX.index(n) for n in self.rows]
        columns = [self.design.index(n) for n in self.free]
        jac = full[np.ix_(rows, columns)]
        for name in self.parameters:
            if name in PARAMS.names:
                lam_column = dr_dp[rows, PARAMS.index(name)]
            elif name == "energy":
                lam_column = np.zeros(len(rows))
            else:
                lam_column = full[rows, self.design.index(name)]
            jac = np.column_stack([jac, lam_column])
        if self.energy_row:
            by_X, by_p = (np.asarray(g).ravel() for g in self._energy_gradient(X, params.vector()))
            energy = np.concatenate([by_X, np.zeros(len(u))])
            lam_energy = []
            for name in self.parameters:
                if name == "energy":
                    lam_energy.append(-1.0)
                elif name in PARAMS.names:
                    lam_energy.append(by_p[PARAMS.index(name)])
                else:
                    lam_energy.append(energy[self.design.index(name)])
            jac = np.vstack([jac, np.concatenate([energy[columns], lam_energy])])
        return jac * self.scale

    # -- the map itself, for bifurcation curves -------------------------------------------

    def dynamic_coordinates(self, u, params: Params) -> tuple[str, ...]:
        """Apex coordinates in which the map has no multiplier that is 1 by energy or spin.

        With a hip torque, all four. Without one, energy is conserved: z follows from the
        energy and the others, so it is left out; with d = 0 as well, the trunk spins
        freely and only ydot is left. On these coordinates (at the orbit's energy) a
        multiplier at +1, -1 or on the unit circle is a bifurcation of the map, never
        structure (see :mod:`baslip.gait.stability`).
        """
        law = self.spec.law
        if not law.torque_free(law.control_dict(u)):
            return APEX.names
        return ("ydot", "theta_h", "theta_h_dot") if params.d != 0.0 else ("ydot",)

    def crossing_veto(self, kind: str, a: Point, b: Point) -> bool:
        """Sign changes between branch points ``a`` and ``b`` that are no ``kind`` point: on
        symmetric gaits, a fold (:func:`baslip.numerics.continuation.test_functions`) whose
        count of complex pairs changes, a pair meeting at +1 (at r_vpp = 0, where the trunk
        spins freely) rather than a real multiplier crossing it."""
        return kind == "fold" and self.symmetric and a.tests["complex_pairs"] != b.tests["complex_pairs"]

    def map_jacobian(self, v: np.ndarray, shift: np.ndarray | None = None) -> np.ndarray:
        """Jacobian of the N-stride map on :meth:`dynamic_coordinates`, at the orbit's
        start displaced by ``shift`` (in those coordinates, physical units) at the same
        energy and control: the matrix whose multipliers decide the curves (after they
        deflate a symmetry multiplier, :attr:`symmetric`), and (through ``shift``) the
        map's higher derivatives for the normal-form coefficients."""
        X, u, params, _ = self.unpack(v)
        names = self.dynamic_coordinates(u, params)
        index = [APEX.index(n) for n in names]
        lifted = self._lift(X, index, shift, params, len(names) < APEX.size)
        dr_dX = self._jacobians(v)[3] if shift is None else self._map_jacobians(lifted, u, params)[0]
        return dr_dX[index, :] @ self._lift_jacobian(lifted, index, params, len(names) < APEX.size)

    def _lift(self, X, index, shift, params, conserved: bool) -> np.ndarray:
        """The apex at dynamic coordinates X[index] + shift: z moves to keep the energy
        (exactly, as the apex energy is affine in z) when energy is conserved."""
        if shift is None:
            return np.asarray(X, dtype=float)
        lifted = np.array(X, dtype=float)
        lifted[index] += shift
        if conserved:
            z = APEX.index("z")
            slope = float(self._energy_gradient(lifted, params.vector())[0][z])
            lifted[z] += (self.energy(X, params) - self.energy(lifted, params)) / slope
        return lifted

    def _lift_jacobian(self, X, index, params, conserved: bool) -> np.ndarray:
        """d(apex)/d(dynamic coordinates) at ``X``: 4 x k."""
        lift = np.eye(APEX.size)[:, index]
        if conserved:
            gradient = np.asarray(self._energy_gradient(X, params.vector())[0]).ravel()
            z = APEX.index("z")
            lift[z, :] -= gradient[index] / gradient[z]
        return lift

    # -- second derivatives, for curves and the nearest-guess family ----------------------

    def residual_hessian(self, v: np.ndarray, weights: np.ndarray, columns) -> np.ndarray:
        """d^2 (weights . F) / dv dv[columns], scaled: len(v) x len(columns).

        Exact for one-stride orbits: the stride's Hessian-vector products
        (:meth:`baslip.engine.returnmap.ReturnMap.hessian_vectors`, one per column) and the
        apex energy's Hessian. Orbits of several strides, and strides the compiled engine
        cannot vouch for, take central differences of :meth:`jacobian` instead.
        """
        columns = list(columns)
        X, u, params, _ = self.unpack(v)
        to_z = self._to_z()
        w = np.zeros(APEX.size)
        w[[APEX.index(n) for n in self.rows]] = weights[: len(self.rows)]
        try:
            product = self._second_derivatives(self.jacobian_map.hessian_vectors, X, u, params, w, to_z[:, columns])
        except NoSecondDerivatives:
            return np.column_stack([weights @ self._differenced(self.jacobian, v, j) for j in columns])
        if self.energy_row:
            by_X_p = np.asarray(self._energy_hessian(X, params.vector()))
            energy = np.zeros((len(to_z), len(to_z)))
            at = np.r_[: APEX.size, len(to_z) - PARAMS.size : len(to_z)]
            energy[np.ix_(at, at)] = by_X_p
            product = product + weights[-1] * energy @ to_z[:, columns]
        return to_z.T @ product

    def map_jacobian_gradient(self, v: np.ndarray, seed: np.ndarray) -> np.ndarray:
        """The gradient in v (scaled) of <seed, map_jacobian(v)>, seed k x k on
        :meth:`dynamic_coordinates`: the derivative that a bifurcation curve's test
        function needs. Exact as :meth:`residual_hessian` is (with the same fallback).

        map_jacobian = P J L, with J = dr/dX, P the rows of the dynamic coordinates and L
        the lift (which moves z to keep the energy where it is conserved). So the seed on J
        is P^T seed L^T, one reverse sweep through the stride's AD Jacobian
        (:meth:`baslip.engine.returnmap.ReturnMap.jacobian_gradient`); L's own dependence
        on X and p is the energy's algebra.
        """
        X, u, params, _ = self.unpack(v)
        names = self.dynamic_coordinates(u, params)
        index = [APEX.index(n) for n in names]
        conserved = len(names) < APEX.size
        on_J = np.zeros((APEX.size, APEX.size))
        on_J[index, :] = seed @ self._lift_jacobian(X, index, params, conserved).T
        try:
            gradient = self._second_derivatives(self.jacobian_map.jacobian_gradient, X, u, params, on_J)
        except NoSecondDerivatives:
            return np.array([np.sum(seed * self._differenced(self.map_jacobian, v, j)) for j in range(len(v))])
        if conserved:
            contracted = self._jacobians(v)[3][index, :].T @ seed  # <seed, P J L> = <contracted, L>
            c = np.zeros(APEX.size)
            c[index] = contracted[APEX.index("z")]
            by_X_p = np.asarray(self._lift_gradient(X, params.vector(), c)).ravel()
            gradient[: APEX.size] += by_X_p[: APEX.size]
            gradient[-PARAMS.size :] += by_X_p[APEX.size :]
        return self._to_z().T @ gradient

    def _second_derivatives(self, of_the_map, *args) -> np.ndarray:
        """``of_the_map(*args)``: the jacobian map's :meth:`ReturnMap.hessian_vectors` or
        :meth:`ReturnMap.jacobian_gradient`; NoSecondDerivatives for orbits of several
        strides, or where differences were asked for."""
        if self.spec.strides != 1 or not self.exact:
            raise NoSecondDerivatives("second derivatives are differenced (orbits of several strides, or asked)")
        try:
            return of_the_map(*args)
        except RunnerFell as err:
            raise CorrectionFailed(f"the runner falls ({err.fall.value})") from None

    def _to_z(self) -> np.ndarray:
        """dz/dv: the stride's inputs z = (X, u, p) per scaled unknown (an apex energy
        parameter moves none of them)."""
        to_z = np.zeros((len(self.design) + PARAMS.size, len(self.scale)))
        for j, name in enumerate([*self.free, *self.parameters]):
            if name in PARAMS.names:
                to_z[len(self.design) + PARAMS.index(name), j] = self.scale[j]
            elif name != "energy":
                to_z[self.design.index(name), j] = self.scale[j]
        return to_z

    @staticmethod
    def _differenced(matrix_at, v: np.ndarray, j: int) -> np.ndarray:
        """d matrix_at(v) / dv_j by central differences (step :data:`CURVATURE_STEP`)."""
        step = np.zeros(len(v))
        step[j] = CURVATURE_STEP
        return (matrix_at(v + step) - matrix_at(v - step)) / (2 * CURVATURE_STEP)

    def verification_failure(self, v: np.ndarray, verify_map: ReturnMap) -> str | None:
        """Why ``v`` is not a verified orbit of its period, or None if it is.

        ``verify_map`` re-simulates the orbit independently and must give eps <= 1e-10, as
        for any reported fixed point; an orbit of N > 1 strides must not repeat sooner (it
        would belong to a branch of shorter orbits).
        """
        X, u, params, _ = self.unpack(v)
        strides = self.spec.strides
        check = verify_map.simulate(X, u, params, strides)
        if check.fall is not None:
            return f"the runner falls ({check.fall.value})"
        eps = float(np.linalg.norm(check.apexes[-1] - X) / np.linalg.norm(X))
        if eps > VERIFY_EPS:
            return f"not verified (eps = {eps:.1e})"
        period = minimal_period(check.apexes)
        if period < strides:
            return f"the orbit repeats after {period} of its {strides} strides"
        return None

    def grazing(self, v: np.ndarray) -> str | None:
        """If the orbit at ``v`` is close to grazing, which phase vanishes and how long it
        lasts (see :func:`grazing_phase`). None otherwise (or if the orbit falls)."""
        X, u, params, _ = self.unpack(v)
        orbit = self.residual_map.simulate(X, u, params, self.spec.strides)
        if orbit.fall is not None:
            return _touching_at_apex(X, self.spec.law.control_dict(u)["theta_td"], params)
        for k, durations in enumerate(orbit.durations):
            found = grazing_phase(durations, orbit.apexes[k][0], k + 1)
            if found:
                return found
        return None

    def multipliers(self, v: np.ndarray) -> tuple[np.ndarray, list[bool]]:
        _, u, params, dr_dX, _, _ = self._jacobians(v)
        stability = classify(dr_dX, params, u, self.spec.law)
        return np.array([m.value for m in stability.multipliers]), [m.trivial for m in stability.multipliers]


class NearestGuessSystem:
    """The family of fixed points that the ``nearest_guess`` objective picks.

    When a problem leaves more quantities free than there are fixed-point equations (a
    sweep over (ydot, z) with the gains free, like grid_downward), the fixed points at
    given parameters form a manifold, and the NLP picks the one nearest the guess in
    scaled units. Those points are the solutions of the optimality conditions::

        F(w, lambda) = 0,    2 (w - g) + dF/dw^T mu = 0

    (w the free quantities scaled by :data:`baslip.model.quantities.NOMINAL`, g the guess, mu
    the Lagrange multipliers), which this system follows: v = (w, mu, parameters). The
    first rows and all derivatives of F are algorithmic, the Lagrangian's curvature
    d(dF/dw^T mu)/dv included (:meth:`FixedPointSystem.residual_hessian`).
    Bounds are not part of the conditions: a point outside them is refused.

    The fixed point itself, its multipliers and its verification are those of the
    underlying :class:`FixedPointSystem`; only the unknowns differ.
    """

    def __init__(self, spec: FixedPointSpec, parameter: str, residual_map: ReturnMap, jacobian_map: ReturnMap,
                 second: str | None = None, exact: bool = True):
        self.fixed_points = FixedPointSystem(spec, parameter, residual_map, jacobian_map, second, square=False,
                                             exact=exact)
        points = self.fixed_points
        self.spec, self.parameter, self.parameters = spec, parameter, points.parameters
        self.lam_scales, self.lam_scale = points.lam_scales, points.lam_scale
        self.normal_forms, self.symmetric = points.normal_forms, points.symmetric
        self.n_free, self.n_equations = len(points.free), len(points.rows) + points.energy_row
        design = dict(zip(spec.design, spec.start_design()))
        self.target = np.array([design[n] for n in points.free]) / points.scale[: self.n_free]
        # v holds mu / multiplier_scale, set by pack so that mu moves no faster along the
        # family than the rest: arclength steps then advance the parameters.
        self.multiplier_scale = 1.0

    def _inner(self, v: np.ndarray) -> np.ndarray:
        """The fixed-point unknowns (w, parameters) of ``v``."""
        return np.concatenate([v[: self.n_free], v[self.n_free + self.n_equations :]])

    def _multipliers_of(self, v: np.ndarray) -> np.ndarray:
        """The Lagrange multipliers mu at ``v``."""
        return self.multiplier_scale * v[self.n_free : self.n_free + self.n_equations]

    # -- unknowns ---------------------------------------------------------------------------

    def start_value(self, name: str | None = None) -> float:
        return self.fixed_points.start_value(name)

    def pack(self, X, u, *lams: float) -> np.ndarray:
        """Unknowns at a fixed point, with the Lagrange multipliers that fit it best; with
        one parameter, then corrected onto the family with the parameter held."""
        inner = self.fixed_points.pack(X, u, *lams)
        gradient = 2 * (inner[: self.n_free] - self.target)
        J = self.fixed_points.jacobian(inner)[:, : self.n_free]
        mu = np.linalg.lstsq(J.T, -gradient, rcond=None)[0]
        self.multiplier_scale = 1.0
        v = np.concatenate([inner[: self.n_free], mu, inner[self.n_free :]])
        # The family's directions (null space of the Jacobian, k x len(v)): mu's fastest
        # speed per unit speed of the parameters, over all directions.
        count = len(self.parameters)
        null = np.linalg.svd(self.jacobian(v))[2][-count:]
        columns = slice(self.n_free, self.n_free + self.n_equations)
        per_parameter = np.linalg.solve(null[:, -count:], null[:, columns])  # d mu / d parameters
        self.multiplier_scale = max(1.0, float(np.linalg.norm(per_parameter, 2)))
        v[columns] /= self.multiplier_scale
        if len(self.parameters) == 1:
            from baslip.numerics.continuation import Settings, correct

            held = np.zeros(len(v))
            held[-1] = 1.0
            v, _ = correct(self, v, held, Settings(max_newton=20))
        return v

    def values(self, v: np.ndarray) -> dict[str, float]:
        return self.fixed_points.values(self._inner(v))

    def unpack(self, v: np.ndarray):
        return self.fixed_points.unpack(self._inner(v))

    def energy(self, X, params: Params) -> float:
        return self.fixed_points.energy(X, params)

    # -- equations --------------------------------------------------------------------------

    def _stationarity(self, inner: np.ndarray, mu: np.ndarray) -> np.ndarray:
        J = self.fixed_points.jacobian(inner)[:, : self.n_free]
        return 2 * (inner[: self.n_free] - self.target) + J.T @ mu

    def residual(self, v: np.ndarray) -> np.ndarray:
        inner = self._inner(v)
        F = self.fixed_points.residual(inner)
        return np.concatenate([F, self._stationarity(inner, self._multipliers_of(v))])

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        inner, mu = self._inner(v), self._multipliers_of(v)
        J = self.fixed_points.jacobian(inner)
        n, m = self.n_free, self.n_equations
        # d(dF/dw^T mu)/dv: the rows of the Hessian of mu . F that belong to w, which by
        # its symmetry are its columns, transposed.
        curvature = self.fixed_points.residual_hessian(inner, mu, range(n)).T
        curvature[:, :n] += 2 * np.eye(n)
        top = np.hstack([J[:, :n], np.zeros((m, m)), J[:, n:]])
        bottom = np.hstack([curvature[:, :n], self.multiplier_scale * J[:, :n].T, curvature[:, n:]])
        return np.vstack([top, bottom])

    def multipliers(self, v: np.ndarray):
        return self.fixed_points.multipliers(self._inner(v))

    def map_jacobian(self, v: np.ndarray, shift: np.ndarray | None = None) -> np.ndarray:
        return self.fixed_points.map_jacobian(self._inner(v), shift)

    def map_jacobian_gradient(self, v: np.ndarray, seed: np.ndarray) -> np.ndarray:
        """As :meth:`FixedPointSystem.map_jacobian_gradient`; the map does not depend on
        the Lagrange multipliers."""
        inner = self.fixed_points.map_jacobian_gradient(self._inner(v), seed)
        return np.concatenate([inner[: self.n_free], np.zeros(self.n_equations), inner[self.n_free :]])

    def crossing_veto(self, kind: str, a: Point, b: Point) -> bool:
        return self.fixed_points.crossing_veto(kind, a, b)

    def verification_failure(self, v: np.ndarray, verify_map: ReturnMap) -> str | None:
        """As :meth:`FixedPointSystem.verification_failure`, and inside the bounds."""
        X, u, _, _ = self.unpack(v)
        for name, value in zip(self.spec.design, np.concatenate([X, u])):
            lo, hi = self.spec.bounds_of(name)
            if not lo <= value <= hi:
                return f"{name} = {value:.6g} leaves its bounds [{lo:.6g}, {hi:.6g}]"
        return self.fixed_points.verification_failure(self._inner(v), verify_map)

    def grazing(self, v: np.ndarray) -> str | None:
        return self.fixed_points.grazing(self._inner(v))
