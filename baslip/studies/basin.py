"""Convergence regions (thesis sec. 4.5, figs. 4.13-4.16), by simulation.

For a stable fixed point (X*, u*), an apex state converges to it if, run with u*, it comes
within ``tolerance`` of X* (relative, eq. 4.1) within ``strides`` strides. The region is
mapped over a grid of (ydot, z), the other apex coordinates at X*'s values, for every
stable point of a finished sweep; the union over them is thesis fig. 4.16.
"""

from __future__ import annotations

import numpy as np

from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.model.dynamics import APEX, Params
from baslip.problem.study import Basin
from baslip.studies.sweep import key_column

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
    points, params, strides, tolerance = context
    chunk = [task for task in chunk if not task.get("done")]  # runs are independent
    try:
        rmap = ReturnMap(SIMULATION_TOLERANCES)
        X_star = np.array([points[int(task["point"])][0] for task in chunk], dtype=float)
        u_star = np.array([points[int(task["point"])][1] for task in chunk], dtype=float)
        X0 = X_star.copy()
        X0[:, APEX.index("ydot")] = [task[key_column("ydot")] for task in chunk]
        X0[:, APEX.index("z")] = [task[key_column("z")] for task in chunk]
        for i, outcome, n, eps in run_many(rmap, X0, X_star, u_star, params, strides, tolerance):
            queue.put({**chunk[i], "outcome": outcome, "strides_run": n, "final_eps": eps})
    finally:
        queue.put(None)
