"""The ``optimal`` study: the most stable gait at every point of a grid.

Each task is one start at one grid point: the hip law's drawn controls (the gains Kp and
Kd under PD, the pivot r_vpp under VPP) drawn over their whole bounds (seeded by the
study's seed, the grid point and the start number, so a task draws the same values in
any lane and on any resume), the fixed point solved with them held, the
descent to the least spectral radius nearby (:mod:`baslip.analysis.descent`), or with
``method: schur_nlp`` the stability NLP from there (:mod:`baslip.analysis.stablenlp`),
and the independent verification of where it ended. Each row also gives the trunk's angle range over the stride,
and whether the gait is upright at the apex (|theta_h - 90 deg| <= 30 deg) and upright
throughout (within 45 deg of vertical at every sampled instant of the stride).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from baslip.diagnostics import logger
from baslip.files.rows import read_points
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import PD, HipLaw
from baslip.model.quantities import quantity_text
from baslip.problem.reader import Problem
from baslip.problem.study import Atlas, Optimal
from baslip.status import Status
from baslip.studies.common import run_info, status_counts, study_table
from baslip.studies.runner import Workers, run_tasks, split_lanes
from baslip.studies.sweep import key_column, result_columns, result_row, sweep_tasks
from baslip.viz.labels import problem_title

#: Upright at the apex: |theta_h - 90 deg| within this; upright throughout: the trunk
#: within UPRIGHT_THROUGHOUT of vertical at every instant of the stride [rad].
UPRIGHT_AT_APEX = math.radians(30)
UPRIGHT_THROUGHOUT = math.radians(45)

_log = logger(__name__)



def optimal_columns(law: HipLaw = PD) -> list[str]:
    """The columns of one start under hip law ``law``, after the grid point's: its gait,
    the controls drawn for its start (``drawn_Kp``, ``drawn_Kd`` under PD, ``drawn_r_vpp``
    under VPP), how its descent went, and the trunk's range."""
    return ["start", *result_columns(law), *(f"drawn_{n}" for n in law.drawn), "start_status", "start_radius",
            "descent_steps", "descent_stop", "trunk_min_deg", "trunk_max_deg", "upright_apex", "upright_throughout"]


#: The columns of one start under the default (PD) law.
OPTIMAL_COLUMNS = optimal_columns(PD)


def optimal_tasks(study: Optimal) -> list[dict]:
    """Every (grid point, start), grid points in snake order, starts within each."""
    return [{**point, "start": start} for point in sweep_tasks(study) for start in range(study.starts)]


def task_rng(study: Optimal | Atlas, task: dict) -> np.random.Generator:
    """The task's own random stream: from the seed, its grid values and its start."""
    values = [int(round(v * 1e9)) % 2**32 for k, v in sorted(task.items()) if k.startswith("sweep_")]
    return np.random.default_rng([study.seed, task["start"], *values])


def optimal_row(task: dict, gait, rmap, params) -> dict:
    """The CSV row of one start (see :func:`optimal_columns`)."""
    from baslip.engine.trajectory import trunk_angle_range

    final = gait.end if gait.end is not None else gait.start
    row = {**result_row(task, final), "start": task["start"]}
    row.update({f"drawn_{n}": gait.held.get(n) for n in final.law.drawn})
    row.update(
        start_status=gait.start.status,
        start_radius=gait.start.spectral_radius,
        descent_steps=_steps(gait),
        descent_stop=gait.note,
    )
    if final.converged:
        low, high = trunk_angle_range(rmap, final.X, final.u, params)
        upright = math.pi / 2
        row.update(
            trunk_min_deg=math.degrees(low), trunk_max_deg=math.degrees(high),
            upright_apex=abs(final.X[1] - upright) <= UPRIGHT_AT_APEX,
            upright_throughout=max(abs(low - upright), abs(high - upright)) <= UPRIGHT_THROUGHOUT,
        )
    return row


def _steps(gait) -> int | None:
    """Steps from the start to the end: the descent's accepted points, or the stability
    NLP's IPOPT iterations (None where neither ran)."""
    if gait.descent is not None:
        return len(gait.descent.steps) - 1
    if gait.end is not None and gait.end is not gait.start:
        return gait.end.solver.iterations
    return None


def optimal_worker(chunk: list[dict], problem: Problem, queue) -> None:
    """Worker process: for each task not yet done, draw its start, solve, descend,
    verify, and put its row on the queue."""
    from baslip.analysis.descent import StabilityDescent, optimise_from
    from baslip.analysis.stablenlp import stable_nlp_from
    from baslip.gait.draws import random_start
    from baslip.gait.from_problem import fixed_point_spec, solver_for

    study = problem.study
    assert isinstance(study, Optimal)
    solver = solver_for(problem)
    descent = StabilityDescent(solver.residual_map, max_iterations=study.iterations)
    base = fixed_point_spec(problem)
    for task in chunk:
        if task.get("done"):
            continue
        swept = {k[len("sweep_"):]: v for k, v in task.items() if k.startswith("sweep_")}
        spec = replace(base, fixed={**base.fixed, **swept})
        # news for the parent's progress line while this start runs (minutes, at times)
        where = ", ".join(quantity_text(n, v, 6) for n, v in swept.items())
        _log.info(f"start {task['start'] + 1} of {study.starts} at {where}")
        started = time.perf_counter()
        if study.method == "schur_nlp":
            gait = stable_nlp_from(solver, spec, task_rng(study, task), problem.name)
        else:
            gait = optimise_from(solver, descent, spec, random_start(spec, task_rng(study, task)), problem.name)
        row = optimal_row(task, gait, solver.residual_map, problem.params)
        queue.put({**row, "time_s": time.perf_counter() - started})


def best_gait_motions(best: list[dict], names: list[str], params, count: int = 6,
                      note=lambda row: "", law: HipLaw = PD) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(label, t [s], theta_h [rad]) over one stride of the ``count`` most stable of the
    ``best`` rows (gaits under hip law ``law``), simulated at rtol = atol = 1e-12: the
    trunk motion figure's lines. ``note(row)`` is added to a line's label."""
    from baslip.engine.returnmap import ReturnMap, Tolerances
    from baslip.engine.trajectory import stride_trajectory

    rmap = ReturnMap(Tolerances(1e-12, 1e-12), law=law)
    motions = []
    for row in sorted(best, key=lambda r: r["spectral_radius"])[:count]:
        X, u = np.array([row[n] for n in APEX.names]), np.array([row[n] for n in law.controls.names])
        motion = stride_trajectory(rmap, X, u, params, strides=1, samples=100)
        where = ", ".join(quantity_text(n, row[key_column(n)], 6) for n in names)
        motions.append((f"{where}{note(row)}: radius {row['spectral_radius']:.3g}", motion.t, motion.theta_h))
    return motions


def best_rows(rows: list[dict], names: list[str], where=lambda row: True) -> list[dict]:
    """Per grid point, the verified row of least spectral radius among those ``where``
    accepts (grid points with none are left out)."""
    keys = [key_column(n) for n in names]
    best: dict[tuple, dict] = {}
    for row in rows:
        if row["status"] != Status.CONVERGED or not isinstance(row["spectral_radius"], float) or not where(row):
            continue
        cell = tuple(row[k] for k in keys)
        if cell not in best or row["spectral_radius"] < best[cell]["spectral_radius"]:
            best[cell] = row
    return [best[cell] for cell in sorted(best)]


def run_optimal(problem: Problem, study: Optimal, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers) -> dict:
    """The most stable gait at every grid point, from many random starts each."""
    names = [a.name for a in study.axes]
    keys = [key_column(n) for n in names]
    law = problem.hip_law
    table = study_table(out_dir / "points.csv", keys + optimal_columns(law), keys + ["start"], quiet)
    report = run_tasks(split_lanes(optimal_tasks(study), lanes), optimal_worker, problem, table,
                       problem.name, quiet=quiet, workers=workers)
    rows = read_points(out_dir / "points.csv")
    best = best_rows(rows, names)
    from baslip.viz import figures  # drawn in this process only (see baslip.studies)

    figures.sweep_figures(best, names, out_dir, problem=problem_title(problem))
    figures.trunk_motion_figure(best_gait_motions(best, names, problem.params, law=law), out_dir, problem=problem_title(problem))

    def least(where) -> dict | None:
        candidates = best_rows(rows, names, where)
        if not candidates:
            return None
        row = min(candidates, key=lambda r: r["spectral_radius"])
        return {**{n: row[key_column(n)] for n in names}, "start": int(row["start"]),
                "spectral_radius": row["spectral_radius"], "stable": row["stable"],
                "apex": {n: row[n] for n in APEX.names}, "control": {n: row[n] for n in law.controls.names},
                "trunk_range_deg": [row["trunk_min_deg"], row["trunk_max_deg"]]}

    not_solved = [{**{k: r[k] for k in keys}, "start": r["start"], "status": r["status"], "reason": r["reason"]}
                  for r in rows if r["status"] != Status.CONVERGED]
    return {
        **status_counts(rows), **run_info(report), "swept": names, "starts": study.starts, "method": study.method,
        "descended": sum(1 for r in rows if r["descent_steps"] != "" and r["status"] == Status.CONVERGED),
        "least_per_point": [{**{n: r[key_column(n)] for n in names}, "spectral_radius": r["spectral_radius"],
                             "stable": r["stable"], "trunk_range_deg": [r["trunk_min_deg"], r["trunk_max_deg"]]}
                            for r in best],
        "least": least(lambda r: True),
        "least_upright_at_apex": least(lambda r: r["upright_apex"] is True),
        "least_upright_throughout": least(lambda r: r["upright_throughout"] is True),
        "not_solved": not_solved,
    }
