"""Convergence regions (thesis sec. 4.5, figs. 4.13-4.16), by simulation.

For a stable fixed point (X*, u*), an apex state converges to it if, run with u*, it comes
within ``tolerance`` of X* (relative, eq. 4.1) within ``strides`` strides. The region is
mapped over a grid of (ydot, z), the other apex coordinates at X*'s values, for every
stable point of a finished sweep; the union over them is thesis fig. 4.16.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.files.atomic import write_files_atomically
from baslip.files.rows import read_points
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HipLaw
from baslip.problem.reader import Problem
from baslip.problem.study import Basin
from baslip.status import Status
from baslip.studies.common import run_info, study_table
from baslip.studies.runner import Workers, run_tasks, split_lanes
from baslip.studies.sources import StudyInputError, source_points
from baslip.studies.sweep import key_column
from baslip.viz.labels import problem_title

#: Simulation accuracy: convergence is judged at 1e-4, far above the map's error.
SIMULATION_TOLERANCES = Tolerances(1e-8, 1e-8)
BASIN_COLUMNS = ["point", "outcome", "strides_run", "final_eps"]


def basin_tasks(study: Basin, n_points: int) -> list[dict]:
    """Every grid state for every stable point (snake order within a point)."""
    ydots, zs = study.grid[0].values, study.grid[1].values
    tasks = []
    for point in range(n_points):
        for i, ydot in enumerate(ydots):
            for z in zs if i % 2 == 0 else reversed(zs):
                tasks.append({"point": point, key_column("ydot"): ydot, key_column("z"): z})
    return tasks


def run_from(rmap: ReturnMap, X0, X_star, u_star, params: Params, strides: int, tolerance: float,
             stop_on_arrival: bool = True):
    """Run u* from X0: ('converged' | 'fell' | 'bounded' | 'stayed', strides run, final
    eps, apexes).

    With ``stop_on_arrival`` False the run goes on for all ``strides`` (or until a fall),
    for starting on X* itself to see whether round-off grows until it falls; it ends
    'stayed' if it is still within ``tolerance`` of X* then.
    """
    X_star = np.asarray(X_star, dtype=float)
    apexes = [np.asarray(X0, dtype=float)]
    for n in range(strides):
        stride = rmap.stride(apexes[-1], u_star, params)
        if not stride.ok:
            return "fell", n, float("nan"), np.array(apexes)
        assert stride.apex is not None
        apexes.append(stride.apex)
        eps = float(np.linalg.norm(stride.apex - X_star) / np.linalg.norm(X_star))
        if eps <= tolerance and stop_on_arrival:
            return "converged", n + 1, eps, np.array(apexes)
    arrived = "converged" if stop_on_arrival else "stayed"
    return (arrived if eps <= tolerance else "bounded"), strides, eps, np.array(apexes)


def run_many(rmap: ReturnMap, X0, X_star, u_star, params: Params, strides: int, tolerance: float):
    """:func:`run_from` for each row of ``X0`` (with the rows of ``X_star`` and ``u_star``),
    all runs in lockstep so that each stride of every run still going is one batched call.
    Yields (row, outcome, strides run, final eps) as each run ends."""
    X0, X_star, u_star = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (X0, X_star, u_star))
    current, alive = X0.copy(), np.arange(len(X0))
    eps = np.full(len(X0), np.nan)
    for n in range(strides):
        if not alive.size:
            return
        results = rmap.strides(current[alive], u_star[alive], params)
        still = []
        for i, stride in zip(alive, results):
            if not stride.ok:
                yield i, "fell", n, float("nan")
                continue
            current[i] = stride.apex
            eps[i] = np.linalg.norm(stride.apex - X_star[i]) / np.linalg.norm(X_star[i])
            if eps[i] <= tolerance:
                yield i, "converged", n + 1, float(eps[i])
            else:
                still.append(i)
        alive = np.array(still, dtype=int)
    for i in alive:
        yield i, "bounded", strides, float(eps[i])


def basin_worker(chunk: list[dict], context: tuple, queue) -> None:
    """Worker process: simulate the (point, ydot, z) tasks of its chunk in lockstep and put
    each row on the queue as its run ends."""
    points, params, strides, tolerance, law = context
    chunk = [task for task in chunk if not task.get("done")]  # runs are independent
    rmap = ReturnMap(SIMULATION_TOLERANCES, law=law)
    X_star = np.array([points[int(task["point"])][0] for task in chunk], dtype=float)
    u_star = np.array([points[int(task["point"])][1] for task in chunk], dtype=float)
    X0 = X_star.copy()
    X0[:, APEX.index("ydot")] = [task[key_column("ydot")] for task in chunk]
    X0[:, APEX.index("z")] = [task[key_column("z")] for task in chunk]
    for i, outcome, n, eps in run_many(rmap, X0, X_star, u_star, params, strides, tolerance):
        queue.put({**chunk[i], "outcome": outcome, "strides_run": n, "final_eps": eps})


def run_basin(problem: Problem, study: Basin, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers) -> dict:
    """Convergence regions: each stable point of the source sweep run from every grid state."""
    from baslip.engine.returnmap import ReturnMap

    law = problem.hip_law
    rows, names = source_points(sources, study.source, "study.source", law)
    if set(names) != {"ydot", "z"}:
        raise StudyInputError("study.source", f"{study.source} does not sweep ydot and z")
    converged = [r for r in rows if r["status"] == Status.CONVERGED]
    stable = [r for r in converged if r["stable"] is True]
    unstable = [r for r in converged if r["stable"] is False]
    points = [_point(r, law) for r in stable]
    table = study_table(out_dir / "basin.csv", ["point", key_column("ydot"), key_column("z"), *BASIN_COLUMNS[1:]],
                   ["point", key_column("ydot"), key_column("z")], quiet)
    context = (points, problem.params, study.strides, study.tolerance, law)
    report = run_tasks(split_lanes(basin_tasks(study, len(points)), lanes), basin_worker, context, table, problem.name,
                       quiet=quiet, workers=workers)

    example_stable, example_unstable = _nearest(stable, study.stable_at), _nearest(unstable, study.unstable_at)
    rmap = ReturnMap(SIMULATION_TOLERANCES, law=law)
    trajectories = {}
    if example_unstable is not None:
        X_u, u_u = _point(example_unstable, law)
        trajectories["unstable_own_control"] = run_from(
            rmap, X_u, X_u, u_u, problem.params, study.strides, study.tolerance, stop_on_arrival=False
        )
        if example_stable is not None:
            X_s, u_s = _point(example_stable, law)
            trajectories["unstable_with_stable_control"] = run_from(rmap, X_u, X_s, u_s, problem.params, study.strides, study.tolerance)
    _write_trajectories(out_dir / "trajectories.csv", trajectories)

    basin_rows = read_points(out_dir / "basin.csv")
    example_index = stable.index(example_stable) if example_stable is not None else None
    grid = (study.grid[0].values, study.grid[1].values)
    from baslip.viz import figures  # drawn in this process only (see baslip.studies)

    figures.basin_figures(basin_rows, stable, unstable, example_index, example_unstable, trajectories, grid, out_dir,
                          problem=problem_title(problem))
    grid_size = len(study.grid[0].values) * len(study.grid[1].values)
    union = {(r[key_column("ydot")], r[key_column("z")]) for r in basin_rows if r["outcome"] == "converged"}
    example_cells = sum(1 for r in basin_rows if r["outcome"] == "converged" and r["point"] == example_index)
    return {
        "source": study.source,
        "stable_points": len(stable),
        "grid_states": grid_size,
        "simulations": len(basin_rows),
        "example_stable_point": None if example_stable is None else {"ydot": example_stable["ydot"], "z": example_stable["z"]},
        "example_unstable_point": None if example_unstable is None else {"ydot": example_unstable["ydot"], "z": example_unstable["z"]},
        "example_region_states": example_cells,
        "union_region_states": len(union),
        "trajectories": {name: {"outcome": t[0], "strides": t[1]} for name, t in trajectories.items()},
        **run_info(report),
    }


def check_basin(problem: Problem, study: Basin, sources: Path) -> None:
    """Refuse a basin study whose source sweep is not there, finished and baslip's."""
    source_points(sources, study.source, "study.source", problem.hip_law)


def _write_trajectories(path: Path, trajectories: dict) -> None:
    lines = ["case,n," + ",".join(APEX.names)]
    for name, (_, _, _, apexes) in trajectories.items():
        lines += [f"{name},{n}," + ",".join(repr(float(v)) for v in X) for n, X in enumerate(apexes)]
    write_files_atomically({path: "\n".join(lines) + "\n"})


def _point(row: dict, law: HipLaw) -> tuple[np.ndarray, np.ndarray]:
    """The gait (X, u) of a source row under ``law``."""
    return np.array([row[n] for n in APEX.names]), np.array([row[n] for n in law.controls.names])


def _nearest(rows: list[dict], at: tuple[float, float]) -> dict | None:
    if not rows:
        return None
    return min(rows, key=lambda r: ((r["ydot"] - at[0]) / 0.1) ** 2 + ((r["z"] - at[1]) / 0.05) ** 2)
