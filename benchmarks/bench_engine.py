"""Benchmark of the compiled stride engine against the adaptive erk event map.

    python benchmarks/bench_engine.py [--repeats N] [--cold]

Both engines run side by side in one process; each row prints the two medians and their
ratio. The baseline is the event map in CasADi's virtual machine, the engine of every
stride before the compiled engine existed; the stride rows also show the event map
generated as C. ``--cold`` also times a first CLI run into an empty cache (code
generation and gcc for the engine, the NLP and the verification). A last table gives
issue 22's figures from the same measurements: the engine's stride against the event map
as C, the Jacobian's cost in strides, and the batched rate, each beside its target;
``--record`` writes them to ``benchmarks/figures/bench_engine.json`` for the README's
speed table (``speed_table.py``).
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import replace

import numpy as np
from figures import Figure, quantity, report

from baslip import FixedPointSolver, Params, ReturnMap, Tolerances, load_problem
from baslip.gait.from_problem import fixed_point_spec

X_RUN = np.array([0.4, -math.pi / 2 + 0.02, 0.5, 0.1])
U_RUN = np.array([0.1, 0.01, 0.2, 0.0, 0.15])
X_GAIT = np.array([0.4, -1.5657, 0.5, 0.164274])  # near the shipped downward gait
U_GAIT = np.array([-0.751879, 1.50002, -0.05246, 1.42038, 0.11471])


def median_s(fn, repeats: int) -> float:
    """Median time [s] of ``fn(k)`` for k = 1 .. repeats, after one call ``fn(0)``. Each call
    should ask for inputs not asked for before in the process (:func:`unseen`): the
    compiled engine remembers its last few strides (:mod:`baslip.engine.recent`), and the
    same stride again would time its memo."""
    fn(0)
    times = []
    for k in range(1, repeats + 1):
        start = time.perf_counter()
        fn(k)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def unseen(X: np.ndarray, counter: Iterator[int]) -> np.ndarray:
    """Apex ``X`` with theta_h_dot moved by k * 1e-12 rad/s, k the next number of
    ``counter``: a stride of the same cost that the engine has not seen (the memo's keys
    are the inputs' exact bytes). One counter for a whole process makes every timed call
    new to the memo: a value and a Jacobian timed one after the other at the same nudges
    would time the Jacobian alone, its value remembered."""
    return X + np.array([0.0, 0.0, 0.0, 1e-12 * next(counter)])


def row(what: str, old: float, new: float, unit: str = "ms", middle: float | None = None) -> None:
    scale = {"ms": 1e3, "us": 1e6}[unit]
    between = "-" if middle is None else quantity(middle * scale, unit)
    print(f"| {what} | {quantity(old * scale, unit)} | {between} | {quantity(new * scale, unit)} | {old / new:.1f}x |")


def strides_per_second(rmap: ReturnMap, starts: np.ndarray, u, p) -> float:
    start = time.perf_counter()
    for X in starts:
        rmap.stride(X, u, p)
    return len(starts) / (time.perf_counter() - start)


def solve_time(solver: FixedPointSolver, spec, repeats: int) -> float:
    """Median time [s] of a verified solve, each from a guess moved by 1e-12 rad in
    theta_td, so that the polish's strides are new to the engine's memo."""
    def solve(k: int):
        guess = {**spec.guess, "theta_td": spec.guess["theta_td"] + 1e-12 * k}
        return solver.solve(replace(spec, guess=guess), "downward")

    return median_s(solve, repeats)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--cold", action="store_true", help="also time the first compile")
    parser.add_argument("--record", action="store_true", help="write issue 22's figures to benchmarks/figures/")
    args = parser.parse_args()
    p = Params()
    targets: list[Figure] = []  # issue 22's figures, from the same measurements
    calls = itertools.count(1)  # every timed stride new to the engine's memo
    print("| what | erk event map (VM) | erk event map (C) | compiled engine | ratio to the VM |")
    print("|---|---|---|---|---|")
    for tol in (1e-10, 1e-12):
        old = ReturnMap(Tolerances(tol, tol), plugin="erk", compile=False)
        old_in_c, new = ReturnMap(Tolerances(tol, tol), plugin="erk"), ReturnMap(Tolerances(tol, tol))
        # The engine loads its Jacobians' library in a thread (baslip.engine.kernels); a
        # first Jacobian waits for it, so that no stride below is timed beside that load
        # (it doubled the first row's median: 290 us against 150 us).
        new.jacobians(X_RUN, U_RUN, p)
        for name, X, u in (("running stride", X_RUN, U_RUN), ("downward gait", X_GAIT, U_GAIT)):
            r_engine = median_s(lambda k: new.stride(unseen(X, calls), u, p), args.repeats)
            r_in_c = median_s(lambda k: old_in_c.stride(unseen(X, calls), u, p), args.repeats)
            row(f"r, {name}, tol {tol:g}", median_s(lambda k: old.stride(unseen(X, calls), u, p), args.repeats),
                r_engine, "us", r_in_c)
            r_and_j = median_s(lambda k: new.jacobians(unseen(X, calls), u, p), args.repeats)
            r_and_j_old = median_s(lambda k: old.jacobians(unseen(X, calls), u, p), args.repeats)
            row(f"r + dr/dX + dr/du, {name}, tol {tol:g}", r_and_j_old, r_and_j, "us")
            targets.append(Figure(22, f"one stride r, {name}, tol {tol:g}: CasADi's erk event map as C over the "
                                  "engine", r_in_c / r_engine, "x", 2.0, "higher",
                                  f"medians of {args.repeats} in one process: engine {1e6 * r_engine:.0f} us, "
                                  f"event map as C {1e6 * r_in_c:.0f} us"))
            targets.append(Figure(22, f"r + dr/dX + dr/du over r, {name}, tol {tol:g}", r_and_j / r_engine, "x", 3.0,
                                  "lower", f"engine {1e6 * r_and_j:,.0f} us against {1e6 * r_engine:,.0f} us "
                                  f"(the event map in the VM: {1e3 * r_and_j_old:.1f} ms)"))
        rng = np.random.default_rng(0)
        for name, X, u, spread in (("the downward gait", X_GAIT, U_GAIT, [0.01, 0.05, 0.05, 0.2]),
                                   ("the running stride", X_RUN, U_RUN, [0.01, 0.02, 0.05, 0.1])):
            starts = X + rng.normal(scale=spread, size=(200, 4))
            rate_old, rate_new = strides_per_second(old, starts, u, p), strides_per_second(new, starts, u, p)
            print(f"| strides/s, 200 starts near {name}, one at a time, tol {tol:g} | {rate_old:,.0f} | - | "
                  f"{rate_new:,.0f} | {rate_new / rate_old:.1f}x |")
            many = X + rng.normal(scale=spread, size=(4096, 4))
            new.strides(many[:64], u, p)  # builds the batch engine
            rate_batch = len(many) / median_s(lambda k: new.strides(many, u, p), 5)  # 4,096 strides: no memo holds them
            print(f"| strides/s, 4096 starts near {name}, `ReturnMap.strides` (2 threads), tol {tol:g} | "
                  f"{rate_old:,.0f} | - | {rate_batch:,.0f} | {rate_batch / rate_old:.1f}x |")
            if tol == 1e-10 and name == "the running stride":
                targets.append(Figure(22, f"strides/s, 4,096 batched near {name}, tol {tol:g}, 2 threads",
                                      rate_batch, "/s", 30000.0, "higher",
                                      f"median of 5 batches; the erk event map in the VM, one at a time: "
                                      f"{rate_old:,.0f} /s ({rate_batch / rate_old:.0f}x)"))

    spec = fixed_point_spec(load_problem("problems/downward.yaml"))
    new_solver = FixedPointSolver()
    old_solver = FixedPointSolver()
    old_solver.residual_map = ReturnMap(Tolerances(1e-12, 1e-12), plugin="erk", compile=False)
    old_solver.jacobian_map = ReturnMap(Tolerances(1e-10, 1e-10), plugin="erk", compile=False)
    old_solver.verify_map = ReturnMap(Tolerances(1e-12, 1e-12), plugin="rosenbrock", compile=False)
    repeats = max(3, args.repeats // 5)
    row("verified solve of downward (NLP, polish, verification, stability)",
        solve_time(old_solver, spec, repeats), solve_time(new_solver, spec, repeats))
    result = new_solver.solve(spec, "downward")
    print(f"\n(downward with the compiled engine: {result.status}, eps = {result.residual:.2e}, "
          f"{result.polish_iterations} polish steps, spectral radius {result.spectral_radius:.6f})")

    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "baslip.solve", "problems/downward.yaml", "--out", out],
                       check=True, capture_output=True)
        print(f"whole CLI process, warm cache: {time.perf_counter() - start:.2f} s")
    report("bench_engine", targets, args.record)
    if args.cold:
        with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
            env = dict(os.environ, BASLIP_CACHE_DIR=cache)
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "baslip.solve", "problems/downward.yaml", "--out", out],
                           check=True, env=env, capture_output=True)
            print(f"first CLI run on an empty cache (generates and compiles the engine and the NLP): "
                  f"{time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
