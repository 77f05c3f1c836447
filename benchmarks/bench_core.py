"""Benchmark of the adaptive event map (the reference and fallback engine): return map,
its Jacobian, and a verified fixed-point solve. The compiled engine has its own,
``bench_engine.py``.

    python benchmarks/bench_core.py [--repeats N]

Prints medians over repeated runs in one process, after everything is built. Also compares
the two ways of locating stance events that CasADi offers (see docs/background/engine.md, "Event location"):

* A: one ``erk`` integrator with zero-crossing events and a transition function (the
  event map's route);
* B: a ``cvodes`` integrator over a time-scaled horizon, with a Newton ``rootfinder`` on
  the liftoff guard (each Newton iteration re-integrates the stance).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from dataclasses import replace

import casadi as ca
import numpy as np

from baslip import FixedPointSolver, Params, ReturnMap, Tolerances, load_problem
from baslip.gait.from_problem import fixed_point_spec, shooting_options
from baslip.model.dynamics import PARAMS, STANCE, build_model, liftoff_guard, stance_dynamics
from baslip.model.hiplaw import CONTROL, hip_torque

X_RUN = np.array([0.4, -math.pi / 2 + 0.02, 0.5, 0.1])
U_RUN = np.array([0.1, 0.01, 0.2, 0.0, 0.15])


def median_ms(fn, repeats: int) -> float:
    fn()  # warm up (lazy set-up inside CasADi)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def rootfinder_stance(tol: float):
    """Route B: liftoff time by Newton on the guard; returns (stance map, its Jacobian)."""
    x0, u, p, T = STANCE.sym("x0", ca.MX), CONTROL.sym("u", ca.MX), PARAMS.sym("p", ca.MX), ca.MX.sym("T")
    xs, us, ps, Ts = STANCE.sym("x"), CONTROL.sym("u"), PARAMS.sym("p"), ca.SX.sym("T")
    flow = ca.integrator(
        "flow", "cvodes",
        {"x": xs, "p": ca.vertcat(us, ps, Ts), "ode": Ts * stance_dynamics(xs, hip_torque(xs, us), ps)},
        0.0, 1.0, {"reltol": tol, "abstol": tol},
    )
    end = flow(x0=x0, p=ca.vertcat(u, p, T))["xf"]
    guard = ca.Function("guard", [T, ca.vertcat(x0, u, p)], [liftoff_guard(end, p)])
    newton = ca.rootfinder("liftoff", "newton", guard, {"abstol": 1e-14})
    T_guess = ca.MX.sym("T_guess")
    t_lo = newton(T_guess, ca.vertcat(x0, u, p))
    x_lo = flow(x0=x0, p=ca.vertcat(u, p, t_lo))["xf"]
    value = ca.Function("stance_B", [x0, u, p, T_guess], [x_lo, t_lo])
    jac = ca.Function("stance_B_jac", [x0, u, p, T_guess], [ca.jacobian(x_lo, ca.vertcat(x0, u))])
    return value, jac


def hop_event_error(stance_time: float, params: Params) -> float:
    """|stance time - closed form| for the vertical hop from z = 0.4 m [s]."""
    drop = 0.4 - params.d - params.rho0
    omega = math.sqrt(params.k / params.m)
    phase = math.atan2(-math.sqrt(2 * params.g * drop) / omega, params.m * params.g / params.k)
    return abs(stance_time - 2 * (math.pi + phase) / omega)


def bench_event_routes(params: Params, repeats: int) -> None:
    model = build_model()
    p = params.vector()
    print("\nEvent location, stance only (touchdown state of a running stride):")
    print(f"  {'route':<28} {'tol':>6} {'value ms':>9} {'+Jacobian ms':>13} {'hop event error s':>18}")
    for tol in (1e-10, 1e-12):
        rmap = ReturnMap(Tolerances(tol, tol), plugin="erk")
        t_td = rmap.touchdown_guess(X_RUN, U_RUN, p)
        # Route A in isolation: the stance integrator of the return map.
        stride = rmap.stride(X_RUN, U_RUN, params)
        hop = rmap.stride([0.4, math.pi / 2, 0.0, 0.0], np.zeros(5), params)
        a_value = median_ms(lambda: rmap.stride(X_RUN, U_RUN, params), repeats)
        a_jac = median_ms(lambda: rmap.jacobians(X_RUN, U_RUN, params), max(3, repeats // 5))
        a_err = hop_event_error(hop.durations["compression"] + hop.durations["decompression"], params)
        print(f"  {'A: erk + events (whole map)':<28} {tol:>6.0e} {a_value:>9.2f} {a_jac:>13.1f} {a_err:>18.1e}")
        # Route B: Newton on the liftoff guard.
        value, jac = rootfinder_stance(tol)
        xf_td = np.array([0.0, 0.0, X_RUN[1], X_RUN[2], -params.g * t_td, X_RUN[3]])
        x_td = np.asarray(model.touchdown_map(xf_td, U_RUN[4], p)).ravel()
        guess = stride.durations["compression"] + stride.durations["decompression"]
        b_value = median_ms(lambda: value(x_td, U_RUN, p, guess * 1.01), repeats)
        b_jac = median_ms(lambda: jac(x_td, U_RUN, p, guess * 1.01), max(3, repeats // 5))
        hop_td = np.asarray(model.touchdown_map([0, 0, math.pi / 2, 0, -math.sqrt(2 * params.g * 0.16), 0], 0.0, p)).ravel()
        b_err = hop_event_error(float(value(hop_td, np.zeros(5), p, 0.11)[1]), params)
        print(f"  {'B: cvodes + rootfinder':<28} {tol:>6.0e} {b_value:>9.2f} {b_jac:>13.1f} {b_err:>18.1e}")


def bench_solves(repeats: int) -> None:
    print("\nFixed-point solve from the YAML guess (NLP + Newton polish + verification + stability):")
    for name in ("downward", "upward"):
        problem = load_problem(f"problems/{name}.yaml")
        start = time.perf_counter()
        solver = FixedPointSolver(shooting_options(problem))
        build_s = time.perf_counter() - start
        spec = fixed_point_spec(problem)
        results = []
        moved = [0]

        def solve():
            # A guess moved by 1e-12 rad each time: the compiled engine remembers its last
            # strides (baslip.engine.recent), and the same polish again would time its memo.
            moved[0] += 1
            guess = {**spec.guess, "theta_td": spec.guess["theta_td"] + 1e-12 * moved[0]}
            results.append(solver.solve(replace(spec, guess=guess), name=name))

        total = median_ms(solve, repeats)
        r = results[-1]
        print(
            f"  {name:<9} build {build_s:5.2f} s | solve median {total:7.1f} ms "
            f"(IPOPT {r.solver.iterations} it, polish {r.polish_iterations}) | eps {r.residual:.1e} | {r.status}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=10)
    args = parser.parse_args()
    params = Params()
    print("Return map r(X, u) of a running stride by the erk event map, median per evaluation:")
    for tol in (1e-8, 1e-10, 1e-12):
        rmap = ReturnMap(Tolerances(tol, tol), plugin="erk")
        value = median_ms(lambda: rmap.stride(X_RUN, U_RUN, params), args.repeats)
        both = median_ms(lambda: (rmap.stride(X_RUN, U_RUN, params), rmap.jacobians(X_RUN, U_RUN, params)), max(3, args.repeats // 3))
        print(f"  rtol = atol = {tol:.0e}: r {value:6.2f} ms | r + dr/dX + dr/du {both:7.1f} ms")
    bench_event_routes(params, args.repeats)
    bench_solves(args.repeats)


if __name__ == "__main__":
    main()
