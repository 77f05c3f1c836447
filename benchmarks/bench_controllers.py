"""Benchmark of the controllers and hip laws: what a basin, a re-solve and a VPP stride cost.

    python benchmarks/bench_controllers.py [--starts 4000] [--strides 100]

Prints, for each gait (the problem files' gaits):

* the wall time of a basin of ``--starts`` starts of up to ``--strides`` strides in the 4x
  box under the constant law and under the tuned feedback, run in lockstep through the
  batched engine on both cores;
* the median cost a stride of the two-stride receding-horizon re-solve (40 starts): a
  run's wall time over its strides, median over the runs; and each apex's re-solve alone
  (its median over all strides, and over the runs' first apexes, where the plan starts
  from the largest miss);
* the cost of one VPP stride against one PD stride, measured in the same process at the
  thesis-scale gaits of ``problems/vpp.yaml`` and ``problems/upward.yaml``.

``--record`` writes these figures to ``benchmarks/figures/bench_controllers.json`` for the
README's speed table.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from figures import Figure, report

from baslip import ReturnMap, Tolerances, load_problem
from baslip.analysis.feedback import (
    ConstantControl,
    LinearFeedback,
    control_scale,
    run_closed_loop,
    run_closed_loop_many,
)
from baslip.analysis.horizon import RecedingHorizon
from baslip.gait.from_problem import fixed_point_spec, solve_start, solver_for
from baslip.model.dynamics import APEX
from baslip.studies.controllers import feedback_for

GAITS = ("controllers_upright", "controllers_upright_best", "controllers_downward", "controllers_vpp",
         "controllers_vpp_human")


def _gait(name: str):
    problem = load_problem(f"problems/{name}.yaml")
    solver = solver_for(problem)
    gait = solve_start(problem, solver)
    spec = fixed_point_spec(problem)
    bounds = np.array([spec.bounds_of(n) for n in problem.hip_law.controls.names])
    return problem, gait, bounds


def _basin(rmap, problem, gait, controller, starts, strides) -> tuple[float, float]:
    settle = any(m.trivial for m in gait.multipliers)
    began = time.perf_counter()
    runs = run_closed_loop_many(rmap, problem.params, controller, starts, gait.X, strides, 1e-6, settle)
    share = sum(r.outcome in ("converged", "settled") for r in runs) / len(runs)
    return time.perf_counter() - began, share


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=4000)
    parser.add_argument("--strides", type=int, default=100)
    parser.add_argument("--record", action="store_true", help="write the figures to benchmarks/figures/")
    args = parser.parse_args()
    basins, horizons = [], []
    for name in GAITS:
        problem, gait, bounds = _gait(name)
        rmap = ReturnMap(Tolerances(1e-12, 1e-12), law=problem.hip_law)
        widths = np.array([dict(problem.study.perturbation)[n] for n in APEX.names]) * 4
        starts = gait.X + np.random.default_rng(0).uniform(-1, 1, (args.starts, APEX.size)) * widths
        A, B = rmap.jacobians(gait.X, gait.u, problem.params)
        context = {"X": gait.X, "u": gait.u, "params": problem.params, "lower": bounds[:, 0], "upper": bounds[:, 1],
                   "tolerance": 1e-6, "settle": any(m.trivial for m in gait.multipliers),
                   "neutral": sum(m.trivial for m in gait.multipliers)}
        began = time.perf_counter()
        choice = feedback_for(problem.study, context, A, B, control_scale(problem.hip_law), rmap)
        tuning = time.perf_counter() - began
        constant = _basin(rmap, problem, gait, ConstantControl(gait.u),
                          starts, args.strides)
        feedback = _basin(rmap, problem, gait, LinearFeedback(gait.X, gait.u, choice.K, bounds[:, 0], bounds[:, 1]),
                          starts, args.strides)
        held = tuple(i for i, n in enumerate(problem.hip_law.controls.names) if n in problem.fix)
        costs, solves, first = [], [], []
        for start in starts[:40]:
            controller = Timed(RecedingHorizon(rmap, problem.params, gait.X, gait.u, 2, held, bounds[:, 0],
                                               bounds[:, 1], K=choice.K, family=context["settle"]))
            began = time.perf_counter()
            run = run_closed_loop(rmap, problem.params, controller, start, gait.X, 30)
            costs.append(1e3 * (time.perf_counter() - began) / max(len(run.controls), 1))
            solves += controller.costs
            first += controller.costs[:1]
        print(f"{name}: tuning {tuning:.1f} s ({choice.kind}); {args.starts}-start basin at 4x: constant "
              f"{constant[0]:.1f} s ({constant[1]:.0%} back), feedback {feedback[0]:.1f} s ({feedback[1]:.0%} back); "
              f"receding horizon, median {statistics.median(costs):.1f} ms a stride", flush=True)
        basins.append(Figure(21, f"a {args.starts:,}-start basin of up to {args.strides} strides, 4x box, `{name}`, "
                                 "the slower of constant and feedback", max(constant[0], feedback[0]), "s", 60.0,
                             "lower", f"batched, both cores: constant {constant[0]:.1f} s, feedback "
                                      f"{feedback[0]:.1f} s ({choice.kind})"))
        horizons.append(Figure(21, f"two-stride receding horizon, median a stride, `{name}`",
                               statistics.median(costs), "ms", 5.0, "lower",
                               f"a run's wall time over its strides, median of 40 runs from the 4x box (at "
                               f"most 30 strides each; quartiles {np.percentile(costs, 25):.1f} and "
                               f"{np.percentile(costs, 75):.1f} ms); each apex's re-solve alone, over all "
                               f"{len(solves)} strides: median {statistics.median(solves):.1f} ms, 90th "
                               f"percentile {np.percentile(solves, 90):.1f} ms; the first apex's: median "
                               f"{statistics.median(first):.1f} ms"))
    report("bench_controllers", [*basins, *horizons, _stride_ratio()], args.record)


class Timed:
    """A controller whose every ``control`` call is timed (``costs``, ms, in order)."""

    def __init__(self, controller):
        self.controller, self.costs = controller, []

    def control(self, X):
        began = time.perf_counter()
        answer = self.controller.control(X)
        self.costs.append(1e3 * (time.perf_counter() - began))
        return answer

    def __getattr__(self, name):
        return getattr(self.controller, name)


def _stride_ratio(repeats: int = 400) -> Figure:
    """One VPP stride against one PD stride, the compiled engine at 1e-10, same process.
    Each repeat nudges theta_h_dot by k * 1e-12 rad/s: the engine remembers its last few
    strides, and the same stride again would time that memo, not a stride."""
    timings = {}
    for name in ("upward", "vpp"):
        problem = load_problem(f"problems/{name}.yaml")
        gait = solve_start(problem)
        rmap = ReturnMap(Tolerances(1e-10, 1e-10), law=problem.hip_law)
        rmap.stride(gait.X, gait.u, problem.params)
        nudge = np.zeros(APEX.size)
        began = time.perf_counter()
        for k in range(1, repeats + 1):
            nudge[APEX.index("theta_h_dot")] = 1e-12 * k
            rmap.stride(gait.X + nudge, gait.u, problem.params)
        timings[name] = (time.perf_counter() - began) / repeats
    print(f"one stride: PD {1e6 * timings['upward']:.0f} us, VPP {1e6 * timings['vpp']:.0f} us, "
          f"ratio {timings['vpp'] / timings['upward']:.2f}")
    return Figure(21, "a VPP stride over a PD stride (thesis-scale gaits, compiled engine, tol 1e-10)",
                  timings["vpp"] / timings["upward"], "x", 1.5, "lower",
                  f"means of {repeats} new strides in one process: VPP {1e6 * timings['vpp']:.0f} us, "
                  f"PD {1e6 * timings['upward']:.0f} us")


if __name__ == "__main__":
    main()
