"""The apex-to-apex return map r(X, u), its Jacobians, and multi-stride simulation.

One stride: apex -> descent -> touchdown -> compression -> bottom -> decompression ->
liftoff -> ascent -> apex. Two engines compute it:

* the **compiled engine** (:mod:`baslip.engine.driver`, the default): fixed-step order-8 flows
  generated as C, with an error estimate that must stay within the tolerance;
* the **event map** (:mod:`baslip.engine.eventmap`): CasADi's adaptive ``erk`` or ``rosenbrock``
  integrators with zero-crossing events. It serves tolerances tighter than the compiled
  engine guarantees, the independent verification, and every stride the compiled engine
  cannot vouch for (it is then built on first use).

Falls are outcomes, not exceptions: :meth:`ReturnMap.stride` returns a :class:`Stride`
whose ``fall`` names the reason, and :meth:`ReturnMap.simulate` stops there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from baslip.engine import arguments
from baslip.engine.eventmap import EventMap
from baslip.engine.outcome import (  # noqa: F401  (re-exported: the public names of the return map)
    PHASES,
    Fall,
    NoSecondDerivatives,
    RunnerFell,
    Simulation,
    Stride,
    Tolerances,
    param_vector,
    precheck,
    touchdown_guess,
    vec,
)
from baslip.errors import ArgumentError, InputError
from baslip.model.catalogue.ba_slip import COLLAPSE_FRACTION  # noqa: F401  (re-exported)
from baslip.model.dynamics import APEX, PARAMS, STANCE
from baslip.model.hiplaw import HIP_LAWS, PD, HipLaw

#: The compiled engine's error bound is met down to this tolerance; tighter ones use the
#: adaptive event map.
COMPILED_TIGHTEST = 1e-12
#: Plugin name of the compiled engine.
COMPILED = "compiled"
#: Every engine a map can run on: the compiled engine and CasADi's integrators.
PLUGINS = (COMPILED, "erk", "rosenbrock")
#: The most terms of a seed that :meth:`ReturnMap.jacobian_gradient` takes as
#: Hessian-vector products (one round on two threads); fuller seeds take one seeded sweep.
PARALLEL_TERMS = 2

if TYPE_CHECKING:
    from baslip.engine.batch import BatchEngine


def _named_law(name: object, law: HipLaw) -> HipLaw:
    """The law called ``name``; ``law``, if not the default, must be that one."""
    if not isinstance(name, str) or name not in HIP_LAWS:
        raise InputError("hip_law", f"expected one of {', '.join(HIP_LAWS)}, got {name!r}")
    if law is not PD and law is not HIP_LAWS[name]:
        raise InputError("hip_law", f"{name!r} contradicts law={law.name!r}; give one of them")
    return HIP_LAWS[name]


def _check_settings(tolerances: object, plugin: object, compile: object, law: object) -> None:
    """Refuse a map's settings that are not of their kind: tolerances that are not finite
    and positive, an unknown plugin, a compile switch or law of the wrong type."""
    if not isinstance(tolerances, Tolerances):
        raise ArgumentError("tolerances", f"expected a Tolerances, got {type(tolerances).__name__}")
    for name in ("rtol", "atol"):
        value = getattr(tolerances, name)
        if not (isinstance(value, (int, float)) and not isinstance(value, bool) and 0.0 < value < 1.0):
            raise ArgumentError(f"tolerances.{name}", f"expected a number between 0 and 1, got {arguments.shown(value)}")
    if plugin is not None and plugin not in PLUGINS:
        raise ArgumentError("plugin", f"expected one of {', '.join(PLUGINS)}, got {arguments.shown(plugin)}")
    if compile is not None and not isinstance(compile, (bool, str)):
        raise ArgumentError("compile", f"expected True, False, None or a mode, got {arguments.shown(compile)}")
    if not isinstance(law, HipLaw):
        raise ArgumentError("law", f"expected a HipLaw, got {type(law).__name__}")


class ReturnMap:
    """The apex return map of the BA-SLIP under a hip law (PD by default), built once per tolerance.

    ``plugin`` is ``"compiled"`` (the default for tolerances down to 1e-12), ``"erk"`` (the
    default below that) or ``"rosenbrock"``. ``compile`` forces the C route (of the
    compiled engine, or of an event map's strides) on or off; None follows
    ``BASLIP_NO_COMPILE``.

    Throughout, ``X`` is an apex (z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s]),
    ``u`` a control vector of the law (PD: Kp [N m/rad], Kd [N m s/rad], theta2_des [rad],
    theta2_dot_des [rad/s], theta_td [rad]; VPP: r_vpp [m], theta_td [rad]) and ``params``
    a :class:`~baslip.model.dynamics.Params` or its vector (m, I, k, rho0, d, g).

    Parameters
    ----------
    tolerances : Tolerances
        The integrators' tolerances (default 1e-10 relative and absolute).
    plugin : str, optional
        The engine: ``"compiled"``, ``"erk"`` or ``"rosenbrock"``; by default the compiled
        engine down to 1e-12, ``"erk"`` below. Raises
        :class:`~baslip.errors.ArgumentError` for another name, or for the compiled
        engine below 1e-12.
    compile : bool or str, optional
        Force the C route on or off; None follows ``BASLIP_NO_COMPILE``, and so does
        :data:`~baslip.engine.codegen.FEW_CALLS`, for a map that the run calls only a few
        times (one gait's polish, check and multipliers): its libraries then compile at
        gcc's quickest level unless the cache holds them at their own (same numbers).
    law : HipLaw
        The stance hip law whose controls ``u`` holds.
    hip_law : str, optional
        The law by its name in problem files, ``"pd"`` or ``"vpp"``, instead of ``law``;
        an unknown name raises :class:`~baslip.errors.InputError` naming the known ones.

    Examples
    --------
    >>> rmap = ReturnMap()
    >>> stride = rmap.stride(X, u, Params())     # numeric, with fall detection
    >>> A, B = rmap.jacobians(X, u, Params())    # dr/dX (4x4) and dr/du (4x5)
    >>> A2, B2 = rmap.jacobians(X, u, Params(), strides=2)   # of r(r(X, u), u)
    >>> vpp_map = ReturnMap(hip_law="vpp")              # u = (r_vpp, theta_td)
    """

    def __init__(self, tolerances: Tolerances = Tolerances(), plugin: str | None = None,
                 compile: bool | str | None = None, law: HipLaw = PD, *, hip_law: str | None = None):
        if hip_law is not None:
            law = _named_law(hip_law, law)
        _check_settings(tolerances, plugin, compile, law)
        self.tolerances = tolerances
        self.law = law
        tolerance = min(tolerances.rtol, tolerances.atol)
        if plugin is None:
            plugin = COMPILED if tolerance >= COMPILED_TIGHTEST else "erk"
        if plugin == COMPILED and tolerance < COMPILED_TIGHTEST:
            raise ArgumentError("plugin", f"the compiled engine guarantees tolerances down to {COMPILED_TIGHTEST:g}, "
                                f"not {tolerance:g}")
        self.plugin = plugin
        self._compiled = None
        if plugin == COMPILED:
            from baslip.engine.driver import CompiledEngine  # the compiled engine is loaded only when used

            self._compiled = CompiledEngine(tolerance, compile, law)
        self._events = None if plugin == COMPILED else EventMap(tolerances, plugin, compile, law)
        self._compile = compile
        self._batch: BatchEngine | None = None  # the batched compiled engine, built on first use
        self.fallbacks = 0  # strides the compiled engine handed to the event map

    @property
    def event_map(self) -> EventMap:
        """The adaptive event map at this map's tolerances (built on first use)."""
        if self._events is None:
            self._events = EventMap(self.tolerances, "erk", self._compile, self.law)
        return self._events

    @property
    def compiled_engine(self):
        """The compiled engine (:class:`baslip.engine.driver.CompiledEngine`), or None for an
        event-map plugin."""
        return self._compiled

    def describe(self) -> str:
        """One phrase naming the engine and its tolerance."""
        if self.plugin == COMPILED:
            assert self._compiled is not None
            return f"compiled DOP853, error estimate <= {self._compiled.tolerance:g}"
        return f"{self.plugin}, rtol = {self.tolerances.rtol:g}, atol = {self.tolerances.atol:g}"

    # -- one stride ------------------------------------------------------------------

    def stride(self, X, u, params) -> Stride:
        """One apex-to-apex stride from apex ``X`` under control ``u`` with ``params``.

        Parameters
        ----------
        X : array_like
            The apex, shape (4,).
        u : array_like
            The control vector, shape (controls,).
        params : Params or array_like
            The model parameters, or their vector, shape (6,).

        Returns
        -------
        Stride
            The next apex and the phase durations [s], or the fall.
        """
        X, u, p = self._point(X, u, params)
        fallen, t_guess = precheck(X, u, p)
        if fallen is not None:
            return fallen
        if self._compiled is not None:
            result = self._compiled.stride(X, u, p, t_guess)
            if result is not None:
                return result
            self.fallbacks += 1
        return self.event_map.stride(X, u, p, t_guess)

    def _point(self, X, u, params, apex: str = "X") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(X, u, p) as flat float vectors, checked: 4 apex values, the law's controls and
        the 6 parameters; raises :class:`~baslip.errors.ArgumentError` naming the argument."""
        return (arguments.vector(X, apex, APEX.size), arguments.vector(u, "u", self.law.controls.size),
                arguments.parameters(params))

    def __call__(self, X, u, params) -> np.ndarray:
        """r(X, u): the next apex; raises :class:`RunnerFell` if the stride falls."""
        result = self.stride(X, u, params)
        if result.fall is not None:
            raise RunnerFell(result.fall)
        assert result.apex is not None
        return result.apex

    def _stride_jacobian(self, X, u, p, with_parameters: bool) -> tuple[np.ndarray, np.ndarray]:
        """One stride's Jacobian in (X, u) or (X, u, p), and the next apex; raises
        :class:`RunnerFell` if it falls."""
        fallen, t_guess = precheck(X, u, p)
        if fallen is not None:
            assert fallen.fall is not None
            raise RunnerFell(fallen.fall)
        answer = None
        if self._compiled is not None:
            answer = self._compiled.stride_jacobian(X, u, p, t_guess)
            if answer is None:
                self.fallbacks += 1
        if answer is None:
            answer = self.event_map.stride_jacobian(X, u, p, t_guess, with_parameters)
        jac, outcome = answer
        if outcome.fall is not None:
            raise RunnerFell(outcome.fall)
        assert outcome.apex is not None and jac is not None  # a stride that did not fall has both
        return jac[:, : APEX.size + self.law.controls.size + (PARAMS.size if with_parameters else 0)], outcome.apex

    def hessian_vectors(self, X, u, params, W, S) -> np.ndarray:
        """Second derivatives of one stride: column k is H_k S[:, k], with H_k the Hessian of
        the scalar W[:, k] . r in z = (X, u, p), by algorithmic differentiation of the
        compiled stride (reverse over forward mode, through the event times), the columns
        shared between two threads.

        Parameters
        ----------
        X : array_like
            The apex, shape (4,).
        u : array_like
            The control vector, shape (controls,).
        params : Params or array_like
            The model parameters, or their vector, shape (6,).
        W : array_like
            Weights of the next apex's coordinates, shape (4, K), or (4,) for every
            column, in their inverse units.
        S : array_like
            Directions in z, shape (4 + controls + 6, K), in z's units.

        Returns
        -------
        numpy.ndarray
            Shape (4 + controls + 6, K). By the Hessians' symmetry, column k is also the
            gradient in z of W[:, k] . (dr/dz S[:, k]). Raises
            :class:`RunnerFell` if the stride falls and :class:`NoSecondDerivatives` where
            the compiled engine cannot vouch for it (or this map is an event map), as its
            Jacobian then comes from another integrator.
        """
        X, u, params = self._point(X, u, params)
        S, W = self._directions_and_weights(S, W)
        if not S.shape[1]:  # no directions: nothing to evaluate
            return np.zeros((len(S), 0))
        return self._second_derivatives(lambda engine, X, u, p, t_guess: engine.stride_hessian_vectors(
            X, u, p, t_guess, W, S), X, u, params)

    def _directions_and_weights(self, S, W) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`hessian_vectors`'s S as (nz, K) and W as (4, K), checked."""
        S = arguments.columns(S, "S", APEX.size + self.law.controls.size + PARAMS.size)
        W = arguments.columns(W, "W", APEX.size)
        if W.shape[1] not in (1, S.shape[1]):
            raise ArgumentError("W", f"expected shape ({APEX.size},) or ({APEX.size}, {S.shape[1]}), got {W.shape}")
        return S, np.broadcast_to(W, (APEX.size, S.shape[1]))

    def jacobian_gradient(self, X, u, params, G) -> np.ndarray:
        """The gradient in z = (X, u, p) of <G, dr/dX> = sum(G * dr/dX) for a 4 x 4 seed G:
        second derivatives of one stride, through the event times. A seed of rank one or
        two (a fold's or period doubling's psi phi^T) takes one Hessian-vector product a
        term, the terms s_k a_k b_k^T of its singular value decomposition in parallel
        threads (H(s_k a_k . r) along (b_k, 0, 0)); a fuller one the Jacobian's four
        forward directions and one reverse sweep, a single call that costs about two
        products (and leaves the other core to a second worker).

        Parameters
        ----------
        X, u, params
            As :meth:`hessian_vectors`.
        G : array_like
            The seed, shape (4, 4), in the units of X over r's rows.

        Returns
        -------
        numpy.ndarray
            Shape (4 + controls + 6,); raises as :meth:`hessian_vectors`.
        """
        G = arguments.rows(G, "G", APEX.size, most=APEX.size)
        if G.shape != (APEX.size, APEX.size) or not np.isfinite(G).all():
            raise ArgumentError("G", f"expected a finite ({APEX.size}, {APEX.size}) seed, got shape {G.shape}")
        X, u, params = self._point(X, u, params)
        left, sizes, right = np.linalg.svd(G)
        kept = sizes > 1e-14 * sizes[0] if sizes[0] > 0 else np.zeros(len(sizes), dtype=bool)  # a zero seed keeps none
        if kept.sum() > PARALLEL_TERMS:
            return self._second_derivatives(lambda engine, X, u, p, t_guess: engine.stride_jacobian_gradient(
                X, u, p, t_guess, G), X, u, params)
        directions = np.zeros((APEX.size + self.law.controls.size + PARAMS.size, int(kept.sum())))
        directions[: APEX.size] = right[kept].T
        return self.hessian_vectors(X, u, params, left[:, kept] * sizes[kept], directions).sum(axis=1)

    def _second_derivatives(self, of_the_engine, X, u, params):
        """``of_the_engine(engine, X, u, p, t_guess)`` on the compiled engine, or the
        exceptions :meth:`hessian_vectors` names."""
        X, u, p = self._point(X, u, params)
        fallen, t_guess = precheck(X, u, p)
        if fallen is not None:
            assert fallen.fall is not None
            raise RunnerFell(fallen.fall)
        product = None if self._compiled is None else of_the_engine(self._compiled, X, u, p, t_guess)
        if product is None:
            raise NoSecondDerivatives("the compiled engine cannot vouch for this stride")
        return product

    # -- Jacobians of r^n ------------------------------------------------------------

    def jacobians(self, X, u, params, strides: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """(dr/dX, dr/du) by algorithmic differentiation through the event times.

        With ``strides = n`` these are the Jacobians of the n-stride map r^n (the same
        control every stride), by the chain rule: dr^n/dX is the product of the strides'
        dr/dX. Raises :class:`RunnerFell` if a stride falls: there is no Jacobian then.

        Parameters
        ----------
        X : array_like
            The apex, shape (4,).
        u : array_like
            The control vector, shape (controls,), the same every stride.
        params : Params or array_like
            The model parameters, or their vector, shape (6,).
        strides : int
            The number n of strides of the map r^n.

        Returns
        -------
        tuple of numpy.ndarray
            dr^n/dX, shape (4, 4), and dr^n/du, shape (4, controls) (4 x 5 under PD).
        """
        dX, du, _ = self._chained_jacobians(X, u, params, strides, with_parameters=False)
        return dX, du

    def linearised_stride(self, X, u, params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dr/dX, dr/du, the next apex) of one stride, from one pass; raises
        :class:`RunnerFell` if it falls.

        Parameters
        ----------
        X : array_like
            The apex, shape (4,).
        u : array_like
            The control vector, shape (controls,).
        params : Params or array_like
            The model parameters, or their vector, shape (6,).

        Returns
        -------
        tuple of numpy.ndarray
            dr/dX, shape (4, 4); dr/du, shape (4, controls); the next apex, shape (4,).
        """
        jac, apex = self._stride_jacobian(*self._point(X, u, params), with_parameters=False)
        return jac[:, : APEX.size], jac[:, APEX.size :], apex

    def parameter_jacobian(self, X, u, params, strides: int = 1) -> np.ndarray:
        """dr^n/dp (4 x 6) with respect to the model parameters (m, I, k, rho0, d, g).

        Parameters
        ----------
        X : array_like
            The apex, shape (4,).
        u : array_like
            The control vector, shape (controls,), the same every stride.
        params : Params or array_like
            The model parameters, or their vector, shape (6,).
        strides : int
            The number n of strides of the map r^n.

        Returns
        -------
        numpy.ndarray
            dr^n/dp, shape (4, 6), in the apex's and the parameters' SI units.
        """
        return self.all_jacobians(X, u, params, strides)[2]

    def all_jacobians(self, X, u, params, strides: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dr^n/dX, dr^n/du, dr^n/dp) from one pass over the strides.

        Parameters
        ----------
        X : array_like
            The apex, shape (4,).
        u : array_like
            The control vector, shape (controls,), the same every stride.
        params : Params or array_like
            The model parameters, or their vector, shape (6,).
        strides : int
            The number n of strides of the map r^n.

        Returns
        -------
        tuple of numpy.ndarray
            Shapes (4, 4), (4, controls) and (4, 6). Raises :class:`RunnerFell` if a
            stride falls.
        """
        return self._chained_jacobians(X, u, params, strides, with_parameters=True)

    def _chained_jacobians(self, X, u, params, strides: int, with_parameters: bool):
        """Jacobians of r^n in (X, u), and in p if asked, accumulated stride by stride."""
        X, u, p = self._point(X, u, params)
        strides = arguments.whole_number(strides, "strides", 1, arguments.MAX_STRIDES)
        nx, nu = APEX.size, self.law.controls.size
        dX, du = np.eye(nx), np.zeros((nx, nu))
        dp = np.zeros((nx, PARAMS.size))
        for _ in range(strides):
            jac, apex_next = self._stride_jacobian(X, u, p, with_parameters)
            step_X, step_u = jac[:, :nx], jac[:, nx : nx + nu]
            if with_parameters:
                dp = step_X @ dp + jac[:, nx + nu :]
            dX, du = step_X @ dX, step_X @ du + step_u
            X = apex_next
        return dX, du, dp if with_parameters else None

    # -- many strides ----------------------------------------------------------------

    def strides(self, X, U, params) -> list[Stride]:
        """One stride from each row of ``X`` (n x 4) under the row of ``U`` (n x controls,
        or one control for all): the compiled engine takes them in batches on both cores.

        Parameters
        ----------
        X : array_like
            Apexes, shape (n, 4) (or one apex, shape (4,)).
        U : array_like
            Controls, shape (n, controls), or one control vector for every row.
        params : Params or array_like
            The model parameters, or their vector, shape (6,).

        Returns
        -------
        list of Stride
            One per row of ``X``, in order.
        """
        X = arguments.rows(X, "X", APEX.size)
        U = arguments.row_controls(U, "U", len(X), self.law.controls.size)
        p = arguments.parameters(params)
        if not len(X):
            return []
        if self._compiled is None:
            return [self.stride(x, u, p) for x, u in zip(X, U)]
        if self._batch is None:
            from baslip.engine.batch import BatchEngine

            self._batch = BatchEngine(self._compiled, compile=self._compile)
        strides = []
        for i, result in enumerate(self._batch.strides(X, U, p)):
            if result is None:
                self.fallbacks += 1
                result = self.event_map.stride(X[i], U[i], p, precheck(X[i], U[i], p)[1])
            strides.append(result)
        return strides

    def simulate_many(self, X0, U, params, strides: int) -> list[Simulation]:
        """:meth:`simulate` from each row of ``X0`` (under the rows of ``U``, or one
        control), run in lockstep so that every stride is one batch.

        Parameters
        ----------
        X0 : array_like
            Initial apexes, shape (n, 4) (or one apex, shape (4,)).
        U : array_like
            Controls, shape (n, controls), or one control vector for every row.
        params : Params or array_like
            The model parameters, or their vector, shape (6,).
        strides : int
            The most strides to run from each apex.

        Returns
        -------
        list of Simulation
            One per row of ``X0``, in order.
        """
        X0 = arguments.rows(X0, "X0", APEX.size)
        U = arguments.row_controls(U, "U", len(X0), self.law.controls.size)
        strides = arguments.whole_number(strides, "strides", 1, arguments.MAX_STRIDES)
        if len(X0) * (strides + 1) > arguments.MAX_APEXES:
            raise ArgumentError("X0", f"{len(X0)} rows x {strides + 1} apexes exceed the limit of "
                                f"{arguments.MAX_APEXES} apexes in one call")
        params = arguments.parameters(params)
        apexes = [[x] for x in X0]
        durations: list[list[dict]] = [[] for _ in X0]
        falls: dict[int, tuple[Fall, int]] = {}
        alive = np.arange(len(X0))
        for n in range(strides):
            if not alive.size:
                break
            results = self.strides(np.array([apexes[i][-1] for i in alive]), U[alive], params)
            for i, result in zip(alive, results):
                if result.fall is not None:
                    falls[int(i)] = (result.fall, n)
                else:
                    apexes[i].append(result.apex)
                    durations[i].append(result.durations)
            alive = np.array([i for i in alive if i not in falls], dtype=int)
        return [
            Simulation(np.array(apexes[i]), durations[i], *falls.get(i, (None, None)))
            for i in range(len(X0))
        ]

    def simulate(self, X0, u, params, strides: int) -> Simulation:
        """Apply ``u`` for up to ``strides`` strides from apex ``X0``.

        Parameters
        ----------
        X0 : array_like
            The initial apex, shape (4,).
        u : array_like
            The control vector, shape (controls,), the same every stride.
        params : Params or array_like
            The model parameters, or their vector, shape (6,).
        strides : int
            The most strides to run.

        Returns
        -------
        Simulation
            The apexes reached, shape (strides + 1, 4) unless a stride fell, and the fall.
        """
        X0, u, params = self._point(X0, u, params, apex="X0")
        strides = arguments.whole_number(strides, "strides", 1, arguments.MAX_STRIDES)
        apexes = [X0]
        durations: list[dict[str, float]] = []
        for n in range(strides):
            result = self.stride(apexes[-1], u, params)
            if result.fall is not None:
                return Simulation(np.array(apexes), durations, result.fall, n)
            assert result.apex is not None
            apexes.append(result.apex)
            durations.append(result.durations)
        return Simulation(np.array(apexes), durations)

    def stance_samples(self, x_touchdown, u, params, duration: float, n: int, compiled: bool = False) -> np.ndarray:
        """Stance states (6 x n) at n equal steps up to ``duration`` [s] after touchdown.

        Parameters
        ----------
        x_touchdown : array_like
            The stance state at touchdown, shape (6,): rho [m], theta1 [rad], theta2 [rad],
            rhodot [m/s], theta1_dot [rad/s], theta2_dot [rad/s].
        u : array_like
            The control vector, shape (controls,).
        params : Params or array_like
            The model parameters, or their vector, shape (6,).
        duration : float
            The time [s] after touchdown of the last sample (normally the stance's).
        n : int
            The number of samples.
        compiled : bool
            For many calls at this ``n``: the integrator as C, cached (the same samples).

        Returns
        -------
        numpy.ndarray
            Shape (6, n): the stance states at ``duration * k / n`` for k = 1 .. n.
        """
        x_touchdown = arguments.vector(x_touchdown, "x_touchdown", STANCE.size)
        u, p = arguments.vector(u, "u", self.law.controls.size), arguments.parameters(params)
        duration = arguments.positive_number(duration, "duration", "s")
        n = arguments.whole_number(n, "n", 1, arguments.MAX_SAMPLES)  # n = 0 would crash CasADi's integrator
        return self.event_map.stance_samples(x_touchdown, u, p, duration, n, compiled)

    @staticmethod
    def touchdown_guess(X, u, p) -> float | None:
        """First zero of the foot height after apex [s]; see :func:`baslip.engine.outcome.touchdown_guess`.

        Parameters
        ----------
        X : array_like
            The apex, shape (4,).
        u : array_like
            The control vector; only its last entry, theta_td [rad], is read.
        p : array_like
            The parameter vector, shape (6,) (m, I, k, rho0, d, g), not a ``Params``.

        Returns
        -------
        float or None
            The time [s] after apex of touchdown, or None if the foot cannot reach the ground.
        """
        return touchdown_guess(arguments.vector(X, "X", APEX.size), arguments.vector(u, "u", np.size(u) or 1),
                               arguments.parameters(p, "p"))
