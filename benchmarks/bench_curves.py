"""Benchmark of bifurcation curves: what a curve point costs with exact second derivatives.

    python benchmarks/bench_curves.py [--points N] [problem ...]

For each curve problem (by default the five shipped ``curve_*`` problems), starts on the
first point of its committed ``results/<name>/curve.csv`` and traces that curve both ways,
up to ``--points`` points each way, twice in one process: first with the second derivatives as
central differences of the AD Jacobian (the baseline, as before exact ones existed), then
with the exact ones (Hessian-vector products of the compiled stride). Every point is
verified by the independent re-simulation, as in the study. Prints the wall time per
point of each, their ratio, the Jacobians of the extended system per point, and how far
apart the two traces lie (the largest difference of matching points, scaled units, where
both took the same steps).
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

from baslip import load_problem
from baslip.analysis.bifurcation import CurveSystem, trace_curve
from baslip.analysis.continuation import Settings
from baslip.analysis.gaitsystem import branch_system
from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.model.dynamics import APEX
from baslip.studies.curve import CURVE_MAX_STEP

ROOT = Path(__file__).resolve().parent.parent
CURVES = ("curve_downward_boundary", "curve_downward_neimark_sacker", "curve_slip_band", "curve_vpp_fold",
          "curve_vpp_pivot")


class Counted(CurveSystem):
    """A curve whose Jacobian calls are counted."""

    jacobians = 0

    def jacobian(self, v):
        self.jacobians += 1
        return super().jacobian(v)


def first_point(name: str) -> dict:
    with open(ROOT / "results" / name / "curve.csv", newline="") as handle:
        return next(csv.DictReader(handle))


def trace(name: str, points: int, exact: bool):
    """(seconds, points traced, Jacobians, the traced unknowns) of one curve of ``name``."""
    problem = load_problem(ROOT / "problems" / f"{name}.yaml")
    solver = solver_for(problem)
    spec = problem.continuation
    base = branch_system(fixed_point_spec(problem), spec.parameter, solver.residual_map, solver.jacobian_map,
                         second=spec.second, exact=exact)
    row = first_point(name)
    X = np.array([float(row[n]) for n in APEX.names])
    u = np.array([float(row[n]) for n in problem.hip_law.controls.names])
    v = base.pack(X, u, float(row[spec.parameter]), float(row[spec.second]))
    _, second_scale = base.lam_scales
    settings = Settings(step=spec.step, max_step=CURVE_MAX_STEP, max_points=points,
                        lam_range=(spec.second_lo / second_scale, spec.second_hi / second_scale),
                        other_ranges=((-2, spec.lo / base.lam_scales[0], spec.hi / base.lam_scales[0]),))
    curve = Counted(base, row["type"])
    curve.jacobian(v)  # the libraries are loaded (or compiled) before the clock starts
    curve.jacobians = 0
    start = time.perf_counter()
    branch = trace_curve(curve, v, settings, accept=lambda w: base.verification_failure(w, solver.verify_map))
    seconds = time.perf_counter() - start
    return seconds, len(branch.points), curve.jacobians, np.array([p.v for p in branch.points])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("problems", nargs="*", default=CURVES)
    parser.add_argument("--points", type=int, default=40, help="points at most each way (default 40)")
    args = parser.parse_args()
    print(f"{'curve':32} {'points':>6} {'differenced':>12} {'exact':>9} {'ratio':>6} {'Jac/pt':>7} {'apart':>8}")
    for name in args.problems:
        old_s, old_n, _, old_v = trace(name, args.points, exact=False)
        new_s, new_n, jacobians, new_v = trace(name, args.points, exact=True)
        apart = f"{np.max(np.abs(old_v - new_v)):8.1e}" if old_v.shape == new_v.shape else "-"
        old_ms, new_ms = 1e3 * old_s / old_n, 1e3 * new_s / new_n
        counts = f"{new_n}" if new_n == old_n else f"{old_n}/{new_n}"
        print(f"{name:32} {counts:>6} {old_ms:9.1f} ms {new_ms:6.1f} ms {old_ms / new_ms:5.1f}x "
              f"{jacobians / new_n:7.1f} {apart:>8}", flush=True)


if __name__ == "__main__":
    main()
