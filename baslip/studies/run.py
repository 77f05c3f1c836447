"""Run a study of a problem file: its points, its summary and its figures.

Writes into the study's folder ``results/<name>/``:

* ``points.csv`` (sweep, random), ``basin.csv`` and ``trajectories.csv`` (basin) or
  ``strides.csv`` (adaptive): one row per finished task, appended as it finishes;
* ``result.json``: counts, wall time and the study's own numbers;
* PNG figures.

Rerunning a finished study does no new solves; an interrupted one resumes.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..control import CONTROL
from ..model import APEX
from ..output import json_text, write_files_atomically
from ..problem import Problem
from .. import plots
from .basin import BASIN_COLUMNS, basin_tasks, basin_worker, run_from, SIMULATION_TOLERANCES
from .runner import ResumableCsv, RunReport, run_tasks, split_lanes
from .schema import Adaptive, Basin, RandomSample, Sweep
from .sweep import RESULT_COLUMNS, key_column, random_tasks, read_points, solve_worker, sweep_lanes


class StudyInputError(ValueError):
    """A study refers to something that is not there (e.g. an unfinished source study)."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key = key


class StudyFailed(RuntimeError):
    """A study could not start: e.g. its starting fixed point did not converge."""


def check_study_inputs(problem: Problem, out_dir: Path) -> None:
    """Raise :class:`StudyInputError` if a study it depends on has not been run."""
    study = problem.study
    if isinstance(study, RandomSample):
        _source_points(out_dir, study.region, "study.region")
    elif isinstance(study, Basin):
        _source_points(out_dir, study.source, "study.source")


def run_study(problem: Problem, problem_path: Path, out_dir: Path, quiet: bool = False) -> dict:
    """Run (or resume) the study of ``problem``; return its summary (also in result.json)."""
    study = problem.study
    start = time.perf_counter()
    if isinstance(study, Sweep):
        origin = {a.name: problem.start_value(a.name) for a in study.axes}
        summary = _run_points(problem, problem_path, out_dir, sweep_lanes(study, origin), [a.name for a in study.axes], quiet)
        plots.sweep_figures(read_points(out_dir / "points.csv"), [a.name for a in study.axes], out_dir)
    elif isinstance(study, RandomSample):
        region_rows, names = _source_points(out_dir, study.region, "study.region")
        lanes = split_lanes(random_tasks(study, region_rows, names))
        summary = _run_points(problem, problem_path, out_dir, lanes, list(names), quiet)
        summary["region"] = study.region
        plots.random_figure(read_points(out_dir / "points.csv"), region_rows, names, out_dir)
    elif isinstance(study, Basin):
        summary = _run_basin(problem, study, out_dir, quiet)
    elif isinstance(study, Adaptive):
        summary = _run_adaptive(problem, study, out_dir, quiet)
    else:  # pragma: no cover - the schema admits no other kind
        raise TypeError(study)
    summary = {"name": problem.name, "kind": study.kind, **summary, "wall_time_s": time.perf_counter() - start}
    write_files_atomically({out_dir / "result.json": json_text(summary)})
    return summary


def _source_points(out_dir: Path, name: str, key: str) -> tuple[list[dict], tuple[str, str]]:
    path = out_dir.parent / name / "points.csv"
    if not path.exists():
        raise StudyInputError(key, f"{path} does not exist: run the study {name!r} first")
    rows = read_points(path)
    names = tuple(c[len("sweep_"):] for c in rows[0] if c.startswith("sweep_")) if rows else ()
    if len(names) != 2:
        raise StudyInputError(key, f"{path} is not a sweep over two quantities")
    return rows, names


def _counts(rows: list[dict]) -> dict:
    statuses = [r["status"] for r in rows]
    return {
        "points": len(rows),
        "solved": statuses.count("converged"),
        "not_verified": statuses.count("not_verified"),
        "failed": statuses.count("failed"),
        "stable": sum(1 for r in rows if r["status"] == "converged" and r["stable"] is True),
    }


def _run_points(problem, problem_path, out_dir, lanes, names, quiet) -> dict:
    keys = [key_column(n) for n in names]
    table = ResumableCsv(out_dir / "points.csv", keys + RESULT_COLUMNS, keys)
    report = run_tasks(lanes, solve_worker, str(problem_path), table, problem.name, quiet=quiet)
    rows = read_points(out_dir / "points.csv")
    return {**_counts(rows), **_run_info(report), "swept": names}


def _run_info(report: RunReport) -> dict:
    return {
        "tasks": report.total,
        "done_before_this_run": report.skipped,
        "done_in_this_run": report.ran,
        "complete": not report.interrupted and report.skipped + report.ran == report.total,
    }


def _point(row: dict) -> tuple[np.ndarray, np.ndarray]:
    return np.array([row[n] for n in APEX.names]), np.array([row[n] for n in CONTROL.names])


def _nearest(rows: list[dict], at: tuple[float, float]) -> dict | None:
    if not rows:
        return None
    return min(rows, key=lambda r: ((r["ydot"] - at[0]) / 0.1) ** 2 + ((r["z"] - at[1]) / 0.05) ** 2)


def _run_basin(problem: Problem, study: Basin, out_dir: Path, quiet: bool) -> dict:
    from ..returnmap import ReturnMap

    rows, names = _source_points(out_dir, study.source, "study.source")
    if set(names) != {"ydot", "z"}:
        raise StudyInputError("study.source", f"{study.source} does not sweep ydot and z")
    converged = [r for r in rows if r["status"] == "converged"]
    stable = [r for r in converged if r["stable"] is True]
    unstable = [r for r in converged if r["stable"] is False]
    points = [_point(r) for r in stable]
    table = ResumableCsv(out_dir / "basin.csv", ["point", key_column("ydot"), key_column("z"), *BASIN_COLUMNS[1:]],
                         ["point", key_column("ydot"), key_column("z")])
    context = (points, problem.params, study.strides, study.tolerance)
    lanes = split_lanes(basin_tasks(study, len(points)))
    report = run_tasks(lanes, basin_worker, context, table, problem.name, quiet=quiet)

    example_stable, example_unstable = _nearest(stable, study.stable_at), _nearest(unstable, study.unstable_at)
    rmap = ReturnMap(SIMULATION_TOLERANCES)
    trajectories = {}
    if example_unstable is not None:
        X_u, u_u = _point(example_unstable)
        trajectories["unstable_own_control"] = run_from(
            rmap, X_u, X_u, u_u, problem.params, study.strides, study.tolerance, stop_on_arrival=False
        )
        if example_stable is not None:
            X_s, u_s = _point(example_stable)
            trajectories["unstable_with_stable_control"] = run_from(rmap, X_u, X_s, u_s, problem.params, study.strides, study.tolerance)
    _write_trajectories(out_dir / "trajectories.csv", trajectories)

    basin_rows = read_points(out_dir / "basin.csv")
    example_index = stable.index(example_stable) if example_stable is not None else None
    plots.basin_figures(basin_rows, stable, unstable, example_index, example_unstable, trajectories, study, out_dir)
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
        **_run_info(report),
    }


def _write_trajectories(path: Path, trajectories: dict) -> None:
    lines = ["case,n," + ",".join(APEX.names)]
    for name, (_, _, _, apexes) in trajectories.items():
        lines += [f"{name},{n}," + ",".join(repr(float(v)) for v in X) for n, X in enumerate(apexes)]
    write_files_atomically({path: "\n".join(lines) + "\n"})


def _run_adaptive(problem: Problem, study: Adaptive, out_dir: Path, quiet: bool) -> dict:
    from ..api import shooting_options, solve_problem
    from ..fixedpoint import FixedPointSolver
    from .adaptive import STRIDE_COLUMNS, run_adaptive

    solver = FixedPointSolver(shooting_options(problem))
    result = solve_problem(problem, solver)
    if not result.converged:
        raise StudyFailed(f"the starting fixed point did not converge: {result.status} ({result.message})")
    table = ResumableCsv(out_dir / "strides.csv", STRIDE_COLUMNS, ["phase", "n"])
    summary = run_adaptive(solver, result.X, result.u, problem.params, study.strides, study.frozen_strides, table, quiet)
    plots.adaptive_figures(table.rows, out_dir)
    return {
        "start": {"apex": result.apex, "control": result.control, "spectral_radius": result.spectral_radius},
        **summary,
    }
