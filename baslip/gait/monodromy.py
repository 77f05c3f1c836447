"""Stability inside the stride NLP: the return map's Jacobian of a shot stride, and a
bound on its multipliers through a complex Schur form.

**The Jacobian.** A shot stride is a chain of phases, each ended by a guard: the descent
(touchdown guard), compression (bottom guard), decompression (liftoff guard) and ascent
(apex guard, zdot = 0). The variation of a phase's end state, with its duration moved so
that its guard stays zero, is

    d out / d x  =  out_x - out_t (guard_x / guard_t)

(the implicit-function theorem on the guard; the saltation of a hybrid map). In stance the
phase is a chain of shooting intervals of length T / n; the derivatives of its nodes in the
apex and in T are shooting nodes of their own, each the variational step of the one before
(:class:`ShotStrideJacobian`). Where the nodes join (at every feasible point of the NLP)
the product of the four phases is dr/dX of the discretised stride, an expression of the
NLP's variables whose derivatives IPOPT sees. It is only as accurate as the RK4 intervals,
so the NLP keeps every interval's h * rate small (:data:`STEP_RATE_LIMIT`).

**The bound** (after Hassan and Hubicki, "Single-stage optimization of open-loop stable
limit cycles with smooth, symbolic derivatives", arXiv 2312.10647, who compare it with
other eigenvalue constraints). Every square matrix A has a complex Schur form
A U = U T, with U unitary and T upper triangular, whose diagonal holds the eigenvalues.
With U and T as NLP variables (real and imaginary parts apart) the conditions

    A U - U T = 0,   U^H U = I,   Im U[0, j] = 0,   |T_jj|^2 <= s^2

bound every multiplier's modulus by s smoothly, with no eigenvalue solver in the NLP and
no assumption on how the multipliers pair up. The condition on Im U[0, j] fixes the phase of each
column of U, which the first two leave free, so the variables are locally unique.

Under a law of positions only (VPP) a symmetric gait has a multiplier 1 that no control
can move: the first slot of T then holds a multiplier near 1 (:data:`STRUCTURAL_SLACK`)
and the bound covers the others (:func:`structural_multipliers`). The accuracy limit
takes the law's hip rates (:meth:`baslip.model.hiplaw.HipLaw.hip_rates`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from baslip.engine.physics import Physics
from baslip.model.dynamics import (
    APEX,
    FLIGHT,
    PARAMS,
    STANCE,
    apex_to_flight,
)
from baslip.model.hiplaw import HipLaw

#: Size of the apex map's Jacobian.
ORDER = APEX.size


@dataclass(frozen=True)
class SchurLayout:
    """Where the Schur variables sit in their flat vector: U's real and imaginary parts
    (column-major), T's upper triangle (row by row) real and imaginary, then the bound s."""

    order: int = ORDER

    @property
    def triangle(self) -> list[tuple[int, int]]:
        """(row, column) of T's entries on and above the diagonal, row by row."""
        n = self.order
        return [(i, j) for i in range(n) for j in range(i, n)]

    @property
    def slices(self) -> dict[str, slice]:
        """Named slices of the flat vector."""
        square, upper = self.order**2, len(self.triangle)
        edges = np.cumsum([0, square, square, upper, upper, 1])
        names = ("U_re", "U_im", "T_re", "T_im", "bound")
        return {name: slice(int(a), int(b)) for name, a, b in zip(names, edges[:-1], edges[1:])}

    @property
    def size(self) -> int:
        return self.slices["bound"].stop

    def unpack(self, z) -> tuple:
        """(U_re, U_im, T_re, T_im, s) from the flat vector ``z`` (CasADi or numpy)."""
        part = {name: z[where] for name, where in self.slices.items()}
        n = self.order
        square = (lambda v: ca.reshape(v, n, n)) if isinstance(z, ca.MX | ca.SX | ca.DM) else (lambda v: np.reshape(v, (n, n), order="F"))
        return (square(part["U_re"]), square(part["U_im"]), self._upper(part["T_re"]), self._upper(part["T_im"]),
                part["bound"][0])

    def _upper(self, entries):
        n = self.order
        if isinstance(entries, ca.MX | ca.SX | ca.DM):
            T = type(entries).zeros(n, n)
        else:
            T = np.zeros((n, n))
        for k, (i, j) in enumerate(self.triangle):
            T[i, j] = entries[k]
        return T

    def pack(self, U: np.ndarray, T: np.ndarray, bound: float) -> np.ndarray:
        """The flat vector of a complex Schur form (U, T) and a bound s."""
        upper = np.array([T[i, j] for i, j in self.triangle])
        return np.concatenate([U.real.ravel(order="F"), U.imag.ravel(order="F"), upper.real, upper.imag, [bound]])


SCHUR = SchurLayout()


#: How near 1 a structural multiplier of the shot stride is held (:func:`schur_constraints`).
#: The shot stride's RK4 intervals break the symmetry that makes it exactly 1 by their
#: truncation error (its dr/dX matches the compiled map's to 1e-6 to 6e-3, see
#: :data:`STEP_RATE_LIMIT`); a bound below 1 - this slack keeps every other multiplier in
#: the bounded set.
STRUCTURAL_SLACK = 1e-2


def structural_multipliers(law: HipLaw) -> int:
    """How many multipliers of a gait of ``law`` equal 1 by structure whatever its
    controls: one, the symmetric family's, under a law of positions only (VPP); none
    under PD (the torque-free and spin-free cases hold only at fixed controls)."""
    return 1 if law.positional else 0


def schur_constraints(A, z, structural: int = 0) -> list[tuple[object, float, float]]:
    """(expression, lower, upper) triples that hold iff the Schur variables ``z`` are a
    complex Schur form of ``A`` whose eigenvalues all have modulus <= s (see the module
    docstring), except the first ``structural`` ones: these are held within
    :data:`STRUCTURAL_SLACK` of 1 instead (the multiplier 1 of a symmetric family, which
    no control can move). ``A`` is a real ``ORDER x ORDER`` expression."""
    U_re, U_im, T_re, T_im, s = SCHUR.unpack(z)
    n = SCHUR.order
    similar_re = ca.mtimes(A, U_re) - (ca.mtimes(U_re, T_re) - ca.mtimes(U_im, T_im))
    similar_im = ca.mtimes(A, U_im) - (ca.mtimes(U_re, T_im) + ca.mtimes(U_im, T_re))
    gram_re = ca.mtimes(U_re.T, U_re) + ca.mtimes(U_im.T, U_im) - ca.DM.eye(n)
    gram_im = ca.mtimes(U_re.T, U_im) - ca.mtimes(U_im.T, U_re)  # antisymmetric
    upper = [(i, j) for i in range(n) for j in range(i, n)]
    strictly_upper = [(i, j) for i, j in upper if i < j]
    moduli = ca.vertcat(*(T_re[j, j] ** 2 + T_im[j, j] ** 2 for j in range(structural, n)))
    constraints = [
        (ca.vec(similar_re), 0.0, 0.0),
        (ca.vec(similar_im), 0.0, 0.0),
        (ca.vertcat(*(gram_re[i, j] for i, j in upper)), 0.0, 0.0),
        (ca.vertcat(*(gram_im[i, j] for i, j in strictly_upper)), 0.0, 0.0),
        (ca.vec(U_im[0, :]), 0.0, 0.0),  # the phase of each column
        (moduli - s**2, -ca.inf, 0.0),
    ]
    if structural:
        near_one = ca.vertcat(*((T_re[j, j] - 1) ** 2 + T_im[j, j] ** 2 for j in range(structural)))
        constraints.append((near_one, -ca.inf, STRUCTURAL_SLACK**2))
    return constraints


def schur_start(A: np.ndarray, structural: int = 0, margin: float = 1.01) -> np.ndarray:
    """Schur variables for a numeric ``A``: its complex Schur form, from the QR
    factorisation of its eigenvectors (A V = V L, V = Q R gives A Q = Q (R L R^-1), upper
    triangular), each column's phase turned so that its first entry is real, and the bound
    ``margin`` times the largest modulus. The ``structural`` eigenvalues nearest 1 come
    first and are left out of the bound (:func:`schur_constraints`)."""
    A = np.asarray(A, dtype=float)
    eigenvalues, V = np.linalg.eig(A)
    nearest_one = np.argsort(np.abs(eigenvalues - 1.0))[:structural]
    order = np.concatenate([nearest_one, [k for k in range(len(eigenvalues)) if k not in nearest_one]]).astype(int)
    eigenvalues, V = eigenvalues[order], V[:, order]
    Q, _ = np.linalg.qr(V.astype(complex))
    first = Q[0, :]
    phase = np.where(np.abs(first) > 0, np.conj(first) / np.where(np.abs(first) > 0, np.abs(first), 1.0), 1.0)
    Q = Q * phase
    T = np.triu(Q.conj().T @ A @ Q)
    bounded = np.abs(eigenvalues[structural:])
    return SCHUR.pack(Q, T, margin * float(np.max(bounded)) if bounded.size else margin)


#: Largest h * rate of a shooting interval in the stability NLP, for each of the stance
#: dynamics' rates (:func:`stance_rates`). Past about 2.8 an RK4 step is unstable, and the
#: product of the intervals' Jacobians grows without bound (a start at Kd = 5.8 N m s/rad,
#: h * rate = 4.4 at 20 nodes, gave multipliers of 1e50) while the orbit itself still
#: closes; at 0.5 the shot stride's dr/dX matched the compiled map's to 1e-6 to 6e-3.
#: Minimising the multipliers would otherwise seek out where the scheme is wrong.
STEP_RATE_LIMIT = 0.5


def stance_rates(law: HipLaw, u, p) -> dict:
    """The stance dynamics' rates whose product with the step must stay small [1/s]: the
    spring's sqrt(k/m), and each of the law's hip stiffness and damping terms
    (:meth:`baslip.model.hiplaw.HipLaw.hip_rates`) over I_hip = I + m d^2, the trunk's
    inertia about the hip. Squared rates for the stiffness and the spring, so that every
    entry is smooth."""
    m, inertia, k, d = (PARAMS.get(p, name) for name in ("m", "I", "k", "d"))
    inertia_hip = inertia + m * d**2
    stiffness, damping = law.hip_rates(u, p)
    return {"spring_squared": k / m,
            **{f"damping_{i}": term / inertia_hip for i, term in enumerate(damping)},
            **{f"stiffness_squared_{i}": term / inertia_hip for i, term in enumerate(stiffness)}}


def accuracy_constraints(law: HipLaw, u, p, step) -> list[tuple[object, float, float]]:
    """(expression, lower, upper): every rate of :func:`stance_rates` times the interval
    ``step`` [s] within :data:`STEP_RATE_LIMIT`."""
    limit = STEP_RATE_LIMIT
    rates = stance_rates(law, u, p)
    return [(step * rates[name] if "squared" not in name else step**2 * rates[name], -ca.inf,
             limit if "squared" not in name else limit**2) for name in rates]


def step_rate(law: HipLaw, u, p, step: float) -> float:
    """The largest h * rate of a numeric control ``u`` of ``law`` and interval ``step``
    [s]: the quantity :data:`STEP_RATE_LIMIT` bounds."""
    rates = stance_rates(law, ca.DM(u), ca.DM(p))
    return max(step * math.sqrt(max(float(value), 0.0)) if "squared" in name else step * float(value)
               for name, value in rates.items())


def accurate_control_bounds(law: HipLaw, params, steps: int) -> dict[str, tuple[float, float]]:
    """Bounds on the law's drawn controls (Kp [N m/rad] and Kd [N m s/rad] under PD, r_vpp
    [m] under VPP) inside which a stance phase of a quarter spring period, pi/2 sqrt(m/k),
    in ``steps`` intervals keeps h * rate within :data:`STEP_RATE_LIMIT`: where to draw
    the stability NLP's starts.

    Parameters
    ----------
    law
        The hip law (:class:`baslip.model.hiplaw.HipLaw`).
    params
        The runner's parameters (:class:`baslip.model.dynamics.Params`).
    steps
        RK4 steps per stance phase (shooting nodes times substeps).
    """
    step = 0.5 * math.pi * math.sqrt(params.m / params.k) / steps
    inertia_hip = params.I + params.m * params.d**2
    damping = STEP_RATE_LIMIT * inertia_hip / step
    stiffness = (STEP_RATE_LIMIT / step) ** 2 * inertia_hip
    return law.rate_limited_bounds(stiffness, damping, params)


def phase_sensitivity(out, guard, x, t):
    """d out / d x with the phase's duration ``t`` moved to keep ``guard`` at zero:
    out_x - out_t guard_x / guard_t. ``x`` and ``t`` are symbols that ``out`` and
    ``guard`` depend on."""
    out_t, guard_t = ca.jacobian(out, t), ca.jacobian(guard, t)
    return ca.jacobian(out, x) - ca.mtimes(out_t, ca.jacobian(guard, x)) / guard_t


def _descent_function(physics: Physics) -> ca.Function:
    """(X, u, p, t_descent) -> d x_touchdown / d X, the touchdown time following the guard."""
    X, u, p, t = APEX.sym("X", ca.MX), physics.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX), ca.MX.sym("t")
    at_touchdown = physics.flight(apex_to_flight(X), t, u, p)
    guard = physics.guard("touchdown", at_touchdown, u, p)
    out = physics.reset("touchdown", at_touchdown, u, p)
    return ca.Function("descent_sensitivity", [X, u, p, t], [phase_sensitivity(out, guard, X, t)])


def _touchdown_function(physics: Physics) -> ca.Function:
    """(X, u, p, t_descent) -> the stance state at touchdown."""
    X, u, p, t = APEX.sym("X", ca.MX), physics.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX), ca.MX.sym("t")
    at_touchdown = physics.reset("touchdown", physics.flight(apex_to_flight(X), t, u, p), u, p)
    return ca.Function("touchdown_state", [X, u, p, t], [at_touchdown])


def _ascent_function(physics: Physics) -> ca.Function:
    """(x_liftoff, u, p, t_ascent) -> d X_next / d x_liftoff, the apex time following zdot = 0."""
    x, u, p, t = STANCE.sym("x", ca.MX), physics.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX), ca.MX.sym("t")
    at_apex = physics.flight(physics.reset("liftoff", x, u, p), t, u, p)
    out = ca.vertcat(*(FLIGHT.get(at_apex, name) for name in APEX.names))
    return ca.Function("ascent_sensitivity", [x, u, p, t],
                       [phase_sensitivity(out, FLIGHT.get(at_apex, "zdot"), x, t)])


def _guard_gradient(physics: Physics, label: str) -> ca.Function:
    """(x, u, p) -> d guard / d x for the stance guard of the transition ``label``."""
    x, u, p = STANCE.sym("x", ca.MX), physics.law.controls.sym("u", ca.MX), PARAMS.sym("p", ca.MX)
    return ca.Function("guard_gradient", [x, u, p], [ca.jacobian(physics.guard(label, x, u, p), x)])


def _variational_step(interval: ca.Function) -> ca.Function:
    """(x0, h, theta, M, dh_dT) -> Phi_x M + Phi_h dh_dT e_last^T: one shooting interval
    carries the sensitivities ``M`` (``STANCE.size x COLUMNS``: to the apex in the first
    columns, to the phase duration T in the last) from its start state ``x0``; its length
    ``h`` changes by ``dh_dT`` per unit of T."""
    x0, h, dh = STANCE.sym("x0", ca.MX), ca.MX.sym("h"), ca.MX.sym("dh_dT")
    theta = ca.MX.sym("theta", interval.size1_in(2))
    M = ca.MX.sym("M", STANCE.size, COLUMNS)
    end = interval(x0, h, theta)
    along_duration = ca.horzcat(ca.MX.zeros(STANCE.size, COLUMNS - 1), ca.jacobian(end, h) * dh)
    return ca.Function("variational_step", [x0, h, theta, M, dh], [ca.mtimes(ca.jacobian(end, x0), M) + along_duration])


#: Columns of a stance phase's sensitivity nodes: d x / d X (one per apex coordinate), then
#: d x / d T of the phase's duration.
COLUMNS = APEX.size + 1


class ShotStrideJacobian:
    """dr/dX of a shot stride, for the NLP of :mod:`baslip.gait.shooting`.

    In stance the sensitivities are shooting nodes of their own (``STANCE.size x COLUMNS *
    n`` per phase), joined like the states: node k is the interval's variational step of
    node k - 1. That keeps every constraint local to one interval, so the NLP's Jacobian
    holds the second derivatives of one interval (generated once, mapped), not of a
    product through the whole stance.

    Parameters
    ----------
    interval
        The NLP's shooting interval, (x0 [stance state], h [s], theta = (u, p)) -> end state.
    nodes
        Shooting intervals per stance phase.
    law
        The hip law, whose controls ``u`` are.
    """

    def __init__(self, interval: ca.Function, nodes: int, law: HipLaw):
        self.nodes = nodes
        self._step = _variational_step(interval)
        physics = Physics.of(law)
        self._descent = _descent_function(physics)
        self._touchdown = _touchdown_function(physics)
        self._ascent = _ascent_function(physics)
        self._bottom = _guard_gradient(physics, "bottom")
        self._liftoff = _guard_gradient(physics, "liftoff")

    @property
    def size(self) -> int:
        """Number of sensitivity variables (both stance phases)."""
        return 2 * STANCE.size * COLUMNS * self.nodes

    def jacobian(self, X, u, p, T, comp_nodes, decomp_nodes, sensitivities, constrain):
        """dr/dX (``ORDER x ORDER``) at the stride's nodes, with the sensitivity nodes
        ``sensitivities`` (a column of :attr:`size`) joined through ``constrain(expr, lo,
        hi)``. ``T`` are the four phase durations [s]; the nodes are ``STANCE.size x n``."""
        comp_sens, decomp_sens = self._split(sensitivities)
        theta = ca.repmat(ca.vertcat(u, p), 1, self.nodes)
        x_td = self._touchdown(X, u, p, T[0])
        bottom, x_lo = comp_nodes[:, -1], decomp_nodes[:, -1]
        at_bottom = self._phase(self._descent(X, u, p, T[0]), ca.horzcat(x_td, comp_nodes[:, :-1]), T[1], theta,
                                comp_sens, self._bottom(bottom, u, p), constrain)
        at_liftoff = self._phase(at_bottom, ca.horzcat(bottom, decomp_nodes[:, :-1]), T[2], theta, decomp_sens,
                                 self._liftoff(x_lo, u, p), constrain)
        return ca.mtimes(self._ascent(x_lo, u, p, T[3]), at_liftoff)

    def _split(self, sensitivities):
        half = STANCE.size * COLUMNS * self.nodes
        shape = (STANCE.size, COLUMNS * self.nodes)
        return ca.reshape(sensitivities[:half], *shape), ca.reshape(sensitivities[half:], *shape)

    def _phase(self, entering, starts, duration, theta, nodes, guard_x, constrain):
        """Join one phase's sensitivity ``nodes`` from the apex Jacobian ``entering`` at its
        start, and return the apex Jacobian at its end, across its guard (gradient
        ``guard_x`` at the end node)."""
        first = ca.horzcat(entering, ca.MX.zeros(STANCE.size, 1))
        previous = ca.horzcat(first, nodes[:, : -COLUMNS])
        n = self.nodes
        carried = self._step.map(n)(starts, ca.repmat(duration / n, 1, n), theta, previous, 1.0 / n)
        constrain(nodes - carried, 0, 0)
        end = nodes[:, -COLUMNS:]
        to_apex, to_duration = end[:, : COLUMNS - 1], end[:, COLUMNS - 1]
        return to_apex - ca.mtimes(to_duration, ca.mtimes(guard_x, to_apex)) / ca.mtimes(guard_x, to_duration)

    def start_values(self, X, u, p, T, comp_nodes, decomp_nodes) -> np.ndarray:
        """The sensitivity nodes that join exactly at the given (numeric) orbit nodes, by
        stepping the intervals in turn: a start for the NLP."""
        theta = np.concatenate([u, p])
        x_td = np.asarray(self._touchdown(X, u, p, T[0])).ravel()
        n = self.nodes
        parts, entering = [], np.asarray(self._descent(X, u, p, T[0]))
        phases = ((x_td, comp_nodes, T[1], self._bottom), (comp_nodes[:, -1], decomp_nodes, T[2], self._liftoff))
        for first_state, nodes, duration, gradient in phases:
            M = np.hstack([entering, np.zeros((STANCE.size, 1))])
            starts = np.column_stack([first_state, nodes[:, :-1]])
            columns = []
            for k in range(n):
                M = np.asarray(self._step(starts[:, k], duration / n, theta, M, 1.0 / n))
                columns.append(M)
            parts.append(np.hstack(columns).ravel(order="F"))
            guard_x = np.asarray(gradient(nodes[:, -1], u, p)).ravel()
            entering = M[:, :-1] - np.outer(M[:, -1], guard_x @ M[:, :-1]) / float(guard_x @ M[:, -1])
        return np.concatenate(parts)
