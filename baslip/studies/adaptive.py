"""Time-varying control (thesis sec. 4.7, figs. 4.20-4.22).

From a fixed point, at every apex X_n the control u_n is re-solved from the current state
so that X_n is a fixed point of r(., u_n): Gauss-Newton on r(X_n, u) - X_n = 0 over the
five entries of u (four equations: the minimum-norm step from u_{n-1}). The runner then
takes one stride with u_n. After ``strides`` strides the last control is held fixed and the
strides until a fall are counted.

Rows go to ``strides.csv`` one stride at a time, so an interrupted run resumes where it
stopped.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from ..control import CONTROL
from ..fixedpoint import FixedPointSolver
from ..model import APEX, Params
from ..quantities import NOMINAL
from .runner import ResumableCsv

STRIDE_COLUMNS = ["phase", "n", *APEX.names, *CONTROL.names, "eps", "solve_time_s", "note"]
#: Re-solve: stop when eps <= this; give up after MAX_STEPS Gauss-Newton steps.
CONTROL_EPS, MAX_STEPS = 1e-12, 8


class ControlSolveFailed(RuntimeError):
    pass


def control_for_apex(solver: FixedPointSolver, X, u0, params: Params) -> tuple[np.ndarray, float]:
    """A control that makes apex X a fixed point, nearest (min-norm) to u0; and its eps."""
    scale = np.array([NOMINAL[n] for n in CONTROL.names])
    u = np.asarray(u0, dtype=float).copy()
    for _ in range(MAX_STEPS + 1):
        stride = solver.residual_map.stride(X, u, params)
        if not stride.ok:
            raise ControlSolveFailed(f"the runner falls ({stride.fall.value})")
        residual = stride.apex - X
        eps = float(np.linalg.norm(residual) / np.linalg.norm(X))
        if eps <= CONTROL_EPS:
            return u, eps
        dr_du = solver.jacobian_map.jacobians(X, u, params)[1]
        u = u + scale * np.linalg.lstsq(dr_du * scale, -residual, rcond=1e-9)[0]
    raise ControlSolveFailed(f"no control within {MAX_STEPS} steps (eps = {eps:.1e})")


def run_adaptive(solver, X0, u0, params, strides: int, frozen_strides: int, table: ResumableCsv, quiet: bool) -> dict:
    """Run (or resume) the adaptive phase, then the frozen phase; return a summary."""
    rows = table.rows
    adaptive = [r for r in rows if r["phase"] == "adaptive"]
    frozen = [r for r in rows if r["phase"] == "frozen"]
    X, u = np.asarray(X0, dtype=float), np.asarray(u0, dtype=float)
    start = time.perf_counter()
    failure = None
    if adaptive:  # resume: the apex after the last saved stride, as the run had it
        last = adaptive[-1]
        u = np.array([float(last[n]) for n in CONTROL.names])
        stride = solver.residual_map.stride(_apex(last), u, params)
        X = stride.apex
        if not stride.ok:
            failure = f"stride {len(adaptive) - 1}: the runner falls ({stride.fall.value})"
    for n in range(len(adaptive), strides):
        if frozen or failure:
            break
        t0 = time.perf_counter()
        try:
            u, eps = control_for_apex(solver, X, u, params)
        except ControlSolveFailed as err:
            failure = f"stride {n}: {err}"
            break
        solve_time = time.perf_counter() - t0
        table.append({"phase": "adaptive", "n": n, **APEX.to_dict(X), **CONTROL.to_dict(u), "eps": eps, "solve_time_s": solve_time})
        stride = solver.residual_map.stride(X, u, params)
        if not stride.ok:
            failure = f"stride {n}: the runner falls ({stride.fall.value})"
            break
        X = stride.apex
        if not quiet and (n + 1) % 16 == 0:
            elapsed = time.perf_counter() - start
            print(f"\radaptive control: {n + 1}/{strides} strides, {elapsed / (n + 1 - len(adaptive)) * 1e3:.0f} ms a stride   ",
                  end="", file=sys.stderr, flush=True)
    if not quiet:
        print(file=sys.stderr)
    adaptive = [r for r in table.rows if r["phase"] == "adaptive"]
    ended = any(r["phase"] == "fall" for r in table.rows) or len(frozen) >= frozen_strides
    if failure is None and adaptive and len(adaptive) == strides and not ended:
        _run_frozen(solver, adaptive[-1], frozen[-1] if frozen else None, params, frozen_strides, table)
    return summarise(table.rows, failure)


def summarise(rows: list[dict], failure: str | None = None) -> dict:
    """Counts and timings of a (finished or partial) adaptive run, from its rows."""
    adaptive = [r for r in rows if r["phase"] == "adaptive"]
    frozen = [r for r in rows if r["phase"] == "frozen"]
    fall = [r for r in rows if r["phase"] == "fall"]
    times = [float(r["solve_time_s"]) for r in adaptive]
    return {
        "adaptive_strides": len(adaptive),
        "adaptive_failure": failure,
        "solve_time_per_stride_s": {"median": float(np.median(times)), "max": float(np.max(times))} if times else None,
        "max_eps": max((float(r["eps"]) for r in adaptive), default=None),
        "frozen_strides_before_fall": int(float(fall[0]["n"])) if fall else None,
        "frozen_fall": fall[0]["note"] if fall else None,
        "frozen_strides_run": len(frozen),
    }


def _apex(row) -> np.ndarray:
    return np.array([float(row[n]) for n in APEX.names])


def _run_frozen(solver, last_adaptive, last_frozen, params, frozen_strides: int, table: ResumableCsv) -> None:
    """Hold the last control from the last adaptive apex (resuming after ``last_frozen``):
    a row per apex reached, and a final 'fall' row whose n counts the strides completed."""
    start = _apex(last_adaptive)
    u = np.array([float(last_adaptive[n]) for n in CONTROL.names])
    X, done = (start, 0) if last_frozen is None else (_apex(last_frozen), int(float(last_frozen["n"])))
    for n in range(done, frozen_strides):
        stride = solver.residual_map.stride(X, u, params)
        if not stride.ok:
            table.append({"phase": "fall", "n": n, **APEX.to_dict(X), **CONTROL.to_dict(u), "note": stride.fall.value})
            return
        X = stride.apex
        eps_from_start = float(np.linalg.norm(X - start) / np.linalg.norm(start))
        table.append({"phase": "frozen", "n": n + 1, **APEX.to_dict(X), **CONTROL.to_dict(u), "eps": eps_from_start, "solve_time_s": 0.0})
