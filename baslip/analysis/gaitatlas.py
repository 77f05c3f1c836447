"""The fixed points of a problem as a manifold for the atlas, and what each chart says.

With the problem's fixed quantities held, the fixed points solve F(v) = r(X, u) - X = 0
(and apex energy = its fixed value, if it is held) in the free design quantities v of the
problem's hip law. Rows that follow from the others by structure are left out (z's under
a law of positions only, VPP, whose gaits are symmetric:
:func:`baslip.gait.shooting.implied_periodicity`), so that the equations keep full rank
along the symmetric family; the independent check re-simulates every row. The atlas
(:mod:`baslip.analysis.atlas`) covers that set; this module gives it

* **coordinates** w in which a unit means about the same everywhere: v / nominal for most
  quantities, and asinh(v / nominal) for the gains Kp and Kd, whose meaningful values
  span four decades (0.01 to 100 N m/rad); a uniform metric in the gains would spend
  nearly every chart on large gains;
* **the equations** on the compiled return map (error estimate <= 1e-12), with their AD
  Jacobian, and a point solved when eps <= 1e-12;
* **the domain**: the problem's bounds (inside the physical ones), and apexes from which
  the runner can take a stride at all;
* **a priority**: the spectral radius, so that the atlas grows from its most stable
  charts first and a chart limit leaves the most stable part of the family covered;
* **what a chart says** (:func:`chart_report`): its multipliers and spectral radius, and
  the checks (:class:`ChartChecker`, on maps of its own, so that they can run in a thread
  beside the covering): the trunk's angle range over the stride and the independent
  re-simulation's eps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from baslip.engine.outcome import precheck, strides_can_start
from baslip.engine.returnmap import ReturnMap, RunnerFell, Tolerances, param_vector
from baslip.engine.trajectory import TrunkRange
from baslip.gait.fixedpoint import VERIFY_TOLERANCES
from baslip.gait.polish import POLISH_EPS, Polish, eps
from baslip.gait.shooting import FixedPointSpec, implied_periodicity
from baslip.gait.stability import Stability, classify
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HipLaw
from baslip.model.quantities import body_scale, nominal
from baslip.numerics.corrector import Evaluation

#: Quantities charted in asinh(value / nominal) rather than value / nominal.
LOGARITHMIC = ("Kp", "Kd")


class GaitManifold:
    """The fixed points of ``spec`` (one-stride gaits) in atlas coordinates.

    Parameters
    ----------
    spec : FixedPointSpec
        The problem: its fixed quantities are held, its bounds are the domain.
    residual_map, jacobian_map : ReturnMap
        The maps of the equations and of their Jacobian (the solver's compiled maps).
    """

    def __init__(self, spec: FixedPointSpec, residual_map: ReturnMap, jacobian_map: ReturnMap):
        if spec.strides != 1:
            raise ValueError("the atlas covers one-stride gaits")
        self.spec = spec
        self.polish = Polish(residual_map, jacobian_map)
        self.residual_map, self.jacobian_map = residual_map, jacobian_map
        self.design = spec.design
        self.free = np.array([i for i, name in enumerate(self.design) if name not in spec.fixed], dtype=int)
        self.names = tuple(self.design[i] for i in self.free)
        implied = implied_periodicity(spec)
        self.rows = np.array([i for i, name in enumerate(APEX.names) if name not in implied], dtype=int)
        self.nominal = np.array([nominal(name, spec.params) for name in self.names])  # the body's units
        self.logarithmic = np.array([name in LOGARITHMIC for name in self.names])
        self.template = np.array([spec.fixed.get(name, 0.0) for name in self.design], dtype=float)
        self.energy = spec.fixed.get("energy")
        bounds = np.array([spec.bounds_of(name) for name in self.names]).T / self.nominal
        self.atlas_bounds = np.where(self.logarithmic, np.arcsinh(bounds), bounds)
        self.p = param_vector(spec.params)
        # The equations in the body's units (exactly 1 at the thesis's body): the same
        # tangent bases, corrector steps and tolerances at every size of a body.
        row_names = [APEX.names[i] for i in self.rows] + (["energy"] if self.energy is not None else [])
        self.row_scale = np.array([body_scale(name, spec.params) for name in row_names])
        self._last_jacobian: tuple[bytes, np.ndarray] = (b"", np.zeros((0, 0)))
        self._stabilities: dict[bytes, Stability] = {}  # per chart centre: ranked by growth, then reported

    #: Error of :meth:`evaluate_roughly` in F's norm, with a margin: the 1e-10 map's
    #: estimate bounds each stride's error relative to max(1, |x|), and the event map it
    #: hands the rare stride to has been seen 6e-9 off the 1e-12 map.
    rough_error = 1e-8

    @property
    def dimension(self) -> int:
        """Dimension of the fixed-point set where the equations have full rank."""
        return len(self.free) - len(self.rows) - (self.energy is not None)

    # -- coordinates -----------------------------------------------------------------------

    def to_design(self, w: np.ndarray) -> np.ndarray:
        """The design quantities (X, u) [SI, rad] at atlas point ``w``."""
        scaled = np.where(self.logarithmic, np.sinh(w), w)
        design = self.template.copy()
        design[self.free] = scaled * self.nominal
        return design

    def to_atlas(self, design: np.ndarray) -> np.ndarray:
        """The atlas point of the design quantities ``design``."""
        scaled = np.asarray(design, dtype=float)[self.free] / self.nominal
        return np.where(self.logarithmic, np.arcsinh(scaled), scaled)

    def _design_per_atlas(self, w: np.ndarray) -> np.ndarray:
        """d(free design quantities) / dw, a diagonal, as a vector."""
        return self.nominal * np.where(self.logarithmic, np.cosh(w), 1.0)

    # -- the ManifoldSystem interface ----------------------------------------------------

    def evaluate(self, w: np.ndarray) -> Evaluation:
        """F(w) = r(X, u) - X (and the energy row) on the 1e-12 map, or why not (a fall)."""
        return self._equations(w, self.residual_map)

    def evaluate_roughly(self, w: np.ndarray) -> Evaluation:
        """F(w) on the Jacobian's map (error estimate <= 1e-10, a third cheaper): the
        corrector's far steps, where |F| is far above :attr:`rough_error`."""
        return self._equations(w, self.jacobian_map)

    def _equations(self, w: np.ndarray, rmap: ReturnMap) -> Evaluation:
        design = self.to_design(w)
        X, u = design[: APEX.size], design[APEX.size :]
        stride = rmap.stride(X, u, self.spec.params)
        if not stride.ok:
            return Evaluation(failure=f"a fall: {stride.fall.value if stride.fall else 'no next apex'}")
        rows = [(stride.apex - X)[self.rows]]
        if self.energy is not None:
            rows.append([self.polish.energy(X, self.spec.params) - self.energy])
        return Evaluation(np.concatenate(rows) / self.row_scale)

    def jacobian(self, w: np.ndarray) -> np.ndarray | str:
        """dF/dw from the AD Jacobian of the compiled stride, or why not (a fall)."""
        design = self.to_design(w)
        try:
            jacobian = self.polish.equations_jacobian(self.spec, design[: APEX.size], design[APEX.size :], self.energy)
        except RunnerFell as err:
            return f"a fall: {err}"
        self._last_jacobian = (w.tobytes(), jacobian)
        kept = np.concatenate([self.rows, np.arange(APEX.size, len(jacobian))])  # and the energy row
        return jacobian[np.ix_(kept, self.free)] * self._design_per_atlas(w) / self.row_scale[:, None]

    def priority(self, w: np.ndarray) -> float:
        """The spectral radius at ``w`` (its non-trivial multipliers): the atlas grows
        from its most stable charts first."""
        return float(self.stability(w).spectral_radius)

    def stability(self, w: np.ndarray) -> Stability:
        """The multipliers at ``w`` from the AD Jacobian of the stride, remembered per point
        (the atlas ranks a chart by them as it is made, and its report gives them). Uses
        the Jacobian just evaluated at ``w`` (the corrector's last), else evaluates it."""
        key = w.tobytes()
        if key not in self._stabilities:
            design = self.to_design(w)
            last, jacobian = self._last_jacobian
            if last != key:
                jacobian = self.polish.equations_jacobian(self.spec, design[: APEX.size], design[APEX.size :],
                                                          self.energy)
            dr_dX = jacobian[: APEX.size, : APEX.size] + np.eye(APEX.size)
            self._stabilities[key] = classify(dr_dX, self.spec.params, design[APEX.size :], self.spec.law)
        return self._stabilities[key]

    def outside(self, w: np.ndarray) -> str:
        """Which bound ``w`` leaves, or which stride it cannot start ("" if neither)."""
        # In atlas coordinates (a monotonic map of each quantity), so that a wild Newton
        # iterate is refused before sinh of it could overflow.
        for name, value, lo, hi in zip(self.names, w, *self.atlas_bounds):
            if not lo <= value <= hi:
                return f"leaves the bounds of {name}"
        design = self.to_design(w)
        fallen, _ = precheck(design[: APEX.size], design[APEX.size :], self.p)
        return f"a fall: {fallen.fall.value}" if fallen is not None and fallen.fall is not None else ""

    def inside(self, points: np.ndarray) -> np.ndarray:
        """Whether each atlas point (rows of ``points``) lies inside the domain: the test of
        :meth:`outside` for many points at once (the charts' areas test thousands)."""
        points = np.atleast_2d(points)
        lo, hi = self.atlas_bounds
        held = np.all((lo <= points) & (points <= hi), axis=1)
        design = np.array([self.to_design(w) for w in points[held]]).reshape(-1, len(self.design))
        held[held] = strides_can_start(design[:, : APEX.size], design[:, APEX.size :], self.p)
        return held

    def solved(self, w: np.ndarray, residual: np.ndarray) -> bool:
        """eps <= 1e-12 on the compiled map over the rows kept (and the energy row as small)."""
        X = self.to_design(w)[: APEX.size]
        periodic = len(self.rows)
        apex_residual = np.zeros(APEX.size)
        apex_residual[self.rows] = residual[:periodic]
        return eps(X + apex_residual, X) <= POLISH_EPS and bool(np.all(np.abs(residual[periodic:]) <= POLISH_EPS))


@dataclass(frozen=True)
class ChartCheck:
    """The independent re-simulation's eps at a chart's centre, and the trunk's range
    [rad] over its stride."""

    residual: float
    theta_h_min: float
    theta_h_max: float


class ChartChecker:
    """The checks of chart centres that do not use the covering's maps: eps from the
    independent, tight-tolerance re-simulation (Rosenbrock, rtol = atol = 1e-12) and the
    trunk's range from a sampled stride (compiled map at 1e-10). It owns its maps, so it
    can run in a thread beside the covering (compiled calls release Python's lock).

    Parameters
    ----------
    law : HipLaw
        The problem's hip law.
    params : Params
        The runner's parameters.
    """

    def __init__(self, law: HipLaw, params: Params):
        self.params = params
        self.verify_map = ReturnMap(VERIFY_TOLERANCES, plugin="rosenbrock", law=law)
        self.trunk_range = TrunkRange(ReturnMap(Tolerances(CHECK_SAMPLE_TOLERANCE, CHECK_SAMPLE_TOLERANCE), law=law))

    def __call__(self, X: np.ndarray, u: np.ndarray) -> ChartCheck:
        """The checks of the fixed point (X, u) [SI, rad]."""
        check = self.verify_map.stride(X, u, self.params)
        low, high = self.trunk_range(X, u, self.params)
        return ChartCheck(eps(check.apex, X) if check.ok else math.inf, low, high)


#: Tolerance of the stride that the trunk's range is sampled from.
CHECK_SAMPLE_TOLERANCE = 1e-10


@dataclass(frozen=True)
class ChartReport:
    """What one chart's centre is: the gait (X, u), its multipliers and spectral radius,
    the trunk's range over the stride [rad], and eps of the independent re-simulation."""

    X: np.ndarray
    u: np.ndarray
    multipliers: tuple[complex, ...]
    spectral_radius: float
    stable: bool
    theta_h_min: float
    theta_h_max: float
    residual: float


def chart_report(manifold: GaitManifold, w: np.ndarray, check: ChartCheck) -> ChartReport:
    """The report of the chart centred at ``w``: its multipliers (:meth:`GaitManifold.stability`,
    from the AD Jacobian of the compiled map) with the chart's independent ``check``
    (:class:`ChartChecker`)."""
    design = manifold.to_design(w)
    stability = manifold.stability(w)
    return ChartReport(design[: APEX.size], design[APEX.size :], tuple(m.value for m in stability.multipliers),
                       stability.spectral_radius, bool(stability.stable), check.theta_h_min, check.theta_h_max,
                       check.residual)
