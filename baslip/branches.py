"""Branches of BA-SLIP fixed points: the fixed-point equations as a continuation system.

A fixed point here is one of the N-stride map r^N when the problem asks for orbits of
N strides (``FixedPointSpec.strides``); its multipliers are those of r^N.

The unknowns are the free design quantities and the continuation parameter lambda, which
is a fixed quantity of the problem (a state, a control, the apex energy) or a model
parameter (m, I, k, rho0, d, g). The equations are the periodicity rows r(X, u) - X that
structure does not already imply (see :func:`baslip.shooting.implied_periodicity`), plus
the apex energy when it is fixed. A branch is a curve only if there are as many free
quantities as equations; otherwise the problem must fix more (or fewer) of them.

Unknowns are scaled by :data:`baslip.quantities.NOMINAL` (model parameters by a tenth of
their value), so that arclength steps are balanced.
"""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np

from .continuation import CorrectionFailed
from .control import CONTROL
from .fixedpoint import VERIFY_EPS, minimal_period
from .model import APEX, PARAMS, Params, apex_energy
from .quantities import DESIGN, NOMINAL
from .returnmap import ReturnMap, RunnerFell
from .shooting import FixedPointSpec, implied_periodicity
from .stability import classify


#: A phase lasting less than this fraction of its flight (descent) or stance (compression,
#: decompression) counts as grazing: the branch is about to lose or gain an event.
GRAZING_FRACTION = 0.02


class BranchError(ValueError):
    """The problem does not define a one-dimensional branch; ``key`` names the entry."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key = key


def check_branch(spec: FixedPointSpec, parameter: str) -> None:
    """Raise :class:`BranchError` unless the problem defines a one-dimensional branch."""
    if parameter not in DESIGN + ("energy",) + PARAMS.names:
        raise BranchError("continuation.parameter", f"{parameter!r} cannot be varied")
    if parameter in DESIGN + ("energy",) and parameter not in spec.fixed:
        raise BranchError("continuation.parameter", f"{parameter} must be fixed (at its starting value)")
    free = [n for n in DESIGN if n not in spec.fixed]
    equations = len([n for n in APEX.names if n not in implied_periodicity(spec)]) + ("energy" in spec.fixed)
    if len(free) != equations:
        raise BranchError(
            "fix",
            f"a branch needs as many free quantities as equations: {len(free)} free "
            f"({', '.join(free)}) but {equations} equations; fix or free quantities to match",
        )


class FixedPointSystem:
    """F(v) = 0 for v = (free design quantities, lambda), all scaled."""

    def __init__(self, spec: FixedPointSpec, parameter: str, residual_map: ReturnMap, jacobian_map: ReturnMap):
        check_branch(spec, parameter)
        self.spec, self.parameter = spec, parameter
        self.residual_map, self.jacobian_map = residual_map, jacobian_map
        self.free = [n for n in DESIGN if n not in spec.fixed]
        self.rows = [n for n in APEX.names if n not in implied_periodicity(spec)]
        self.energy_row = "energy" in spec.fixed
        value = self.start_value()
        self.lam_scale = NOMINAL.get(parameter, 1.0) if parameter != "energy" else 0.1
        if parameter in PARAMS.names:
            self.lam_scale = 0.1 * abs(value) if value else 0.01
        self.scale = np.array([NOMINAL[n] for n in self.free] + [self.lam_scale])
        X, p = APEX.sym("X"), PARAMS.sym("p")
        energy = apex_energy(X, p)
        self._energy = ca.Function("E", [X, p], [energy])
        self._energy_gradient = ca.Function("dE", [X, p], [ca.gradient(energy, X), ca.gradient(energy, p)])
        self._cache: tuple[bytes, tuple] | None = None

    # -- unknowns -------------------------------------------------------------------------

    def start_value(self) -> float:
        if self.parameter in PARAMS.names:
            return float(getattr(self.spec.params, self.parameter))
        return float(self.spec.fixed[self.parameter])

    def pack(self, X, u, lam: float) -> np.ndarray:
        design = dict(zip(DESIGN, np.concatenate([X, u])))
        return np.array([design[n] for n in self.free] + [lam]) / self.scale

    def unpack(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, Params, float]:
        physical = v * self.scale
        lam = float(physical[-1])
        values = dict(self.spec.fixed)
        values.update(zip(self.free, physical[:-1]))
        params = self.spec.params
        if self.parameter in PARAMS.names:
            params = replace(params, **{self.parameter: lam})
        elif self.parameter != "energy":
            values[self.parameter] = lam
        design = np.array([values[n] for n in DESIGN])
        return design[: APEX.size], design[APEX.size :], params, lam

    # -- equations ------------------------------------------------------------------------

    def energy(self, X, params: Params) -> float:
        """Apex energy [J]."""
        return float(self._energy(X, params.vector()))

    def _energy_target(self, lam: float) -> float:
        return lam if self.parameter == "energy" else self.spec.fixed.get("energy", 0.0)

    def residual(self, v: np.ndarray) -> np.ndarray:
        X, u, params, lam = self.unpack(v)
        orbit = self.residual_map.simulate(X, u, params, self.spec.strides)
        if orbit.fall is not None:
            raise CorrectionFailed(f"the runner falls ({orbit.fall.value})")
        periodic = orbit.apexes[-1] - X
        rows = [periodic[APEX.index(n)] for n in self.rows]
        if self.energy_row:
            rows.append(self.energy(X, params) - self._energy_target(lam))
        return np.array(rows)

    def _jacobians(self, v: np.ndarray):
        key = v.tobytes()
        if self._cache is None or self._cache[0] != key:
            X, u, params, _ = self.unpack(v)
            try:
                strides = self.spec.strides
                if self.parameter in PARAMS.names:  # one pass gives all three
                    dr_dX, dr_du, dr_dp = self.jacobian_map.all_jacobians(X, u, params, strides)
                else:
                    (dr_dX, dr_du), dr_dp = self.jacobian_map.jacobians(X, u, params, strides), None
            except RunnerFell as err:
                raise CorrectionFailed(f"the runner falls ({err.fall.value})") from None
            self._cache = (key, (X, u, params, dr_dX, dr_du, dr_dp))
        return self._cache[1]

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        X, u, params, dr_dX, dr_du, dr_dp = self._jacobians(v)
        full = np.hstack([dr_dX - np.eye(APEX.size), dr_du])  # d(r - X)/d(X, u)
        rows = [APEX.index(n) for n in self.rows]
        columns = [DESIGN.index(n) for n in self.free]
        jac = full[np.ix_(rows, columns)]
        if self.parameter in PARAMS.names:
            lam_column = dr_dp[rows, PARAMS.index(self.parameter)]
        elif self.parameter == "energy":
            lam_column = np.zeros(len(rows))
        else:
            lam_column = full[rows, DESIGN.index(self.parameter)]
        jac = np.column_stack([jac, lam_column])
        if self.energy_row:
            by_X, by_p = (np.asarray(g).ravel() for g in self._energy_gradient(X, params.vector()))
            energy = np.concatenate([by_X, np.zeros(CONTROL.size)])
            if self.parameter == "energy":
                lam_energy = -1.0
            elif self.parameter in PARAMS.names:
                lam_energy = by_p[PARAMS.index(self.parameter)]
            else:
                lam_energy = energy[DESIGN.index(self.parameter)]
            jac = np.vstack([jac, np.concatenate([energy[columns], [lam_energy]])])
        return jac * self.scale

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
        """If the orbit at ``v`` is close to grazing, where: an apex at the touchdown
        height (its descent lasting under :data:`GRAZING_FRACTION` of its flight) or a
        stance phase shrinking to nothing. None otherwise (or if the orbit falls)."""
        X, u, params, _ = self.unpack(v)
        orbit = self.residual_map.simulate(X, u, params, self.spec.strides)
        if orbit.fall is not None:
            return None
        for k, d in enumerate(orbit.durations):
            flight = d["descent"] + d["ascent"]
            if d["descent"] < GRAZING_FRACTION * flight:
                return (f"grazing: the apex of stride {k + 1} (z = {orbit.apexes[k][0]:.6g} m) is at the touchdown "
                        f"height (descent {1e3 * d['descent']:.3g} ms of a {1e3 * flight:.3g} ms flight)")
            stance = d["compression"] + d["decompression"]
            for phase in ("compression", "decompression"):
                if d[phase] < GRAZING_FRACTION * stance:
                    return f"grazing: the {phase} of stride {k + 1} lasts {1e3 * d[phase]:.3g} ms of a {1e3 * stance:.3g} ms stance"
        return None

    def multipliers(self, v: np.ndarray) -> tuple[np.ndarray, list[bool]]:
        _, u, params, dr_dX, _, _ = self._jacobians(v)
        stability = classify(dr_dX, params, u)
        return np.array([m.value for m in stability.multipliers]), [m.trivial for m in stability.multipliers]
