"""Time-varying control (thesis sec. 4.7, figs. 4.20-4.22), from a perturbed apex.

The run starts at the problem's fixed point X* moved by ``perturbation``. At every apex
X_n the control u_n is re-solved (:class:`baslip.analysis.feedback.ResolvedControl`), by the
thesis's criterion (the next apex as near as possible to X_n: the "control parameters that
best fit to the current state" of sec. 4.7.1) or by tracking (as near as possible to X*).
Each is a least-squares problem: the eps it leaves is recorded, not treated as a failure.
The runner then takes one stride with u_n. After ``strides`` strides the last control is
held fixed and the strides until a fall are counted.

Rows go to ``strides.csv`` one stride at a time, so an interrupted run resumes where it
stopped, exactly: the next apex is re-simulated from the last row, and the re-solve
starts from the last row's control, as it would have.

Finally the largest perturbation that is still recovered is found by bisection on a
factor s of ``perturbation``: recovered means the re-solved runner is still hopping after
``probe_strides`` strides from X* + s * perturbation. The doublings' probes run on both
cores at once, stopped at the first factor not recovered, so the factors asked, and the
answer, are those of one probe at a time.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from baslip.analysis.feedback import ResolvedControl
from baslip.diagnostics import logger
from baslip.engine.outcome import Tolerances
from baslip.engine.returnmap import ReturnMap
from baslip.gait.polish import eps
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import PD, HipLaw
from baslip.problem.reader import Problem
from baslip.problem.study import Adaptive
from baslip.studies.common import StudyFailed, study_table
from baslip.studies.processes import map_in_processes
from baslip.studies.runner import ResumableCsv, Workers
from baslip.viz.labels import problem_title

_log = logger(__name__)


def stride_columns(law: HipLaw = PD) -> list[str]:
    """The columns of strides.csv under ``law``."""
    return ["phase", "n", *APEX.names, *law.controls.names, "eps", "eps_to_gait", "solve_time_s", "note"]


#: Bisection steps on the perturbation factor, and the largest factor tried.
BISECTIONS, LARGEST_FACTOR = 4, 64.0


def run_adaptive(controller: ResolvedControl, X0, params, strides: int, frozen_strides: int, table: ResumableCsv,
                 quiet: bool) -> dict:
    """Run (or resume) the adaptive phase from apex X0, then the frozen phase; return a summary."""
    rmap, X_star = controller.rmap, controller.X_star
    controls = rmap.law.controls
    rows = table.rows
    adaptive = [r for r in rows if r["phase"] == "adaptive"]
    frozen = [r for r in rows if r["phase"] == "frozen"]
    X = np.asarray(X0, dtype=float)
    failure = None
    if adaptive:  # resume: the apex after the last saved stride, as the run had it
        last = adaptive[-1]
        controller.last = _control(last, controls)
        stride = rmap.stride(_apex(last), controller.last, params)
        if stride.fall is not None:
            failure = f"stride {len(adaptive) - 1}: the runner falls ({stride.fall.value})"
        else:
            assert stride.apex is not None
            X = stride.apex
    start = time.perf_counter()
    for n in range(len(adaptive), strides):
        if frozen or failure:
            break
        t0 = time.perf_counter()
        u, residual = controller.control(X)
        solve_time = time.perf_counter() - t0
        table.append({"phase": "adaptive", "n": n, **APEX.to_dict(X), **controls.to_dict(u), "eps": residual,
                      "eps_to_gait": eps(X, X_star), "solve_time_s": solve_time})
        stride = rmap.stride(X, u, params)
        if stride.fall is not None:
            failure = f"stride {n}: the runner falls ({stride.fall.value})"
            break
        assert stride.apex is not None
        X = stride.apex
        if not quiet and (n + 1) % 256 == 0:
            elapsed = time.perf_counter() - start
            _log.info(f"adaptive control: {n + 1}/{strides} strides, {elapsed / (n + 1 - len(adaptive)) * 1e3:.1f} ms a stride")
    adaptive = [r for r in table.rows if r["phase"] == "adaptive"]
    ended = any(r["phase"] == "fall" for r in table.rows) or len(frozen) >= frozen_strides
    if failure is None and adaptive and len(adaptive) == strides and not ended:
        _run_frozen(rmap, adaptive[-1], frozen[-1] if frozen else None, params, frozen_strides, table)
    return summarise(table.rows, failure)


def largest_recovered(context: dict, rmap: ReturnMap, jobs: int | None = None) -> dict:
    """The largest factor s (doubling from 1 to :data:`LARGEST_FACTOR`, then
    :data:`BISECTIONS` bisection steps) for which the runner started at X* + s *
    perturbation is still hopping after ``probe_strides`` re-solved strides.

    ``context`` holds what a probe needs: the gait as :func:`resolved_control` reads it,
    its hip ``law``, the ``perturbation`` and ``probe_strides``. The doublings' probes run at
    once on ``jobs`` worker processes (default one per core), the bisection's here, each
    from a fresh controller, so the answer does not depend on how many run at once.
    """
    perturbation = np.asarray(context["perturbation"], dtype=float)
    found = bisected_factor(
        lambda factors: map_in_processes(_prober, factors, context, jobs, enough=lambda answers: not answers[-1]),
        # Each bisection step needs the one before: in this process, on its map ``rmap``.
        probe_on(rmap, context))
    return {**found, "probe_strides": context["probe_strides"],
            "perturbation": None if found["factor"] is None else (found["factor"] * perturbation).tolist()}


def resolved_control(rmap: ReturnMap, gait: dict) -> ResolvedControl:
    """A fresh re-solving controller on ``rmap`` for ``gait`` (its params, X_star, u_star,
    criterion, fixed controls and their lower and upper bounds)."""
    return ResolvedControl(rmap, gait["params"], gait["X_star"], gait["u_star"], gait["criterion"],
                           fixed=gait["fixed"], lower=gait["lower"], upper=gait["upper"])


def _prober(context: dict):
    """A worker's probe (:func:`probe_on` a map of its own)."""
    return probe_on(ReturnMap(Tolerances(1e-12, 1e-12), law=context["law"]), context)


def probe_on(rmap: ReturnMap, context: dict):
    """The probe on ``rmap`` (the 1e-12 map of the gait's law): factor s -> whether the
    re-solved runner started at X* + s * perturbation still hops after probe_strides
    strides."""
    X_star, params = np.asarray(context["X_star"], dtype=float), context["params"]
    perturbation = np.asarray(context["perturbation"], dtype=float)

    def recovered(s: float) -> bool:
        controller = resolved_control(rmap, context)
        X = X_star + s * perturbation
        for _ in range(context["probe_strides"]):
            u, _ = controller.control(X)
            stride = rmap.stride(X, u, params)
            if not stride.ok or stride.apex is None:
                return False
            X = stride.apex
        return True

    return recovered


def bisected_factor(doublings_at: Callable[[list[float]], list[bool]], recovered: Callable[[float], bool]) -> dict:
    """The largest factor for which the runner is recovered: doubling from 1, then
    bisection. ``doublings_at(factors)`` answers for the leading factors up to the first
    not recovered, all at once (so on both cores); ``recovered(s)`` answers one bisection
    step at a time. The factors asked are those one probe at a time would ask, so the
    answer is the same."""
    doublings = [2.0**k for k in range(round(math.log2(LARGEST_FACTOR)) + 1)]
    answers = doublings_at(doublings)
    if not answers[0]:
        return {"factor": None, "note": "the perturbation itself is not recovered"}
    if all(answers) and len(answers) == len(doublings):
        return {"factor": LARGEST_FACTOR, "note": f"recovered up to the largest factor tried, {LARGEST_FACTOR:g}"}
    failure = answers.index(False)
    low, high = doublings[failure - 1], doublings[failure]
    for _ in range(BISECTIONS):
        middle = (low + high) / 2
        low, high = (middle, high) if recovered(middle) else (low, middle)
    return {"factor": low, "first_not_recovered": high,
            "note": f"recovered at {low:.4g} times the perturbation, not at {high:.4g}"}


def summarise(rows: list[dict], failure: str | None = None) -> dict:
    """Counts and timings of a (finished or partial) adaptive run, from its rows."""
    adaptive = [r for r in rows if r["phase"] == "adaptive"]
    frozen = [r for r in rows if r["phase"] == "frozen"]
    fall = [r for r in rows if r["phase"] == "fall"]
    times = [float(r["solve_time_s"]) for r in adaptive]
    to_gait = [float(r["eps_to_gait"]) for r in adaptive]
    return {
        "adaptive_strides": len(adaptive),
        "adaptive_failure": failure,
        "solve_time_per_stride_s": {"median": float(np.median(times)), "max": float(np.max(times))} if times else None,
        # The last solve before a fall can leave no finite residual (every trial fell).
        "max_eps": max((float(r["eps"]) for r in adaptive if np.isfinite(float(r["eps"]))), default=None),
        "eps_to_gait": {"first": to_gait[0], "last": to_gait[-1], "max": max(to_gait)} if to_gait else None,
        "frozen_strides_before_fall": int(float(fall[0]["n"])) if fall else None,
        "frozen_fall": fall[0]["note"] if fall else None,
        "frozen_strides_run": len(frozen),
    }


def _apex(row) -> np.ndarray:
    return np.array([float(row[n]) for n in APEX.names])


def _control(row, controls) -> np.ndarray:
    return np.array([float(row[n]) for n in controls.names])


def _run_frozen(rmap, last_adaptive, last_frozen, params, frozen_strides: int, table: ResumableCsv) -> None:
    """Hold the last control from the apex after the last adaptive stride (resuming after
    ``last_frozen``): a row per apex reached, and a final 'fall' row whose n counts the
    strides completed."""
    controls = rmap.law.controls
    u = _control(last_adaptive, controls)
    first = rmap.stride(_apex(last_adaptive), u, params)
    if first.fall is not None:
        table.append({"phase": "fall", "n": 0, **APEX.to_dict(_apex(last_adaptive)), **controls.to_dict(u),
                      "note": first.fall.value})
        return
    assert first.apex is not None
    start = first.apex
    X, done = (start, 0) if last_frozen is None else (_apex(last_frozen), int(float(last_frozen["n"])))
    for n in range(done, frozen_strides):
        stride = rmap.stride(X, u, params)
        if stride.fall is not None:
            table.append({"phase": "fall", "n": n, **APEX.to_dict(X), **controls.to_dict(u), "note": stride.fall.value})
            return
        assert stride.apex is not None
        X = stride.apex
        table.append({"phase": "frozen", "n": n + 1, **APEX.to_dict(X), **controls.to_dict(u),
                      "eps": eps(X, start), "solve_time_s": 0.0})


def run_adaptive_study(problem: Problem, study: Adaptive, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers) -> dict:
    """Per-stride re-optimised control from a perturbed apex: the run itself in one lane
    (``lanes`` unused), the probes of the largest recovered perturbation on ``workers.jobs``
    worker processes (default one per core)."""
    from baslip.gait.from_problem import fixed_point_spec, solve_start, solver_for

    solver = solver_for(problem)
    result = solve_start(problem, solver)
    if not result.converged:
        raise StudyFailed(f"the starting fixed point did not converge: {result.status} ({result.message})")
    spec = fixed_point_spec(problem)
    names = problem.hip_law.controls.names
    bounds = np.array([spec.bounds_of(n) for n in names])
    held = tuple(i for i, n in enumerate(names) if n in problem.fix)

    gait = {"law": problem.hip_law, "params": problem.params, "X_star": result.X, "u_star": result.u,
            "criterion": study.criterion, "fixed": held, "lower": bounds[:, 0], "upper": bounds[:, 1]}

    offset = np.array([dict(study.perturbation).get(n, 0.0) for n in APEX.names])
    table = study_table(out_dir / "strides.csv", stride_columns(problem.hip_law), ["phase", "n"], quiet)
    summary = run_adaptive(resolved_control(solver.residual_map, gait), result.X + offset, problem.params,
                           study.strides, study.frozen_strides, table, quiet)
    from baslip.viz.adaptive import adaptive_figures  # drawn in this process only (see baslip.studies)

    adaptive_figures(table.rows, out_dir, problem=problem_title(problem))
    recovery = None
    if offset.any():
        if not quiet:
            _log.info(f"{problem.name}: bisecting the largest recovered perturbation...")
        recovery = largest_recovered({**gait, "perturbation": offset, "probe_strides": study.probe_strides},
                                     solver.residual_map, workers.jobs)
    return {
        "start": {"apex": result.apex, "control": result.control, "spectral_radius": result.spectral_radius},
        "perturbation": dict(study.perturbation),
        "criterion": study.criterion,
        **summary,
        "largest_recovered": recovery,
    }
