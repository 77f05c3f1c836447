"""Run a study of a problem file: its points, its summary and its figures.

Writes into the study's folder ``results/<name>/``:

* ``points.csv`` (sweep, random), ``basin.csv`` and ``trajectories.csv`` (basin) or
  ``strides.csv`` (adaptive): one row per finished task, appended as it finishes;
* ``result.json``: counts, wall time and the study's own numbers;
* PNG figures.

Rerunning a finished study does no new solves; an interrupted one resumes, giving the
same answers as an uninterrupted run. The folder is held by one run at a time
(:mod:`baslip.files.lock`). ``result.json`` is written first, with ``complete: false`` and the
``provenance`` of the run; a rerun whose problem differs from the one recorded there is
refused (:class:`StaleFolder`) unless it is asked to start afresh.
"""

from __future__ import annotations

import contextlib
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np

from baslip.errors import InputError, RunError
from baslip.files.atomic import json_text, write_files_atomically
from baslip.files.lock import busy, hold
from baslip.files.provenance import changed_entries, provenance
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import CONTROL
from baslip.problem.reader import Problem, ProblemError, check_point
from baslip.problem.study import Adaptive, Basin, Controllers, Optimal, RandomSample, Sweep
from baslip.status import Status
from baslip.studies.basin import BASIN_COLUMNS, SIMULATION_TOLERANCES, basin_tasks, basin_worker, run_from
from baslip.studies.boundary import boundary_segments, read_curves
from baslip.studies.controllers import (
    CONTROLLER_COLUMNS,
    CONTROLLERS,
    controller_tasks,
    controllers_worker,
    lqr_weights,
)
from baslip.studies.optimal import OPTIMAL_COLUMNS, best_gait_motions, best_rows, optimal_tasks, optimal_worker
from baslip.studies.runner import LANES, ResumableCsv, RunReport, Workers, run_tasks, split_lanes
from baslip.studies.sweep import RESULT_COLUMNS, key_column, random_tasks, read_points, solve_worker, sweep_lanes
from baslip.viz import figures as plots

#: Files a study writes besides its figures; ``--fresh`` removes them before starting.
DATA_FILES = ("points.csv", "basin.csv", "trajectories.csv", "strides.csv")


class StudyInputError(InputError):
    """A study refers to something that is not there (e.g. an unfinished source study)."""


class StudyFailed(RunError):
    """A study could not start: e.g. its starting fixed point did not converge."""


class StaleFolder(InputError):
    """The output folder holds results of another problem (or of unknown origin)."""


def check_study_inputs(problem: Problem, sources: Path) -> None:
    """Raise :class:`StudyInputError` if a study it depends on (in the folder ``sources``)
    has not been run (to the end), is being run, cannot be read, or gives points this
    problem would refuse."""
    study = problem.study
    if isinstance(study, RandomSample):
        rows, names = _source_points(sources, study.region, "study.region")
        for task in random_tasks(study, rows, names, _boundary(sources, study, names)[1]):
            values = {n: task[key_column(n)] for n in names}
            try:
                check_point(problem, values)
            except ProblemError as err:
                where = ", ".join(f"{n} = {v:g}" for n, v in values.items())
                raise StudyInputError("study.region", f"the draw at {where}: {err.message}") from None
    elif isinstance(study, Basin):
        _source_points(sources, study.source, "study.source")


def run_study(problem: Problem, out_dir: Path, quiet: bool = False, fresh: bool = False,
              jobs: int | None = None, scheduler: str | None = None, lanes: int | None = None,
              sources: Path | None = None) -> dict:
    """Run (or resume) the study of ``problem``; return its summary (also in result.json).

    The runs a study reads (its source, region or boundary) are looked up in ``sources``,
    by default the folder that holds ``out_dir``.

    ``fresh`` discards what the folder holds first; without it, results of another
    problem there raise :class:`StaleFolder`. ``lanes`` splits a new run's tasks into
    that many warm-started lanes (default :data:`~baslip.studies.runner.LANES`); a resumed
    run keeps its recorded count, and asking for another raises :class:`StaleFolder`.
    Raises :class:`baslip.files.lock.FolderBusy` if another process is writing into ``out_dir``.
    """
    with hold(out_dir):
        record = _claim(problem, out_dir, fresh, lanes)
        start = time.perf_counter()
        summary = _run(problem, out_dir, sources or out_dir.parent, quiet, record["lanes"], Workers(jobs, scheduler))
        summary = {"name": problem.name, "kind": problem.study.kind, **summary,
                   "wall_time_s": time.perf_counter() - start, "provenance": record}
        write_files_atomically({out_dir / "result.json": json_text(summary)})
    return summary


def _run(problem: Problem, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers) -> dict:
    study = problem.study
    if isinstance(study, Sweep):
        origin = {a.name: problem.start_value(a.name) for a in study.axes}
        names = [a.name for a in study.axes]
        summary = _run_points(problem, out_dir, sweep_lanes(study, origin, lanes), names, quiet, workers)
        plots.sweep_figures(read_points(out_dir / "points.csv"), names, out_dir)
    elif isinstance(study, RandomSample):
        region_rows, names = _source_points(sources, study.region, "study.region")
        curve_rows, segments = _boundary(sources, study, names)
        tasks = split_lanes(random_tasks(study, region_rows, names, segments), lanes)
        summary = _run_points(problem, out_dir, tasks, list(names), quiet, workers)
        summary["region"] = study.region
        if study.boundary is not None:
            summary["boundary"] = study.boundary
        plots.random_figure(read_points(out_dir / "points.csv"), region_rows, names, out_dir, curve_rows)
    elif isinstance(study, Basin):
        summary = _run_basin(problem, study, out_dir, sources, quiet, lanes, workers)
    elif isinstance(study, Adaptive):
        summary = _run_adaptive(problem, study, out_dir, quiet)
    elif isinstance(study, Optimal):
        summary = _run_optimal(problem, study, out_dir, quiet, lanes, workers)
    elif isinstance(study, Controllers):
        summary = _run_controllers(problem, study, out_dir, quiet, lanes, workers)
    else:  # pragma: no cover - the schema admits no other kind
        raise TypeError(study)
    return summary


def _claim(problem: Problem, out_dir: Path, fresh: bool, lanes: int | None = None) -> dict:
    """Check that ``out_dir`` holds nothing but earlier results of this same problem, run
    in the same number of lanes (or clear it if ``fresh``); record this run's provenance
    in result.json; return it."""
    record = {**provenance(problem), "lanes": lanes or LANES}
    data = [out_dir / name for name in DATA_FILES if (out_dir / name).exists()]
    old = _recorded_provenance(out_dir)
    if fresh:
        for path in data + [out_dir / "result.json"]:
            path.unlink(missing_ok=True)
            path.with_name(f".{path.name}.states").unlink(missing_ok=True)
    elif data:
        if old is None:
            raise StaleFolder("", f"{out_dir} holds results with no provenance record (from an older baslip?); "
                              "rerun with --fresh to discard them, or choose another --out")
        if old.get("problem_hash") != record["problem_hash"]:
            ignored = ("name", "solver.print_level")
            changed = [n for n in changed_entries(old.get("problem", {}), record["problem"]) if n not in ignored]
            raise StaleFolder("", f"{out_dir} holds results of a different problem (changed: {', '.join(changed[:4]) or 'unknown'}); "
                              "rerun with --fresh to discard them, or choose another --out")
        if lanes is not None and lanes != old.get("lanes", LANES):
            raise StaleFolder("", f"{out_dir} holds a run in {old.get('lanes', LANES)} lanes, not {lanes}; rerun with "
                              "--fresh to start again in the new count, or leave out --lanes to resume")
        record["lanes"] = old.get("lanes", LANES)
        if old.get("versions") != record["versions"] or old.get("code") != record["code"]:
            record["earlier_runs"] = [{"versions": old.get("versions"), "code": old.get("code")}, *old.get("earlier_runs", [])]
    write_files_atomically({out_dir / "result.json": json_text(
        {"name": problem.name, "kind": problem.study.kind, "complete": False, "provenance": record})})
    return record


def _recorded_provenance(out_dir: Path) -> dict | None:
    try:
        record = json.loads((out_dir / "result.json").read_text())
    except (OSError, ValueError):
        return None
    return record.get("provenance") if isinstance(record, dict) else None


def _source_points(sources: Path, name: str, key: str) -> tuple[list[dict], tuple[str, str]]:
    folder = sources / name
    path = folder / "points.csv"
    if not path.exists():
        raise StudyInputError(key, f"{path} does not exist: run the study {name!r} first")
    holder = busy(folder)
    if holder is not None:
        raise StudyInputError(key, f"the study {name!r} is still being run by {holder}; wait for it to finish")
    record = {}
    with contextlib.suppress(OSError, ValueError):
        record = json.loads((folder / "result.json").read_text())
    if not isinstance(record, dict) or record.get("complete") is not True:
        raise StudyInputError(key, f"the study {name!r} has not run to the end (its result.json does not say complete); rerun it first")
    try:
        rows = read_points(path)
        names = tuple(c[len("sweep_"):] for c in rows[0] if c.startswith("sweep_")) if rows else ()
        for row in rows:
            for column in (*APEX.names, *CONTROL.names, "spectral_radius", "stable", "status"):
                if column not in row:
                    raise ValueError(f"it has no column {column}")
                if column in ("stable", "status"):
                    continue
                if row[column] != "" and not isinstance(row[column], float):
                    raise ValueError(f"its column {column} holds {str(row[column])[:20]!r}")
    except UnicodeDecodeError:
        raise StudyInputError(key, f"{path} is not a points.csv written by baslip (it is not UTF-8 text)") from None
    except csv.Error:
        raise StudyInputError(key, f"{path} is not a points.csv written by baslip (it is not CSV)") from None
    except ValueError as err:
        raise StudyInputError(key, f"{path} is not a points.csv written by baslip ({err})") from None
    if len(names) != 2:
        raise StudyInputError(key, f"{path} is not a sweep over two quantities")
    return rows, names


def _boundary(sources: Path, study: RandomSample, names: tuple[str, str]):
    """(curve rows, boundary segments) of the study's traced boundary, or (None, None)."""
    if study.boundary is None:
        return None, None
    folder = sources / study.boundary
    path = folder / "curve.csv"
    if not path.exists():
        raise StudyInputError("study.boundary", f"{path} does not exist: run the continuation {study.boundary!r} first")
    holder = busy(folder)
    if holder is not None:
        raise StudyInputError("study.boundary", f"{study.boundary!r} is still being run by {holder}; wait for it to finish")
    try:
        rows = read_curves(path)
        missing = [n for n in (*names, "curve", "stability_boundary") if rows and n not in rows[0]]
        if missing:
            raise ValueError(f"it has no column {missing[0]}")
    except UnicodeDecodeError:
        raise StudyInputError("study.boundary", f"{path} is not a curve.csv written by baslip (it is not UTF-8 text)") from None
    except (csv.Error, ValueError, TypeError) as err:
        raise StudyInputError("study.boundary", f"{path} is not a curve.csv written by baslip ({err})") from None
    segments = boundary_segments(rows, names)
    if not segments:
        raise StudyInputError("study.boundary", f"{path} holds no curve that bounds stable gaits in ({', '.join(names)})")
    return rows, segments


def _counts(rows: list[dict]) -> dict:
    statuses = [r["status"] for r in rows]
    return {
        "points": len(rows),
        "solved": statuses.count(Status.CONVERGED),
        "not_verified": statuses.count(Status.NOT_VERIFIED),
        "failed": statuses.count(Status.FAILED),
        "stable": sum(1 for r in rows if r["status"] == Status.CONVERGED and r["stable"] is True),
    }


def _run_points(problem, out_dir, lanes, names, quiet, workers=Workers()) -> dict:
    keys = [key_column(n) for n in names]
    table = _table(out_dir / "points.csv", keys + RESULT_COLUMNS, keys, quiet)
    report = run_tasks(lanes, solve_worker, problem, table, problem.name, quiet=quiet, workers=workers)
    rows = read_points(out_dir / "points.csv")
    not_solved = [{**{k: r[k] for k in keys}, "status": r["status"], "reason": r["reason"]}
                  for r in rows if r["status"] != Status.CONVERGED]
    return {**_counts(rows), **_run_info(report), "swept": names, "not_solved": not_solved}


def _table(path: Path, columns, keys, quiet: bool) -> ResumableCsv:
    """The study's resumable CSV, saying what was repaired in it."""
    table = ResumableCsv(path, columns, keys)
    if not quiet:
        for note in table.notes:
            print(f"note: {note}", file=sys.stderr)
    return table


def _run_info(report: RunReport) -> dict:
    return {
        "tasks": report.total,
        "done_before_this_run": report.skipped,
        "done_in_this_run": report.ran,
        "complete": report.complete,
    }


def outcome(summary: dict) -> str | None:
    """Why a study's run is not a success (None if it is): it stopped short, or it
    solved nothing at all."""
    if not summary.get("complete", True):
        return f"stopped short: {summary['done_before_this_run'] + summary['done_in_this_run']} of {summary['tasks']} tasks done; rerun to resume"
    if summary["kind"] in ("sweep", "random", "optimal") and summary["solved"] == 0:
        return f"no fixed point was found at any of the {summary['points']} points"
    if summary["kind"] == "basin" and summary["stable_points"] == 0:
        return f"the source study {summary['source']!r} has no stable fixed point to simulate"
    if summary["kind"] == "controllers" and summary["done_before_this_run"] + summary["done_in_this_run"] == 0:
        return "no controller run was made"
    if summary["kind"] == "adaptive" and summary["adaptive_strides"] == 0:
        return f"no adaptive stride was taken: {summary['adaptive_failure']}"
    return None


def _point(row: dict) -> tuple[np.ndarray, np.ndarray]:
    return np.array([row[n] for n in APEX.names]), np.array([row[n] for n in CONTROL.names])


def _nearest(rows: list[dict], at: tuple[float, float]) -> dict | None:
    if not rows:
        return None
    return min(rows, key=lambda r: ((r["ydot"] - at[0]) / 0.1) ** 2 + ((r["z"] - at[1]) / 0.05) ** 2)


def _run_basin(problem: Problem, study: Basin, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers = Workers()) -> dict:
    from baslip.engine.returnmap import ReturnMap

    rows, names = _source_points(sources, study.source, "study.source")
    if set(names) != {"ydot", "z"}:
        raise StudyInputError("study.source", f"{study.source} does not sweep ydot and z")
    converged = [r for r in rows if r["status"] == Status.CONVERGED]
    stable = [r for r in converged if r["stable"] is True]
    unstable = [r for r in converged if r["stable"] is False]
    points = [_point(r) for r in stable]
    table = _table(out_dir / "basin.csv", ["point", key_column("ydot"), key_column("z"), *BASIN_COLUMNS[1:]],
                   ["point", key_column("ydot"), key_column("z")], quiet)
    context = (points, problem.params, study.strides, study.tolerance)
    report = run_tasks(split_lanes(basin_tasks(study, len(points)), lanes), basin_worker, context, table, problem.name,
                       quiet=quiet, workers=workers)

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
    grid = (study.grid[0].values, study.grid[1].values)
    plots.basin_figures(basin_rows, stable, unstable, example_index, example_unstable, trajectories, grid, out_dir)
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


def _run_optimal(problem: Problem, study: Optimal, out_dir: Path, quiet: bool, lanes: int,
                 workers: Workers = Workers()) -> dict:
    names = [a.name for a in study.axes]
    keys = [key_column(n) for n in names]
    table = _table(out_dir / "points.csv", keys + OPTIMAL_COLUMNS, keys + ["start"], quiet)
    report = run_tasks(split_lanes(optimal_tasks(study), lanes), optimal_worker, problem, table,
                       problem.name, quiet=quiet, workers=workers)
    rows = read_points(out_dir / "points.csv")
    best = best_rows(rows, names)
    plots.sweep_figures(best, names, out_dir)
    plots.trunk_motion_figure(best_gait_motions(best, names, problem.params), out_dir)

    def least(where) -> dict | None:
        candidates = best_rows(rows, names, where)
        if not candidates:
            return None
        row = min(candidates, key=lambda r: r["spectral_radius"])
        return {**{n: row[key_column(n)] for n in names}, "start": int(row["start"]),
                "spectral_radius": row["spectral_radius"], "stable": row["stable"],
                "apex": {n: row[n] for n in APEX.names}, "control": {n: row[n] for n in CONTROL.names},
                "trunk_range_deg": [row["trunk_min_deg"], row["trunk_max_deg"]]}

    not_solved = [{**{k: r[k] for k in keys}, "start": r["start"], "status": r["status"], "reason": r["reason"]}
                  for r in rows if r["status"] != Status.CONVERGED]
    return {
        **_counts(rows), **_run_info(report), "swept": names, "starts": study.starts,
        "descended": sum(1 for r in rows if r["descent_steps"] != "" and r["status"] == Status.CONVERGED),
        "least_per_point": [{**{n: r[key_column(n)] for n in names}, "spectral_radius": r["spectral_radius"],
                             "stable": r["stable"], "trunk_range_deg": [r["trunk_min_deg"], r["trunk_max_deg"]]}
                            for r in best],
        "least": least(lambda r: True),
        "least_upright_at_apex": least(lambda r: r["upright_apex"] is True),
        "least_upright_throughout": least(lambda r: r["upright_throughout"] is True),
        "not_solved": not_solved,
    }


def _run_controllers(problem: Problem, study: Controllers, out_dir: Path, quiet: bool, lanes: int,
                     workers: Workers = Workers()) -> dict:
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
    table = _table(out_dir / "controllers.csv", CONTROLLER_COLUMNS, ["controller", "sample"], quiet)
    report = run_tasks(split_lanes(controller_tasks(study), lanes), controllers_worker, context, table,
                       problem.name, quiet=quiet, workers=workers)
    rows = read_points(out_dir / "controllers.csv")
    plots.controllers_figure(rows, dict(study.perturbation), out_dir)
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
        **_run_info(report),
    }


def _run_adaptive(problem: Problem, study: Adaptive, out_dir: Path, quiet: bool) -> dict:
    from baslip.analysis.feedback import ResolvedControl
    from baslip.gait.from_problem import fixed_point_spec, solve_start, solver_for
    from baslip.studies.adaptive import STRIDE_COLUMNS, largest_recovered, run_adaptive

    solver = solver_for(problem)
    result = solve_start(problem, solver)
    if not result.converged:
        raise StudyFailed(f"the starting fixed point did not converge: {result.status} ({result.message})")
    spec = fixed_point_spec(problem)
    bounds = np.array([spec.bounds_of(n) for n in CONTROL.names])
    held = tuple(i for i, n in enumerate(CONTROL.names) if n in problem.fix)

    def controller():
        return ResolvedControl(solver.residual_map, problem.params, result.X, result.u, study.criterion,
                               fixed=held, lower=bounds[:, 0], upper=bounds[:, 1])

    offset = np.array([dict(study.perturbation).get(n, 0.0) for n in APEX.names])
    table = _table(out_dir / "strides.csv", STRIDE_COLUMNS, ["phase", "n"], quiet)
    summary = run_adaptive(controller(), result.X + offset, problem.params, study.strides, study.frozen_strides, table, quiet)
    plots.adaptive_figures(table.rows, out_dir)
    recovery = None
    if offset.any():
        if not quiet:
            print(f"{problem.name}: bisecting the largest recovered perturbation...", file=sys.stderr)
        recovery = largest_recovered(controller, solver.residual_map, problem.params, result.X, offset, study.probe_strides)
    return {
        "start": {"apex": result.apex, "control": result.control, "spectral_radius": result.spectral_radius},
        "perturbation": dict(study.perturbation),
        "criterion": study.criterion,
        **summary,
        "largest_recovered": recovery,
    }
