"""Fixed points over many values: grid sweeps, body-angle scans and random samples.

Each point fixes the swept quantities at its values on top of the problem's own fixed
values; everything else (guess, bounds, objective) is the problem's. Within a worker, a
point is warm-started from IPOPT's answer at the latest point that converged (the tasks
come in snake order, so neighbours follow each other); where that answer is not
verified, from the converged points before it (:data:`WARM_STARTS`).
"""

from __future__ import annotations

import math
import random
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from baslip.engine.returnmap import PHASES
from baslip.errors import ProblemError
from baslip.files.rows import read_points
from baslip.gait.fixedpoint import FixedPointResult
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import PD, HipLaw
from baslip.problem.reader import Problem, check_point
from baslip.problem.study import Atlas, Optimal, RandomSample, Sweep
from baslip.status import Status
from baslip.studies.boundary import inside
from baslip.studies.common import run_info, status_counts, study_table
from baslip.studies.runner import LANES, Workers, run_tasks, split_lanes
from baslip.studies.sources import StudyInputError, source_points, traced_boundary
from baslip.viz.labels import problem_title

#: Converged points a lane keeps as warm starts: where the solve from the latest is not
#: verified (IPOPT's answer is no fixed point of the map), it is solved again from the
#: ones before. On the body-angle scan, where a borderline verification (eps 2.3e-10
#: against 1e-10) decides which neighbour the next point starts from, the retries verify
#: 38 of its 65 angles instead of 35.
WARM_STARTS = 3


def result_columns(law: HipLaw = PD) -> list[str]:
    """The columns of a solved point under hip law ``law``, after the swept values."""
    return [*APEX.names, *law.controls.names, *PHASES,
            "energy", "residual", "spectral_radius", "stable", "status", "reason", "time_s"]


#: The columns of a solved point under the default (PD) law.
RESULT_COLUMNS = result_columns(PD)


def key_column(name: str) -> str:
    """CSV column of a swept quantity (the apex/control columns hold the solved values)."""
    return f"sweep_{name}"


def sweep_lanes(study: Sweep, start: dict, lanes: int = LANES) -> list[list[dict]]:
    """Lanes of neighbouring points, one per worker.

    One quantity: two lanes walking outwards from the value nearest its starting value
    (``start[name]``), like a continuation in each direction. Two quantities: the grid in
    snake order, cut into ``lanes`` lanes.
    """
    if len(study.axes) == 1:
        (axis,) = study.axes
        values = list(axis.values)
        centre = min(range(len(values)), key=lambda i: abs(values[i] - start[axis.name]))
        up, down = values[centre:], values[:centre][::-1]
        return [[{key_column(axis.name): v} for v in lane] for lane in (up, down) if lane]
    return split_lanes(sweep_tasks(study), lanes)


def sweep_tasks(study: Sweep | Optimal | Atlas) -> list[dict]:
    """Grid points in snake order: consecutive points are neighbours."""
    if len(study.axes) == 1:
        (axis,) = study.axes
        return [{key_column(axis.name): v} for v in axis.values]
    outer, inner = study.axes
    tasks = []
    for i, a in enumerate(outer.values):
        values = inner.values if i % 2 == 0 else tuple(reversed(inner.values))
        tasks += [{key_column(outer.name): a, key_column(inner.name): b} for b in values]
    return tasks


def radius_grid(rows: list[dict], names: tuple[str, str]):
    """Axis values and a (len(a) x len(b)) array of spectral radii, NaN where not converged."""
    a_name, b_name = (key_column(n) for n in names)
    a_values = sorted({r[a_name] for r in rows})
    b_values = sorted({r[b_name] for r in rows})
    radius = np.full((len(a_values), len(b_values)), np.nan)
    for r in rows:
        if r["status"] == Status.CONVERGED and isinstance(r["spectral_radius"], float):
            radius[a_values.index(r[a_name]), b_values.index(r[b_name])] = r["spectral_radius"]
    return np.array(a_values), np.array(b_values), radius


def interpolated_radius(a, b, radius, x: float, y: float) -> float:
    """Bilinear interpolation of the radius grid; NaN outside it or next to a gap."""
    i, j = int(np.searchsorted(a, x)) - 1, int(np.searchsorted(b, y)) - 1
    i, j = min(max(i, 0), len(a) - 2), min(max(j, 0), len(b) - 2)
    if not (a[0] <= x <= a[-1] and b[0] <= y <= b[-1]):
        return math.nan
    s, t = (x - a[i]) / (a[i + 1] - a[i]), (y - b[j]) / (b[j + 1] - b[j])
    corners = radius[i : i + 2, j : j + 2]
    weights = np.array([[(1 - s) * (1 - t), (1 - s) * t], [s * (1 - t), s * t]])
    return float(np.sum(corners * weights))


def random_tasks(study: RandomSample, region_rows: list[dict], names: tuple[str, str], segments=None,
                 law: HipLaw = PD) -> list[dict]:
    """``count`` uniform draws inside the region's stable set, ordered along the first
    axis. Inside means an interpolated radius below 1 or, given the ``segments`` of a
    traced stability boundary, on the stable side of it as seen from the nearest stable
    grid point (:func:`baslip.studies.boundary.inside`).

    The fixed point at a given (ydot, z) is not unique. Without a boundary, each draw
    starts from, and is picked nearest to, the nearest stable fixed point of the region,
    to follow the stable family that defines the region. With one, each draw is solved
    as the grid's cells are (nearest the problem's guess, warm-started along its lane),
    which is the family the boundary was traced on."""
    a, b, radius = radius_grid(region_rows, names)
    stable = [r for r in region_rows if r["status"] == Status.CONVERGED and r["stable"] is True]
    spans = [np.ptp(a) or 1.0, np.ptp(b) or 1.0]

    def nearest(x, y):
        return min(stable, key=lambda r: ((r[names[0]] - x) / spans[0]) ** 2 + ((r[names[1]] - y) / spans[1]) ** 2)

    def accepted(x, y):
        if segments is None:
            return interpolated_radius(a, b, radius, x, y) < 1.0
        reference = nearest(x, y)
        return inside((x, y), (reference[names[0]], reference[names[1]]), segments)

    rng = random.Random(study.seed)
    draws: list[tuple[float, float]] = []
    for _ in range(1000 * study.count):
        if len(draws) == study.count or not stable:
            break
        x, y = rng.uniform(a[0], a[-1]), rng.uniform(b[0], b[-1])
        if accepted(x, y):
            draws.append((round(float(x), 12), round(float(y), 12)))
    draws.sort()
    tasks = []
    for x, y in draws:
        task: dict[str, Any] = {key_column(names[0]): x, key_column(names[1]): y}
        if segments is None:
            start = nearest(x, y)
            task["guess"] = {n: start[n] for n in APEX.names + law.controls.names if n not in names}
        tasks.append(task)
    return tasks


def result_row(task: dict, result: FixedPointResult) -> dict:
    """One CSV row: the task's swept values, then the solved point."""
    row = {k: v for k, v in task.items() if k.startswith("sweep_")}
    row.update(zip(APEX.names, result.X.tolist()))
    row.update(zip(result.law.controls.names, result.u.tolist()))
    row.update(result.durations or {})
    row.update(
        energy=result.energy,
        residual=result.residual,
        spectral_radius=result.spectral_radius,
        stable=result.stable,
        status=result.status,
        reason="" if result.converged else result.message,
        time_s=result.solver.time_s,
    )
    return row


def solve_worker(chunk: list[dict], problem: Problem, queue) -> None:
    """Worker process: build the solver once, solve each task not yet done, put its row
    (with the IPOPT point it hands on to the next task as ``state``) on the queue."""
    from baslip.gait.from_problem import fixed_point_spec, solver_for

    solver = solver_for(problem)
    base = fixed_point_spec(problem)
    warm: list[np.ndarray] = []  # the lane's latest converged IPOPT points, newest first
    for task in chunk:
        if task.get("done"):  # solved in an earlier run: hand on what it handed on then
            warm = handed_on(warm, task["state"])
            continue
        swept = {k[len("sweep_"):]: v for k, v in task.items() if k.startswith("sweep_")}
        spec = replace(base, fixed={**base.fixed, **swept}, guess={**base.guess, **task.get("guess", {})})
        # A task with its own guess starts from it; the others from their predecessors.
        result = solver.solve(spec, name=problem.name) if "guess" in task else solved_from(solver, spec, problem.name, warm)
        state = result.nlp_w.tolist() if result.converged and result.nlp_w is not None else None
        warm = handed_on(warm, state)
        queue.put({**result_row(task, result), "state": state})


def handed_on(warm: list[np.ndarray], state: list[float] | None) -> list[np.ndarray]:
    """The warm starts after a point that handed on ``state`` (None: it did not converge)."""
    return warm if state is None else [np.array(state), *warm][:WARM_STARTS]


def solved_from(solver, spec, name: str, warm: list[np.ndarray]) -> FixedPointResult:
    """The point solved from the latest warm start (from the guess if there is none); where
    IPOPT's answer is not verified, solved again from the ones before, the first verified
    kept (else the first answer, with the time of every try)."""
    first = solver.solve(spec, name=name, w0=warm[0] if warm else None)
    spent = first.solver.time_s
    for w0 in warm[1:] if first.status == Status.NOT_VERIFIED else ():
        again = solver.solve(spec, name=name, w0=w0)
        spent += again.solver.time_s
        if again.converged:
            return replace(again, solver=replace(again.solver, time_s=spent))
    return replace(first, solver=replace(first.solver, time_s=spent))


def run_sweep(problem: Problem, study: Sweep, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers) -> dict:
    """A grid sweep (or body-angle scan): its points, warm-started along each lane."""
    origin = {a.name: problem.start_value(a.name) for a in study.axes}
    names = [a.name for a in study.axes]
    summary = solve_points(problem, out_dir, sweep_lanes(study, origin, lanes), names, quiet, workers)
    from baslip.viz import figures  # drawn in this process only (see baslip.studies)

    figures.sweep_figures(read_points(out_dir / "points.csv"), names, out_dir, problem=problem_title(problem))
    return summary


def run_random(problem: Problem, study: RandomSample, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers) -> dict:
    """Random samples over the stable cells of a finished sweep (or inside a traced boundary)."""
    region_rows, names = source_points(sources, study.region, "study.region", problem.hip_law)
    curve_rows, segments = traced_boundary(sources, study, names)
    tasks = split_lanes(random_tasks(study, region_rows, names, segments, problem.hip_law), lanes)
    summary = solve_points(problem, out_dir, tasks, list(names), quiet, workers)
    summary["region"] = study.region
    if study.boundary is not None:
        summary["boundary"] = study.boundary
    from baslip.viz import figures  # drawn in this process only (see baslip.studies)

    figures.random_figure(read_points(out_dir / "points.csv"), region_rows, names, out_dir, curve_rows,
                          problem=problem_title(problem))
    return summary


def check_random(problem: Problem, study: RandomSample, sources: Path) -> None:
    """Refuse a sample whose region or boundary is not there, or whose draws the problem refuses."""
    rows, names = source_points(sources, study.region, "study.region", problem.hip_law)
    tasks = random_tasks(study, rows, names, traced_boundary(sources, study, names)[1], problem.hip_law)
    if not tasks:
        raise StudyInputError("study.region", f"{study.region!r} has no stable region to draw from (no stable "
                              "point, or none inside the boundary)")
    for task in tasks:
        values = {n: task[key_column(n)] for n in names}
        try:
            check_point(problem, values)
        except ProblemError as err:
            where = ", ".join(f"{n} = {v:g}" for n, v in values.items())
            raise StudyInputError("study.region", f"the draw at {where}: {err.message}") from None


def solve_points(problem: Problem, out_dir: Path, lanes: list, names: list[str], quiet: bool, workers: Workers) -> dict:
    """Solve each lane's points into ``points.csv``; the counts of what was solved."""
    keys = [key_column(n) for n in names]
    table = study_table(out_dir / "points.csv", keys + result_columns(problem.hip_law), keys, quiet)
    report = run_tasks(lanes, solve_worker, problem, table, problem.name, quiet=quiet, workers=workers)
    rows = read_points(out_dir / "points.csv")
    not_solved = [{**{k: r[k] for k in keys}, "status": r["status"], "reason": r["reason"]}
                  for r in rows if r["status"] != Status.CONVERGED]
    return {**status_counts(rows), **run_info(report), "swept": names, "not_solved": not_solved}
