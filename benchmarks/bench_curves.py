"""Benchmark of bifurcation curves: what a curve point costs with exact second derivatives.

    python benchmarks/bench_curves.py [--points N] [problem ...]

For each curve problem (by default the five shipped ``curve_*`` problems), starts on the
first point of its committed ``results/<name>/curve.csv`` and traces that curve both ways,
up to ``--points`` points each way, three times in one process: with the second
derivatives as central differences of the AD Jacobian (the baseline, as before exact ones
existed); with the exact ones (Hessian-vector products of the compiled stride) and a
fresh Jacobian at every Newton step until the step is short (the corrector before the
updated one); and with the exact ones and the corrector that updates the last point's
Jacobian by Broyden's formula (as the study runs). Every point is verified by the
independent re-simulation, as in the study. Prints the points of each, the wall time per
point of each, the ratios of the first two to the third, the Jacobians of the extended
system per point of the last two, and how far apart the first and third traces lie (the
largest difference of matching points, scaled units, where both took the same steps).
``--record`` writes each curve's cost a point to ``benchmarks/figures/bench_curves.json``
for the README's speed table.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
from figures import Figure, report

from baslip import load_problem
from baslip.analysis.bifurcation import CurveSystem, trace_curve
from baslip.analysis.gaitsystem import branch_system
from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.model.dynamics import APEX
from baslip.numerics.continuation import Settings
from baslip.studies.curve import CURVE_MAX_STEP

ROOT = Path(__file__).resolve().parent.parent
CURVES = ("curve_downward_boundary", "curve_downward_neimark_sacker", "curve_slip_band", "curve_vpp_fold",
          "curve_vpp_pivot")


class FreshNewton(CurveSystem):
    """A curve whose corrector takes Newton steps with fresh Jacobians (before the updated
    corrector): the baseline of the corrector's gain."""

    costly_jacobian = False


def counted(base) -> dict:
    """Count the calls of ``base.jacobian``: one per Jacobian of the extended system."""
    calls = {"jacobians": 0}
    original = base.jacobian

    def jacobian(v):
        calls["jacobians"] += 1
        return original(v)

    base.jacobian = jacobian
    return calls


def first_point(name: str) -> dict:
    with open(ROOT / "results" / name / "curve.csv", newline="") as handle:
        return next(csv.DictReader(handle))


def trace(name: str, points: int, exact: bool, updated: bool = True):
    """(seconds, points traced, Jacobians, the traced unknowns) of one curve of ``name``:
    with exact or differenced second derivatives, and the updated or fresh-Newton corrector."""
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
    curve = (CurveSystem if updated else FreshNewton)(base, row["type"])
    curve.jacobian(v)  # the libraries are loaded (or compiled) before the clock starts
    calls = counted(base)
    start = time.perf_counter()
    branch = trace_curve(curve, v, settings, accept=lambda w: base.verification_failure(w, solver.verify_map))
    seconds = time.perf_counter() - start
    return seconds, len(branch.points), calls["jacobians"], np.array([p.v for p in branch.points])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("problems", nargs="*", default=CURVES)
    parser.add_argument("--points", type=int, default=40, help="points at most each way (default 40)")
    parser.add_argument("--record", action="store_true", help="write the figures to benchmarks/figures/")
    args = parser.parse_args()
    figures = []
    print(f"{'curve':32} {'points':>9} {'differenced':>12} {'exact, Newton':>14} {'exact':>9} {'ratios':>11} "
          f"{'Jac/pt':>11} {'apart':>8}")
    for name in args.problems:
        old_s, old_n, _, old_v = trace(name, args.points, exact=False)
        fresh_s, fresh_n, fresh_jacobians, _ = trace(name, args.points, exact=True, updated=False)
        new_s, new_n, jacobians, new_v = trace(name, args.points, exact=True)
        apart = f"{np.max(np.abs(old_v - new_v)):8.1e}" if old_v.shape == new_v.shape else "-"
        old_ms, fresh_ms, new_ms = 1e3 * old_s / old_n, 1e3 * fresh_s / fresh_n, 1e3 * new_s / new_n
        counts = f"{old_n}/{fresh_n}/{new_n}"
        print(f"{name:32} {counts:>9} {old_ms:9.1f} ms {fresh_ms:11.1f} ms {new_ms:6.1f} ms "
              f"{old_ms / new_ms:4.1f}x {fresh_ms / new_ms:4.1f}x {fresh_jacobians / fresh_n:5.1f} {jacobians / new_n:5.1f} "
              f"{apart:>8}", flush=True)
        figures.append(Figure(22, f"a point of `{name}`, exact second derivatives, every point verified", new_ms,
                              "ms", 50.0, "lower",
                              f"{new_n} points from the committed first; central differences of the Jacobian: "
                              f"{old_ms:.1f} ms ({old_ms / new_ms:.1f}x)"))
    report("bench_curves", figures, args.record)


if __name__ == "__main__":
    main()
