"""Benchmark of the atlas (``kind: atlas``): what one chart costs, and where the time goes.

    python benchmarks/bench_atlas.py [--charts N] [--problem problems/atlas_upright_cell.yaml]

Covers the first cell of the problem's atlas study from the problem's own guess (one
seed) up to ``--charts`` charts, then reports every chart as the study does. Prints, per
chart: the covering's time, the number of residual evaluations and AD Jacobians it took,
and the chart report's time (multipliers, trunk range, independent re-simulation). The
baseline, measured in the same process at the charts' own centres, is one residual
evaluation and one AD Jacobian of the compiled stride, so that the covering's cost reads
as a count of those.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import numpy as np

from baslip import load_problem
from baslip.analysis.atlas import cover
from baslip.analysis.gaitatlas import GaitManifold, chart_report
from baslip.problem.study import Atlas
from baslip.studies.atlascell import CellAtlas
from baslip.studies.sweep import key_column, sweep_tasks


class Counted:
    """A manifold whose residual and Jacobian calls are counted."""

    def __init__(self, manifold: GaitManifold):
        self.manifold, self.evaluations, self.jacobians = manifold, 0, 0

    def evaluate(self, w):
        self.evaluations += 1
        return self.manifold.evaluate(w)

    def jacobian(self, w):
        self.jacobians += 1
        return self.manifold.jacobian(w)

    def __getattr__(self, name):
        return getattr(self.manifold, name)


def median_ms(fn, points) -> float:
    times = []
    for w in points:
        start = time.perf_counter()
        fn(w)
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default="problems/atlas_upright_cell.yaml")
    parser.add_argument("--charts", type=int, default=300)
    args = parser.parse_args()
    problem = load_problem(args.problem)
    study = problem.study
    if not isinstance(study, Atlas):
        parser.error(f"{args.problem}: not an atlas study")
    study = replace(study, max_charts=args.charts)
    cells = CellAtlas(problem, study)
    task = sweep_tasks(study)[0]
    held = {a.name: task[key_column(a.name)] for a in study.axes}
    spec = replace(cells.base, fixed={**cells.base.fixed, **held})
    solver = cells.solver
    manifold = GaitManifold(spec, solver.residual_map, cells.jacobian_map)
    seed = solver.solve(spec)
    if not seed.converged:
        raise SystemExit(f"{args.problem}: the guess's gait did not solve: {seed.message}")
    counted = Counted(manifold)
    start = time.perf_counter()
    atlas = cover(counted, [manifold.to_atlas(np.concatenate([seed.X, seed.u]))], manifold.dimension, cells.settings)
    covering = time.perf_counter() - start
    start = time.perf_counter()
    for chart in atlas.charts:
        chart_report(manifold, chart.center, solver.verify_map, cells.trunk_range)
    reports = time.perf_counter() - start
    n = len(atlas.charts)
    centres = [c.center for c in atlas.charts[:: max(1, n // 50)]]
    one_residual = median_ms(manifold.evaluate, centres)
    one_jacobian = median_ms(manifold.jacobian, centres)
    cell = ", ".join(f"{k} = {v:g}" for k, v in held.items())
    print(f"{problem.name}, cell {cell}: {n} charts, dimension {atlas.dimension}")
    print(f"  covering      {1e3 * covering / n:7.1f} ms a chart ({covering:6.1f} s): "
          f"{counted.evaluations / n:5.1f} residuals and {counted.jacobians / n:4.1f} Jacobians a chart")
    print(f"  chart reports {1e3 * reports / n:7.1f} ms a chart ({reports:6.1f} s)")
    print(f"  baseline, at the charts' centres: residual {one_residual:6.2f} ms, AD Jacobian {one_jacobian:6.2f} ms")
    print(f"  covering / (its residuals and Jacobians at the baseline's cost): "
          f"{covering / (1e-3 * (counted.evaluations * one_residual + counted.jacobians * one_jacobian)):5.2f}")
    print(f"  1,000 charts: about {(covering + reports) / n * 1000:5.0f} s (covering and reports, no seeds, no polish)")


if __name__ == "__main__":
    main()
