"""Run a ``continuation:`` problem: solve the start, trace the branch, write its files.

Writes ``branch.csv`` (one row per point: the parameter, apex, control, energy, the four
multipliers, spectral radius, stability and the special-point label), ``result.json``
(the special points and why the run stopped) and ``diagram.png``.
"""

from __future__ import annotations

import csv
import io
import sys
import time
from pathlib import Path

import numpy as np

from ..continuation import Point, Settings, continue_branch
from ..control import CONTROL
from ..model import APEX
from ..output import json_text, write_files_atomically
from ..stability import STABILITY_MARGIN


class BranchStartFailed(RuntimeError):
    """The starting fixed point did not converge."""


def run_continuation(problem, out_dir: Path, quiet: bool = False) -> dict:
    from .. import plots
    from ..api import fixed_point_spec, shooting_options, solve_problem
    from ..branches import FixedPointSystem
    from ..fixedpoint import VERIFY_EPS, FixedPointSolver

    spec = problem.continuation
    start_time = time.perf_counter()
    solver = FixedPointSolver(shooting_options(problem))
    start = solve_problem(problem, solver)
    if not start.converged:
        raise BranchStartFailed(f"the starting fixed point did not converge: {start.status} ({start.message})")
    system = FixedPointSystem(fixed_point_spec(problem), spec.parameter, solver.residual_map, solver.jacobian_map)
    v0 = system.pack(start.X, start.u, system.start_value())

    def verified(v):
        X, u, params, _ = system.unpack(v)
        check = solver.verify_map.stride(X, u, params)
        if not check.ok:
            return f"the runner falls ({check.fall.value})"
        eps = float(np.linalg.norm(check.apex - X) / np.linalg.norm(X))
        return None if eps <= VERIFY_EPS else f"not verified (eps = {eps:.1e})"

    def progress(n, point):
        if not quiet:
            lam = point.v[-1] * system.lam_scale
            print(f"\r{problem.name}: {n} points, {spec.parameter} = {lam:.6g}   ", end="", file=sys.stderr, flush=True)

    settings = Settings(
        step=spec.step, max_points=spec.max_points,
        lam_range=(spec.lo / system.lam_scale, spec.hi / system.lam_scale),
    )
    branch = continue_branch(system, v0, spec.direction, settings, accept=verified, progress=progress)
    if not quiet:
        print(file=sys.stderr)
    rows = [_row(system, p) for p in branch.points]
    write_files_atomically({out_dir / "branch.csv": _csv(rows, spec.parameter)})
    plots.bifurcation_diagram(rows, spec.parameter, spec.plot, out_dir / "diagram.png")
    special = [
        {"type": r["special"], spec.parameter: r[spec.parameter], "apex": {n: r[n] for n in APEX.names},
         "control": {n: r[n] for n in CONTROL.names},
         "multipliers": [[r[f"mult{i}_re"], r[f"mult{i}_im"]] for i in range(1, 5)]}
        for r in rows if r["special"]
    ]
    return {
        "name": problem.name,
        "parameter": spec.parameter,
        "range": [spec.lo, spec.hi],
        "points": len(rows),
        "stop_reason": branch.stop_reason,
        "special_points": special,
        "wall_time_s": time.perf_counter() - start_time,
    }


def _row(system, point: Point) -> dict:
    X, u, params, lam = system.unpack(point.v)
    row = {system.parameter: lam, **APEX.to_dict(X), **CONTROL.to_dict(u)}
    row["energy"] = system.energy(X, params)
    for i, m in enumerate(point.multipliers, start=1):
        row[f"mult{i}_re"], row[f"mult{i}_im"] = float(m.real), float(m.imag)
    nontrivial = [abs(m) for m, t in zip(point.multipliers, point.trivial) if not t]
    radius = max(nontrivial) if nontrivial else 0.0
    row.update(spectral_radius=radius, stable=bool(radius < 1 - STABILITY_MARGIN), special=point.special)
    return row


def _csv(rows: list[dict], parameter: str) -> str:
    columns = [parameter, *APEX.names, *CONTROL.names, "energy"]
    columns += [f"mult{i}_{part}" for i in range(1, 5) for part in ("re", "im")]
    columns += ["spectral_radius", "stable", "special"]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, columns, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (repr(v) if isinstance(v, float) else ("true" if v is True else "false" if v is False else v))
                         for k, v in row.items()})
    return buffer.getvalue()


def write_summary(summary: dict, out_dir: Path) -> None:
    write_files_atomically({out_dir / "result.json": json_text(summary)})
