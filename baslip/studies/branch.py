"""Run a ``continuation:`` problem: solve the start, trace the branch, write its files.

With ``switch: period_doubling`` the run also switches, at each period doubling found on
the first branch, onto the branch of orbits of twice the period, and traces it.

Writes ``branch.csv`` (one row per point: the branch it belongs to and its period in
strides, the parameter, apex, control, energy, the four multipliers, spectral radius,
stability and the special-point label), ``result.json`` (the branches, why each stopped,
and the special points) and ``diagram.png``.

With a ``second`` parameter it then follows bifurcation curves from the branch's special
points (:mod:`baslip.studies.curve`) and also writes ``curve.csv`` and ``curve.png``.
"""

from __future__ import annotations

import io
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from baslip.diagnostics import end_progress_line
from baslip.engine.codegen import recording_code
from baslip.errors import RunError
from baslip.files.atomic import json_text, write_files_atomically
from baslip.files.runs import hold_for
from baslip.gait.stability import STABILITY_MARGIN
from baslip.model.dynamics import APEX
from baslip.model.quantities import quantity_text
from baslip.numerics.continuation import CorrectionFailed, Point, Settings, continue_branch, join, switch_branch
from baslip.studies.curve import curve_csv, follow_curves
from baslip.studies.traced import TracedBranch, named_stop, point_record, points_csv, progress_lines
from baslip.viz.labels import problem_title

#: First step onto a switched branch, as a fraction of the continuation step: small, so
#: that the new branch starts close to the bifurcation it comes from.
SWITCH_FRACTION = 0.1
#: Attempts at a branch switch; the amplitude is halved after each failed one.
SWITCH_ATTEMPTS = 4


class BranchStartFailed(RunError):
    """The starting fixed point did not converge."""


def run_continuation(problem, out_dir: Path, quiet: bool = False, jobs: int | None = None) -> dict:
    """Trace the problem's branches, write branch.csv, result.json and diagram.png to
    ``out_dir`` together, and return the summary that result.json holds. Curves are
    traced on ``jobs`` worker processes (default: one per core; the points do not depend
    on it). Raises :class:`baslip.files.lock.FolderBusy` if another process is writing
    into ``out_dir``."""
    with hold_for(problem, out_dir), recording_code() as code:
        return _run_continuation(problem, out_dir, quiet, code, jobs)


def _run_continuation(problem, out_dir: Path, quiet: bool, code: dict[str, str], jobs: int | None) -> dict:
    from baslip.analysis.gaitsystem import branch_system
    from baslip.files.provenance import provenance
    from baslip.gait.from_problem import fixed_point_spec, solve_start, solver_for
    from baslip.viz import branchplot
    from baslip.viz import figures as plots

    spec = problem.continuation
    controls = problem.hip_law.controls.names
    start_time = time.perf_counter()
    solver = solver_for(problem)
    start = solve_start(problem, solver)
    if not start.converged:
        raise BranchStartFailed(f"the starting fixed point did not converge: {start.status} ({start.message})")

    def system_for(strides: int):
        fixed_point = replace(fixed_point_spec(problem), strides=strides)
        return branch_system(fixed_point, spec.parameter, solver.residual_map, solver.jacobian_map)

    first = system_for(problem.strides)
    settings = Settings(
        step=spec.step, max_points=spec.max_points,
        lam_range=(spec.lo / first.lam_scale, spec.hi / first.lam_scale),
    )
    v0 = first.pack(start.X, start.u, first.start_value())
    traced = [_trace(first, v0, spec.direction, settings, solver, 0, None, quiet)]
    failed_switches = []
    if spec.switch == "period_doubling":
        for point in [p for p in traced[0].branch.special if p.special == "period_doubling"]:
            doubled = system_for(2 * problem.strides)
            origin = {"type": point.special, spec.parameter: first.unpack(point.v)[3], "branch": 0}
            try:
                v, direction = _switch(doubled, point, settings, solver)
            except CorrectionFailed as err:
                failed_switches.append({**origin, "reason": str(err)})
                continue
            traced.append(_trace(doubled, v, direction, settings, solver, len(traced), origin, quiet))

    rows = [_row(t, p, solver) for t in traced for p in t.branch.points]
    diagram = io.BytesIO()
    branchplot.bifurcation_diagram(rows, spec.parameter, spec.plot, diagram, problem=problem_title(problem))
    files: dict[Path, str | bytes] = {}
    curves = None
    if spec.second is not None:

        curve_rows, curves = follow_curves(problem, traced[0], solver, quiet, jobs)
        figure = io.BytesIO()
        plots.curve_diagram(curve_rows, spec.parameter, spec.second, figure, problem=problem_title(problem),
                            params=problem.params, branch=rows)
        files = {out_dir / "curve.csv": curve_csv(curve_rows, spec.parameter, spec.second, controls),
                 out_dir / plots.figure_file("curve"): figure.getvalue()}
    summary = {
        "name": problem.name,
        "parameter": spec.parameter,
        "range": [spec.lo, spec.hi],
        "points": len(rows),
        "stop_reason": traced[0].branch.stop_reason,
        "branches": [
            {"branch": t.number, "strides": t.strides, "points": len(t.branch.points),
             "stop_reason": t.branch.stop_reason, "switched_from": t.origin}
            for t in traced
        ],
        "failed_switches": failed_switches,
        "special_points": [_special(r, spec.parameter, controls) for r in rows if r["special"]],
        **({"curves": curves} if curves is not None else {}),
        "wall_time_s": time.perf_counter() - start_time,
        "provenance": provenance(problem, code),
    }
    # All files or none: an error before this point leaves the old ones as they were.
    write_files_atomically({
        out_dir / "branch.csv": _csv(rows, spec.parameter, controls),
        out_dir / "result.json": json_text(summary),
        out_dir / plots.figure_file("diagram"): diagram.getvalue(),
        **files,
    })
    return summary


def _trace(system, v0, direction, settings, solver, number, origin, quiet) -> TracedBranch:
    """Trace one branch, every point verified independently."""

    started, lam0 = time.perf_counter(), v0[-1]
    lo, hi = settings.lam_range

    def describe(n, point):
        lam, elapsed = point.v[-1], time.perf_counter() - started
        end = hi if lam >= lam0 else lo
        rate = abs(lam - lam0) / elapsed if elapsed > 0 else 0.0
        eta = f", about {abs(end - lam) / rate:.0f} s to the end of the range" if rate > 0 and math.isfinite(end) else ""
        return (f"branch {number} ({system.spec.strides} stride{'s' if system.spec.strides > 1 else ''}): "
                f"{n} points, {quantity_text(system.parameter, lam * system.lam_scale, 6)}{eta}")

    progress = progress_lines(describe, quiet)

    def verified(v):
        return system.verification_failure(v, solver.verify_map)

    if isinstance(direction, str):  # "both": down first, then up, joined at the start
        lower = continue_branch(system, v0, -1.0, settings, accept=verified, progress=progress)
        upper = continue_branch(system, v0, 1.0, settings, accept=verified, progress=progress)
        lower = replace(lower, stop_reason=named_stop(system, lower))
        upper = replace(upper, stop_reason=named_stop(system, upper))
        branch = join(lower, upper)
    else:
        branch = continue_branch(system, v0, direction, settings, accept=verified, progress=progress)
        branch = replace(branch, stop_reason=named_stop(system, branch))
    end_progress_line()
    return TracedBranch(number, system, branch, origin)


def _switch(system, point: Point, settings: Settings, solver) -> tuple[np.ndarray, np.ndarray]:
    """First verified point of the branch through ``point`` of ``system``, trying smaller
    amplitudes if the first attempts fail."""
    amplitude, reason = SWITCH_FRACTION * settings.step, ""
    for _ in range(SWITCH_ATTEMPTS):
        try:
            v, direction = switch_branch(system, point, amplitude, settings)
            reason = system.verification_failure(v, solver.verify_map)
            if reason is None:
                return v, direction
        except CorrectionFailed as err:
            reason = str(err)
        amplitude /= 2
    raise CorrectionFailed(f"no verified point on the new branch: {reason}")


def _row(traced: TracedBranch, point: Point, solver) -> dict:
    system = traced.system
    X, u, params, lam = system.unpack(point.v)
    row = {"branch": traced.number, "strides": traced.strides, system.parameter: lam,
           **APEX.to_dict(X), **system.spec.law.control_dict(u)}
    row["energy"] = system.energy(X, params)
    for i, m in enumerate(point.multipliers, start=1):
        row[f"mult{i}_re"], row[f"mult{i}_im"] = float(m.real), float(m.imag)
    nontrivial = [abs(m) for m, t in zip(point.multipliers, point.trivial) if not t]
    radius = max(nontrivial) if nontrivial else 0.0
    row.update(spectral_radius=radius, stable=bool(radius < 1 - STABILITY_MARGIN), special=point.special)
    # For the diagram only: every apex of the orbit (a period-2 branch shows both).
    orbit = solver.residual_map.simulate(X, u, params, traced.strides)
    row["orbit"] = [APEX.to_dict(a) for a in orbit.apexes[:-1]] if orbit.fall is None else [APEX.to_dict(X)]
    return row


def _special(row: dict, parameter: str, controls: tuple[str, ...]) -> dict:
    return {"type": row["special"], parameter: row[parameter], "branch": row["branch"], "strides": row["strides"],
            **point_record(row, controls)}


def _csv(rows: list[dict], parameter: str, controls: tuple[str, ...]) -> str:
    return points_csv(rows, ["branch", "strides", parameter], ["spectral_radius", "stable", "special"], controls)


