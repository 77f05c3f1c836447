"""Benchmark of the atlas (``kind: atlas``): what one chart costs, and where the time goes.

    python benchmarks/bench_atlas.py [--charts N] [--problem problems/atlas_upright_cell.yaml]

Covers the first cell of the problem's atlas study from the problem's own guess (one
seed) up to ``--charts`` charts, with each chart's independent check (re-simulation and
trunk range) in a second thread as the study does it. Prints, per chart: the wall time of
covering and checks together, the number of residual evaluations (exact and rough) and AD
Jacobians the covering took, and the checks' own time. The baseline, measured in the
same process at the charts' own centres, is one residual evaluation and one AD Jacobian
of the compiled stride, so that the covering's cost reads as a count of those.
``--record`` writes the cell's figure to ``benchmarks/figures/bench_atlas.json`` for the
README's speed table (issue 20 asks for about 1,000 charts: run with ``--charts 1000``).
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import numpy as np
from figures import Figure, report

from baslip import ReturnMap, Tolerances, load_problem
from baslip.analysis.gaitatlas import CHECK_SAMPLE_TOLERANCE, GaitManifold
from baslip.engine.eventmap import EventMap
from baslip.engine.trajectory import TrunkRange
from baslip.problem.study import Atlas
from baslip.studies.atlascell import CellAtlas
from baslip.studies.sweep import key_column, sweep_tasks


class Counted:
    """A manifold whose residual and Jacobian calls are counted."""

    def __init__(self, manifold: GaitManifold):
        self.manifold, self.evaluations, self.rough, self.jacobians = manifold, 0, 0, 0

    def evaluate(self, w):
        self.evaluations += 1
        return self.manifold.evaluate(w)

    def evaluate_roughly(self, w):
        self.rough += 1
        return self.manifold.evaluate_roughly(w)

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


def stance_sampling_ms(law, params, designs) -> tuple[float, float]:
    """Median ms of one chart's stance samples (the costly part of its trunk range) in
    CasADi's virtual machine (the baseline: the code before) and generated as C, at the
    strides the trunk ranges of ``designs`` (rows of X then u) sample, interleaved."""
    sampled = []

    class Recording(ReturnMap):
        def stance_samples(self, x_touchdown, u, params, duration, n, compiled=False):
            sampled.append((x_touchdown, u, params, duration, n))
            return super().stance_samples(x_touchdown, u, params, duration, n, compiled)

    tolerances = Tolerances(CHECK_SAMPLE_TOLERANCE, CHECK_SAMPLE_TOLERANCE)
    trunk = TrunkRange(Recording(tolerances, law=law))
    for design in designs:
        trunk(design[:4], design[4:], params)
    sampler = EventMap(tolerances, "erk", None, law)
    times: dict[bool, list[float]] = {False: [], True: []}
    for args in sampled:
        for compiled, spent in times.items():
            start = time.perf_counter()
            sampler.stance_samples(*args, compiled=compiled)
            spent.append(1e3 * (time.perf_counter() - start))
    return statistics.median(times[False][1:]), statistics.median(times[True][1:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default="problems/atlas_upright_cell.yaml")
    parser.add_argument("--charts", type=int, default=300)
    parser.add_argument("--record", action="store_true", help="write the figure to benchmarks/figures/")
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
    atlas, _ = cells.cover_and_check(counted, [manifold.to_atlas(np.concatenate([seed.X, seed.u]))])
    wall = time.perf_counter() - start
    n = len(atlas.charts)
    centres = [c.center for c in atlas.charts[:: max(1, n // 50)]]
    start = time.perf_counter()
    for w in centres:
        design = manifold.to_design(w)
        cells.checker(design[:4], design[4:])
    check = (time.perf_counter() - start) / len(centres)
    designs = [manifold.to_design(w) for w in centres]
    sampling_vm, sampling_c = stance_sampling_ms(problem.hip_law, problem.params, designs)
    one_residual = median_ms(manifold.evaluate, centres)
    one_rough = median_ms(manifold.evaluate_roughly, centres)
    one_jacobian = median_ms(manifold.jacobian, centres)
    calls = 1e-3 * (counted.evaluations * one_residual + counted.rough * one_rough + counted.jacobians * one_jacobian)
    cell = ", ".join(f"{k} = {v:g}" for k, v in held.items())
    print(f"{problem.name}, cell {cell}: {n} charts, dimension {atlas.dimension}")
    print(f"  covering and checks {1e3 * wall / n:7.1f} ms a chart ({wall:6.1f} s wall): "
          f"{counted.evaluations / n:5.1f} residuals, {counted.rough / n:5.1f} rough residuals "
          f"and {counted.jacobians / n:4.1f} Jacobians a chart")
    print(f"  a chart's checks (in the second thread) {1e3 * check:7.1f} ms")
    print(f"  a chart's stance samples for its trunk range: {sampling_vm:6.2f} ms in CasADi's virtual machine "
          f"(the code before), {sampling_c:6.2f} ms generated as C ({sampling_vm / sampling_c:4.1f}x)")
    print(f"  baseline, at the charts' centres: residual {one_residual:6.2f} ms, rough residual {one_rough:6.2f} ms, "
          f"AD Jacobian {one_jacobian:6.2f} ms")
    print(f"  wall / (the covering's residuals and Jacobians at the baseline's cost): {wall / calls:5.2f}")
    print(f"  1,000 charts: about {wall / n * 1000:5.0f} s (covering and checks, no seeds, no polish)")
    report("bench_atlas", [Figure(
        20, f"one 2-D cell covered, {n:,} charts ({problem.name}, {cell}), each chart independently checked", wall,
        "s", 30.0, "lower",
        f"from one seed, no polish; {counted.evaluations / n:.1f} residuals, {counted.rough / n:.1f} rough residuals "
        f"and {counted.jacobians / n:.1f} Jacobians a chart, {calls:.1f} s at the cost of single calls in the same "
        f"process ({wall / calls:.2f}x)")], args.record)

if __name__ == "__main__":
    main()
