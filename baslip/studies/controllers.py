"""The ``controllers`` study: three stride-to-stride controllers on one gait, compared.

The gait is the problem's fixed point. Apex states are drawn uniformly from the box
X* +- ``perturbation`` (four dimensions, seeded); from each, every controller runs for at
most ``strides`` strides (:func:`baslip.analysis.feedback.run_closed_loop`):

* ``constant``: the constant PD hip law, u = u*;
* ``feedback``: u = u* + K (X - X*), K deadbeat where dr/du has rank 4, else discrete LQR
  with Q = diag(1 / lqr_scale^2) and R = diag(1 / nominal control sizes^2);
* ``resolve``: u re-solved at every apex (``criterion``: thesis or tracking).

A run has *converged* once an apex is within ``tolerance`` (eq. 4.1) of X*; it is
*bounded* if it neither converged nor fell. The basin fraction of a controller is the
share of the box's samples that converge.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from baslip.files.rows import read_points
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import CONTROL
from baslip.model.quantities import NOMINAL
from baslip.problem.reader import Problem
from baslip.problem.study import Controllers
from baslip.studies.common import StudyFailed, run_info, study_table
from baslip.studies.runner import Workers, run_tasks, split_lanes
from baslip.viz import figures

CONTROLLERS = ("constant", "feedback", "resolve")
CONTROLLER_COLUMNS = [
    "controller", "sample", *(f"d_{n}" for n in APEX.names), "outcome", "strides_run", "strides_to_converge",
    "final_eps", "max_residual", "ms_per_stride",
]


def controller_tasks(study: Controllers) -> list[dict]:
    """Every (controller, sample) with its perturbation; samples drawn once, shared."""
    rng = np.random.default_rng(study.seed)
    widths = dict(study.perturbation)
    deltas = rng.uniform(-1, 1, size=(study.samples, APEX.size)) * np.array([widths.get(n, 0.0) for n in APEX.names])
    return [
        {"controller": name, "sample": k, **{f"d_{n}": round(float(v), 15) for n, v in zip(APEX.names, delta)}}
        for name in CONTROLLERS for k, delta in enumerate(deltas)
    ]


def lqr_weights(study: Controllers) -> np.ndarray:
    """Q of the LQR: an apex deviation of lqr_scale (default: the nominal size) costs as
    much as a nominal change of a control."""
    scale = dict(study.lqr_scale)
    return np.diag([1 / scale.get(n, NOMINAL[n]) ** 2 for n in APEX.names])


def make_controller(name: str, context: dict, rmap):
    from baslip.analysis.feedback import ConstantControl, LinearFeedback, ResolvedControl

    X, u = context["X"], context["u"]
    if name == "constant":
        return ConstantControl(u)
    if name == "feedback":
        return LinearFeedback(X, u, context["K"], context["lower"], context["upper"])
    return ResolvedControl(rmap, context["params"], X, u, context["criterion"], fixed=context["held"],
                           lower=context["lower"], upper=context["upper"])


def controllers_worker(chunk: list[dict], context: dict, queue) -> None:
    """Worker process: run each task's controller from its perturbed apex."""
    from baslip.analysis.feedback import run_closed_loop
    from baslip.engine.returnmap import ReturnMap, Tolerances
    from baslip.gait.polish import eps

    try:
        rmap = ReturnMap(Tolerances(1e-12, 1e-12))
        for task in chunk:
            if task.get("done"):
                continue
            X0 = context["X"] + np.array([task[f"d_{n}"] for n in APEX.names])
            controller = make_controller(task["controller"], context, rmap)
            started = time.perf_counter()
            run = run_closed_loop(rmap, context["params"], controller, X0, context["X"], context["strides"],
                                  context["tolerance"])
            elapsed = time.perf_counter() - started
            queue.put({
                **task, "outcome": run.outcome, "strides_run": len(run.controls),
                "strides_to_converge": run.strides_to_converge,
                "final_eps": eps(run.apexes[-1], context["X"]),
                "max_residual": float(np.max(run.residuals)) if len(run.residuals) else 0.0,
                "ms_per_stride": 1e3 * elapsed / max(len(run.controls), 1),
            })
    finally:
        queue.put(None)


def run_controllers(problem: Problem, study: Controllers, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers) -> dict:
    """Three stride-to-stride controllers on one gait, from the same perturbed starts."""
    from baslip.analysis.feedback import CONTROL_SCALE, closed_loop_multipliers, control_rank, deadbeat_gain, lqr_gain
    from baslip.gait.from_problem import fixed_point_spec, solve_start, solver_for

    solver = solver_for(problem)
    gait = solve_start(problem, solver)
    if not gait.converged:
        raise StudyFailed(f"the gait did not converge: {gait.status} ({gait.message})")
    A, B = solver.jacobian_map.jacobians(gait.X, gait.u, problem.params)
    rank = control_rank(B)
    try:
        K = deadbeat_gain(A, B) if rank == APEX.size else lqr_gain(A, B, lqr_weights(study), np.diag(1 / CONTROL_SCALE**2))
    except ValueError as err:
        raise StudyFailed(f"no linear feedback for this gait: {err}") from None
    spec = fixed_point_spec(problem)
    bounds = np.array([spec.bounds_of(n) for n in CONTROL.names])
    context = {
        "X": gait.X, "u": gait.u, "K": K, "params": problem.params, "strides": study.strides,
        "tolerance": study.tolerance, "criterion": study.criterion, "lower": bounds[:, 0], "upper": bounds[:, 1],
        "held": tuple(i for i, n in enumerate(CONTROL.names) if n in problem.fix),
    }
    table = study_table(out_dir / "controllers.csv", CONTROLLER_COLUMNS, ["controller", "sample"], quiet)
    report = run_tasks(split_lanes(controller_tasks(study), lanes), controllers_worker, context, table,
                       problem.name, quiet=quiet, workers=workers)
    rows = read_points(out_dir / "controllers.csv")
    figures.controllers_figure(rows, dict(study.perturbation), out_dir)
    multipliers = closed_loop_multipliers(A, B, K)

    def tally(name: str) -> dict:
        mine = [r for r in rows if r["controller"] == name]
        converged = [r for r in mine if r["outcome"] == "converged"]
        return {
            "samples": len(mine),
            "basin_fraction": len(converged) / len(mine) if mine else None,
            "bounded_fraction": sum(r["outcome"] == "bounded" for r in mine) / len(mine) if mine else None,
            "fell_fraction": sum(r["outcome"] == "fell" for r in mine) / len(mine) if mine else None,
            "median_strides_to_converge": float(np.median([r["strides_to_converge"] for r in converged])) if converged else None,
            "median_ms_per_stride": float(np.median([r["ms_per_stride"] for r in mine])) if mine else None,
        }

    return {
        "gait": {"apex": gait.apex, "control": gait.control, "spectral_radius": gait.spectral_radius,
                 "rank_dr_du": rank},
        "feedback": {"kind": "deadbeat" if rank == APEX.size else "lqr", "K": K.tolist(),
                     "rows": list(CONTROL.names), "columns": list(APEX.names),
                     "closed_loop_multipliers": [[float(m.real), float(m.imag)] for m in multipliers],
                     "closed_loop_radius": float(np.max(np.abs(multipliers)))},
        "perturbation": dict(study.perturbation), "tolerance": study.tolerance, "strides": study.strides,
        "resolve_criterion": study.criterion,
        "controllers": {name: tally(name) for name in CONTROLLERS},
        **run_info(report),
    }
