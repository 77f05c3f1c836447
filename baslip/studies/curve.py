"""Follow bifurcation curves in two parameters from the special points of a branch.

A ``continuation:`` with ``second``, ``second_range`` and ``follow`` first traces its
one-parameter branch (:mod:`baslip.studies.branch`), then, for each curve type in
``follow``, starts from the branch's special point of that type nearest the start (or
from every one, with ``starts: all``) and traces the curve both ways within both ranges
(:mod:`baslip.analysis.bifurcation`). Every point is verified by the independent re-simulation, as on
a branch.

Gives the rows of ``curve.csv`` (one per point: the curve, what holds there, both
parameters, apex, control, energy, the four multipliers, whether the point bounds a
region of stable gaits, cos(theta) of a Neimark-Sacker pair, and the codimension-two
label) and the summary of the curves for ``result.json``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baslip.analysis.bifurcation import CURVE_DIRECTIONS, CurveSystem, curve_start, stability_boundary, trace_half
from baslip.analysis.gaitsystem import branch_system
from baslip.diagnostics import end_progress_line
from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.model.dynamics import APEX
from baslip.model.quantities import quantity_text
from baslip.numerics.continuation import Branch, CorrectionFailed, Point, Settings, join
from baslip.studies.processes import map_in_processes
from baslip.studies.traced import TracedBranch, named_stop, point_record, points_csv, progress_lines

#: Largest step along a curve (scaled units): small enough that the drawn polyline, and
#: the inside/outside test of :mod:`baslip.studies.boundary`, follow the curve closely.
CURVE_MAX_STEP = 0.25
#: A start this close (scaled units) to a curve already traced lies on it.
SAME_CURVE = 1e-3


def follow_curves(problem, branch: TracedBranch, solver, quiet: bool, jobs: int | None = None) -> tuple[list[dict], dict]:
    """Trace the curves that ``problem.continuation`` asks for from ``branch``; return
    the rows of curve.csv and the curves' summary.

    Each curve's first point is found here; its two halves are then traced at once on
    the cores (``jobs`` worker processes, default one per core), each half from its first
    point alone, so the points do not depend on how many run at once. A start that lies
    on a curve traced from an earlier start is skipped (its halves are traced, then
    dropped)."""
    spec = problem.continuation
    base, settings = _curve_setup(problem, branch.strides, solver)
    second_start = base.start_value(spec.second)
    starts, failed = [], []
    for kind, point in _starts(branch, spec):
        X, u, _, first_value = branch.system.unpack(point.v)
        origin = {"type": kind, spec.parameter: first_value, spec.second: second_start}
        packed = (X, u, first_value, second_start)
        v = base.pack(*packed)
        try:
            start = curve_start(CurveSystem(base, kind), v, settings, _verified(base, solver))
        except CorrectionFailed as err:
            failed.append({**origin, "reason": str(err)})
            continue
        starts.append((kind, v, packed, start, origin))
    halves = map_in_processes(_half_tracer, [(n, kind, packed, start, sign)
                                             for n, (kind, _, packed, start, _) in enumerate(starts)
                                             for sign in CURVE_DIRECTIONS],
                              (problem, branch.strides, quiet), jobs)
    end_progress_line()
    traced: list[tuple[int, CurveSystem, Branch, dict]] = []
    skipped = []
    for n, (kind, v, _, _, origin) in enumerate(starts):
        on = _on_traced(v, kind, traced)
        if on is not None:
            skipped.append({**origin, "on_curve": on})
            continue
        traced.append((len(traced), CurveSystem(base, kind), join(*halves[2 * n : 2 * n + 2]), origin))
    rows = [_row(number, curve, point) for number, curve, points, _ in traced for point in points.points]
    summary = {
        "second": spec.second,
        "second_range": [spec.second_lo, spec.second_hi],
        "follow": list(spec.follow),
        "curves": [{"curve": number, "type": curve.kind, "points": len(points.points), "from": origin,
                    "stop_reason": points.stop_reason} for number, curve, points, origin in traced],
        "skipped_starts": skipped,
        "failed_curves": failed,
        "codimension_two_points": [_codim2(r, spec.parameter, spec.second, problem.hip_law.controls.names) for r in rows
                                   if r["special"]],
    }
    return rows, summary


def _curve_setup(problem, strides: int, solver):
    """(the base system of the curves, with both parameters free; their settings)."""
    spec = problem.continuation
    base = branch_system(replace(fixed_point_spec(problem), strides=strides), spec.parameter,
                         solver.residual_map, solver.jacobian_map, second=spec.second)
    first_scale, second_scale = base.lam_scales
    settings = Settings(step=spec.step, max_step=CURVE_MAX_STEP, max_points=spec.max_points,
                        lam_range=(spec.second_lo / second_scale, spec.second_hi / second_scale),
                        other_ranges=((-2, spec.lo / first_scale, spec.hi / first_scale),))
    return base, settings


def _verified(base, solver):
    """The veto of curve points: the independent re-simulation's failure, if any."""
    return lambda w: base.verification_failure(w, solver.verify_map)


def _half_tracer(context):
    """A worker's tracer of curve halves (see :func:`follow_curves`): it builds the solver
    and the curves' base system once, and traces each half it is given, (curve number,
    type, (apex, control, both parameters) of the branch point it starts from, the
    curve's first point, sign), to a Branch."""
    problem, strides, quiet = context
    solver = solver_for(problem)
    base, settings = _curve_setup(problem, strides, solver)

    def trace(item) -> Branch:
        number, kind, packed, start, sign = item
        # Packing sets the scale of the nearest-guess family's multipliers, as it was set
        # when the curve's first point was found.
        base.pack(*packed)
        progress = progress_lines(lambda n, p: _describe(base, kind, number, n, p), quiet)
        return trace_half(CurveSystem(base, kind), start, sign, settings, accept=_verified(base, solver),
                          progress=progress, explain=lambda b: named_stop(base, b))

    return trace


def _starts(branch: TracedBranch, spec) -> list[tuple[str, Point]]:
    """(curve type, branch point) to start from: per type, the special point nearest the
    branch's start in the first parameter, or all of them."""
    start = branch.system.start_value()
    starts = []
    for kind in spec.follow:
        found = [p for p in branch.branch.points if p.special == kind]
        if spec.starts == "first" and found:
            found = [min(found, key=lambda p: abs(branch.system.unpack(p.v)[3] - start))]
        starts += [(kind, p) for p in found]
    return starts


def _on_traced(v: np.ndarray, kind: str, traced) -> int | None:
    """The number of a traced curve of ``kind`` that passes through ``v``'s parameters."""
    here = v[-2:]
    for number, curve, points, _ in traced:
        if curve.kind != kind:
            continue
        polyline = np.array([p.v[-2:] for p in points.points])
        for a, b in zip(polyline[:-1], polyline[1:]):
            t = np.clip(np.dot(here - a, b - a) / max(np.dot(b - a, b - a), 1e-300), 0.0, 1.0)
            if np.linalg.norm(a + t * (b - a) - here) < SAME_CURVE:
                return number
    return None


def _describe(base, kind: str, number: int, n: int, point: Point) -> str:
    values = ", ".join(quantity_text(name, value, 6) for name, value in base.values(point.v).items())
    return f"curve {number} ({kind.replace('_', ' ')}): {n} points, {values}"


def _row(number: int, curve: CurveSystem, point: Point) -> dict:
    base = curve.base
    X, u, params, _ = base.unpack(point.v)
    A = curve.map_jacobian(point.v)
    row = {"curve": number, "type": curve.on_curve(point.v), **APEX.to_dict(X), **base.spec.law.control_dict(u),
           "energy": base.energy(X, params)}
    row.update(base.values(point.v))  # both parameters (the energy, if it is one, as continued)
    for i, m in enumerate(point.multipliers, start=1):
        row[f"mult{i}_re"], row[f"mult{i}_im"] = float(m.real), float(m.imag)
    row["stability_boundary"] = stability_boundary(curve.kind, A)
    row["kappa"] = point.tests.get("kappa", "")
    row["special"] = point.special
    return row


def _codim2(row: dict, first: str, second: str, controls: tuple[str, ...]) -> dict:
    return {"type": row["special"], "curve": row["curve"], "on": row["type"], first: row[first], second: row[second],
            **point_record(row, controls)}


def curve_csv(rows: list[dict], first: str, second: str, controls: tuple[str, ...]) -> str:
    """curve.csv: both parameters lead, under their own names; ``controls`` are the hip
    law's control columns."""
    return points_csv(rows, ["curve", "type", first, second], ["stability_boundary", "kappa", "special"], controls)
