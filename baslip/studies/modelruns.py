"""Runs of a described model's problem: its gait, its branch or its atlas, and their files.

:func:`run_model_problem` solves the problem's gait (verified independently), then the
continuation or the atlas it asks for, and writes, all at once or not at all:

* ``result.json``: the problem, the gait (values, multipliers, checks), and the branch's
  or atlas's summary (points, special points, stable share, why it stopped);
* ``branch.csv`` (one row per point) and ``branch.png``, or ``charts.csv`` (one row per
  chart centre) and ``atlas.png``;
* ``curve.csv`` and ``curve.png``: the bifurcation curves a continuation follows in a
  second parameter, from the branch's first special point of each kind;
* ``basins.csv`` (one row per controller and start) and ``basins.png``: the gait's
  stride-to-stride controllers and their measured basins;
* ``points.csv`` and ``sweep.png``: a sweep's gaits on a grid of fixed quantities, each
  verified or with the reason there is none.

Every row carries its independent verification; the summaries count only rows verified
to the problem's tolerance.
"""

from __future__ import annotations

import csv
import io
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from baslip.analysis.atlas import AtlasSettings
from baslip.analysis.modelcontrol import RETURNED, basin, design, grid_axes, grid_starts
from baslip.analysis.modelcurves import ModelCurve, trace_model_curve
from baslip.analysis.modelfamilies import ModelBranch, ModelChart, continue_model, cover_model
from baslip.analysis.modelstart import carry, reference_start
from baslip.diagnostics import IN_PLACE, logger
from baslip.errors import RunError
from baslip.files.atomic import json_text, write_files_atomically
from baslip.gait.modelsolver import ModelGait, ModelSolver, NoFixedPoint
from baslip.numerics.continuation import Settings
from baslip.numerics.intervals import wilson_interval
from baslip.problem.model_file import (
    ModelAtlasStudy,
    ModelContinuation,
    ModelControllersStudy,
    ModelProblem,
    ModelSweepStudy,
)
from baslip.problem.modelspec import ModelSpec

LOG = logger(__name__)


@dataclass(frozen=True)
class ModelRun:
    """What a described model's problem gave: its gait, and its branch or atlas.

    Attributes
    ----------
    problem : ModelProblem
        The problem.
    gait : ModelGait
        Its verified gait.
    branch : ModelBranch or None
        The continuation's branch, if it asked for one.
    charts : tuple of ModelChart
        The atlas's chart centres, if it asked for one.
    record : dict
        ``result.json``'s content.
    table : tuple of dict
        The branch's points or the atlas's chart centres, as ``branch.csv`` or
        ``charts.csv`` holds them (empty for a gait alone).
    curves : tuple of ModelCurve
        The bifurcation curves the continuation followed, if it asked for any.
    files : tuple of Path
        The files written (none without an output folder).
    """

    problem: ModelProblem
    gait: ModelGait
    branch: ModelBranch | None
    charts: tuple[ModelChart, ...]
    record: dict
    table: tuple[dict, ...] = ()
    curves: tuple[ModelCurve, ...] = ()
    files: tuple[Path, ...] = field(default=())

    @property
    def kind(self) -> str:
        """``branch``, ``atlas``, ``basins``, ``sweep`` or ``gait``: what the run holds besides its gait."""
        if self.branch is not None:
            return "branch"
        if self.problem.sweep is not None:
            return "sweep"
        return "atlas" if self.problem.atlas is not None else "basins" if self.problem.controllers else "gait"

    def rows(self) -> list[dict]:
        """The branch's points or the atlas's chart centres (values by name, spectral
        radius, stability, verification)."""
        return [dict(row) for row in self.table]

    def to_dataframe(self):
        """:meth:`rows` as a pandas DataFrame (needs pandas)."""
        try:
            import pandas
        except ImportError:
            raise ImportError("to_dataframe needs pandas: pip install pandas") from None
        return pandas.DataFrame(self.rows())

    def plot(self):
        """The run's figures by the names of the files the command line writes them to:
        its branch (and its curves), its atlas, its controllers' basins or its sweep;
        none for a gait alone."""
        from baslip.viz.gallery import Figures

        figures = []
        if self.table:
            figures.append(_figure(self.problem, self.kind, list(self.table), _basin_axes(self.record)))
            figures[-1].set_label(self.kind)
        if self.curves:
            figures.append(_curves_figure(self.problem, self.curves))
            figures[-1].set_label("curve")
        return Figures(figures)

    def summary(self) -> str:
        """A few lines on the gait and what the run found."""
        gait = self.gait
        free = ", ".join(f"{n} = {gait.values[n]:.6g}" for n in gait.spec.free)
        lines = [f"{self.problem.name}: model {gait.spec.model.name}, law {self.record['gait']['law']}: "
                 f"{'stable' if gait.stable else 'unstable'} gait, spectral radius {gait.spectral_radius:.4g}",
                 f"  {free}; verified independently to {gait.verification:.1e}"]
        if "branch" in self.record:
            b = self.record["branch"]
            lines.append(f"  branch in {b['parameter']}: {b['points']} points ({b['verified']} verified), "
                         f"{b['stable']} stable; special points: {', '.join(b['special']) or 'none'}; {b['stop_reason']}")
        for curve in self.record.get("curves", []):
            lines.append(f"  {curve['type'].replace('_', ' ')} curve in ({curve['first']}, {curve['second']}): "
                         f"{curve['points']} points ({curve['verified']} verified); {curve['stop_reason']}")
        for c in self.record.get("controllers", {}).get("controllers", []):
            lines.append(f"  {c['name']}: closed-loop spectral radius {c['spectral_radius']:.4g}; basin "
                         f"{c['returned']} of {c['starts']} starts ({100 * c['share']:.0f} %, 95 % interval "
                         f"{100 * c['interval'][0]:.0f}-{100 * c['interval'][1]:.0f} %)"
                         + (f"; {c['fell']} fell" if "fell" in c else ""))
        if "sweep" in self.record:
            w = self.record["sweep"]
            lines.append(f"  sweep: {w['points']} points, {w['verified']} verified, {w['stable']} stable")
        if "atlas" in self.record:
            a = self.record["atlas"]
            lines.append(f"  atlas: {a['charts']} charts ({a['verified']} verified), {a['pieces']} piece(s), "
                         f"{a['stable']} stable; least spectral radius {a['least_radius']:.4g}; "
                         f"{'complete' if a['complete'] else 'not complete'}")
        return "\n".join(lines)


def run_model_problem(problem: ModelProblem, out: Path | None = None) -> ModelRun:
    """Solve ``problem``'s gait and run what it asks for; write the files into ``out``.

    Raises
    ------
    NoFixedPoint
        The gait was not found, or not verified.
    """
    start = time.perf_counter()
    solver = ModelSolver(problem.spec)
    gait, started = _first_gait(solver, problem)
    record: dict = {"problem": problem.to_dict(), "gait": {**gait.to_dict(), "start": started}}
    branch: ModelBranch | None = None
    charts: tuple[ModelChart, ...] = ()
    rows: list[dict] = []
    curves: tuple[ModelCurve, ...] = ()
    if problem.continuation is not None:
        branch = _branch(solver, gait, problem, problem.continuation)
        record["branch"], rows = _branch_summary(problem, branch)
        curves = _curves(solver, gait, problem, problem.continuation, branch)
        if curves:
            record["curves"] = _curves_summary(problem, curves)
    if problem.atlas is not None:
        charts, record["atlas"], rows = _atlas(solver, gait, problem, problem.atlas)
    if problem.controllers is not None:
        record["controllers"], rows = _controllers(solver, gait, problem, problem.controllers)
    if problem.sweep is not None:
        record["sweep"], rows = _sweep(solver, gait, problem, problem.sweep)
    record["wall_time_s"] = time.perf_counter() - start
    run = ModelRun(problem, gait, branch, charts, record, tuple(rows), curves)
    if out is None:
        return run
    named: dict[Path, str | bytes] = {out / "result.json": json_text(record)}
    if rows:
        from baslip.viz.modelplots import png

        table = {"branch": "branch.csv", "atlas": "charts.csv", "basins": "basins.csv", "sweep": "points.csv"}[run.kind]
        named.update({out / table: _csv(rows), out / f"{run.kind}.png": png(_figure(problem, run.kind, rows, _basin_axes(record)))})
    if curves:
        from baslip.viz.modelplots import png

        named.update({out / "curve.csv": _csv(_curve_rows(problem, curves)),
                      out / "curve.png": png(_curves_figure(problem, curves))})
    write_files_atomically(named)
    return replace(run, files=tuple(named))


def _first_gait(solver: ModelSolver, problem: ModelProblem) -> tuple[ModelGait, str]:
    """The problem's gait and where it started: from the guess; or, with no guess, or
    where the guess gives none and the model names a reference gait, from the reference
    carried to the problem (said on the log)."""
    spec, failed = problem.spec, ""
    if not problem.from_reference:
        LOG.info("%s: solving the gait of model %s", problem.name, spec.model.name)
        try:
            return solver.solve(spec), "the guess"
        except NoFixedPoint as err:
            if not spec.model.reference or spec.model.law(spec.law).name != spec.model.laws[0].name:
                raise
            failed = str(err)
            LOG.info("%s: no gait from the guess (%s); starting from the model's reference gait", problem.name, err)
    LOG.info("%s: carrying model %s's reference gait to the problem", problem.name, spec.model.name)
    try:
        carried = reference_start(solver, spec)
        gait = solver.solve(replace(spec, guess={n: carried[n] for n in spec.free}))
    except RunError as err:
        if not failed:
            raise
        raise NoFixedPoint(f"no gait from the guess ({failed}), nor from the model's reference gait ({err})") from None
    where = "the model's reference gait, carried to the problem"
    return gait, f"{where} (the guess gave none: {failed})" if failed else where


def _branch(solver: ModelSolver, gait: ModelGait, problem: ModelProblem, spec: ModelContinuation) -> ModelBranch:
    settings = Settings(step=spec.step, max_step=max(spec.step, 0.2), max_points=spec.max_points)

    def progress(count: int, _point) -> None:
        LOG.info("%s: branch in %s: %d points on this side", problem.name, spec.parameter, count, extra=IN_PLACE)

    return continue_model(solver, gait, spec.parameter, (spec.low, spec.high), settings, progress)


def _rows(values: list[dict], names: tuple[str, ...], extra: list[dict]) -> list[dict]:
    return [{**{n: v[n] for n in names}, **e} for v, e in zip(values, extra)]


def _csv(rows: list[dict]) -> str:
    """The rows as CSV text, flags as ``true``/``false`` (as baslip's other tables)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows([{k: str(v).lower() if isinstance(v, bool) else v for k, v in row.items()} for row in rows])
    return buffer.getvalue()


def _names(problem: ModelProblem) -> tuple[str, ...]:
    spec = problem.spec
    return (*spec.model.section.coordinates, *(q.name for q in spec.model.quantities(spec.law)))


def _units(problem: ModelProblem) -> dict:
    return {n: problem.spec.model.unit(n, problem.spec.law) for n in _names(problem)}


def _branch_summary(problem: ModelProblem, branch: ModelBranch) -> tuple[dict, list[dict]]:
    """The branch's summary for ``result.json`` (counting verified points only), and its rows."""
    tolerance = problem.spec.tolerance
    rows = _rows([p.values for p in branch.points], _names(problem),
                 [{"spectral_radius": p.spectral_radius, "stable": p.spectral_radius < 1.0, "special": p.special,
                   "verification": p.verification} for p in branch.points])
    verified = [r for r in rows if r["verification"] <= tolerance]
    summary = {
        "parameter": branch.parameter, "points": len(rows), "verified": len(verified),
        "stable": sum(r["stable"] for r in verified), "stop_reason": branch.stop_reason,
        "special": [r["special"] for r in verified if r["special"]],
        "special_points": [r for r in verified if r["special"]],
    }
    return summary, rows


def _curves(solver: ModelSolver, gait: ModelGait, problem: ModelProblem, spec: ModelContinuation,
            branch: ModelBranch) -> tuple[ModelCurve, ...]:
    """Each curve asked for, from the branch's first verified special point of its kind."""
    curves = []
    for kind in spec.follow:
        starts = [p for p in branch.points if p.special == kind and p.verification <= problem.spec.tolerance]
        if not starts:
            LOG.info("%s: no %s on the branch: no such curve", problem.name, kind.replace("_", " "))
            continue
        LOG.info("%s: tracing the %s curve in (%s, %s)", problem.name, kind.replace("_", " "), spec.parameter,
                 spec.second)
        curves.append(trace_model_curve(solver, gait, kind, (spec.parameter, spec.second),
                                        ((spec.low, spec.high), spec.second_range), at=starts[0].values))
    return tuple(curves)


def _curve_rows(problem: ModelProblem, curves: tuple[ModelCurve, ...]) -> list[dict]:
    names = (*_names(problem), *(i.name for i in problem.spec.model.invariants_of(problem.spec.law)))
    return [{"curve": number, "type": curve.kind, **{n: p.values[n] for n in names if n in p.values},
             "special": p.special, "verification": p.verification}
            for number, curve in enumerate(curves) for p in curve.points]


def _curves_figure(problem: ModelProblem, curves: tuple[ModelCurve, ...]):
    from baslip.viz.modelplots import curves_figure

    return curves_figure(_curve_rows(problem, curves), curves[0].first, curves[0].second, _units(problem),
                         f"{problem.name}: bifurcation curves of {problem.spec.model.name}")


def _curves_summary(problem: ModelProblem, curves: tuple[ModelCurve, ...]) -> list[dict]:
    tolerance = problem.spec.tolerance
    return [{"type": c.kind, "first": c.first, "second": c.second, "points": len(c.points),
             "verified": sum(p.verification <= tolerance for p in c.points), "stop_reason": c.stop_reason,
             "codimension_two": [{"type": p.special, **{k: p.values[k] for k in (c.first, c.second)}}
                                 for p in c.points if p.special and p.verification <= tolerance]}
            for c in curves]


def _controllers(solver: ModelSolver, gait: ModelGait, problem: ModelProblem,
                 study: ModelControllersStudy) -> tuple[dict, list[dict]]:
    """Each controller's closed-loop multipliers and its measured basin, and the rows of
    every start (``basins.csv``)."""
    starts = grid_starts(solver, gait, study.spread, study.grid)
    coordinates = problem.spec.model.section.coordinates
    axes = [coordinates[i] for i in grid_axes(solver, gait)]
    summary, rows = [], []
    for controller in design(solver, gait):
        def progress(done: int, name: str = controller.name) -> None:
            LOG.info("%s: %s: %d of %d starts", problem.name, name, done, len(starts), extra=IN_PLACE)

        outcomes = basin(solver, gait, controller, starts, study.strides, progress)
        returned = sum(ok for ok, _ in outcomes)
        # A start that neither returned nor ran every stride fell (its stride failed).
        fell = sum(not ok and taken < study.strides for ok, taken in outcomes)
        summary.append({"name": controller.name, "controls": list(controller.controls),
                        "gain": controller.gain.tolist(), "spectral_radius": controller.spectral_radius,
                        "multipliers": [[float(m.real), float(m.imag)] for m in controller.multipliers],
                        "starts": len(starts), "returned": returned, "share": returned / len(starts),
                        "interval": list(wilson_interval(returned, len(starts))), "fell": fell})
        rows += [{"controller": controller.name, **dict(zip(coordinates, start.tolist())), "returned": ok,
                  "strides": taken} for start, (ok, taken) in zip(starts, outcomes)]
    record = {"grid": study.grid, "spread": study.spread, "axes": axes, "strides": study.strides,
              "returned_within": RETURNED, "controllers": summary}
    return record, rows


def _grid(study: ModelSweepStudy) -> list[dict[str, float]]:
    """The sweep's points in an order where each is next to the one before (the second
    axis runs back and forth), so that each starts from its neighbour."""
    (first, firsts), *rest = study.axes
    if not rest:
        return [{first: v} for v in firsts]
    second, seconds = rest[0]
    return [{first: a, second: b} for i, a in enumerate(firsts) for b in (seconds if i % 2 == 0 else seconds[::-1])]


def _sweep(solver: ModelSolver, gait: ModelGait, problem: ModelProblem,
           study: ModelSweepStudy) -> tuple[dict, list[dict]]:
    """Each point's verified gait (or why there is none), each starting from the last
    point solved; and the summary."""
    spec, names, rows = gait.spec, _names(problem), []
    base = {**gait.values, **spec.fixed_invariants}
    start = base
    grid = _grid(study)
    for done, point in enumerate(grid, start=1):
        try:
            found = _solved_at(solver, replace(spec, fixed={**spec.fixed, **point}), start, base)
        except RunError as err:  # no gait here: recorded, and the next point starts from the last one found
            rows.append({**{n: point.get(n, gait.values[n]) for n in names}, "spectral_radius": float("nan"),
                         "stable": False, "verification": float("nan"), "status": str(err)})
        else:
            start = {**found.values, **found.spec.fixed_invariants}
            rows.append({**{n: found.values[n] for n in names}, "spectral_radius": found.spectral_radius,
                         "stable": found.stable, "verification": found.verification, "status": "verified"})
        LOG.info("%s: sweep: %d of %d points", problem.name, done, len(grid), extra=IN_PLACE)
    verified = [r for r in rows if r["status"] == "verified"]
    summary = {"axes": {name: list(values) for name, values in study.axes}, "points": len(rows),
               "verified": len(verified), "stable": sum(r["stable"] for r in verified)}
    return summary, rows


def _solved_at(solver: ModelSolver, spec: ModelSpec, start: dict, fallback: dict) -> ModelGait:
    """The gait of ``spec`` from its neighbour's values (every quantity's); where that
    start does not converge, continued to ``spec`` from the neighbour, and else from the
    problem's own gait (``fallback``)."""
    free = {n: start[n] for n in spec.free}
    try:
        return solver.solve(replace(spec, guess=free))
    except RunError:
        pass
    for origin in (start, fallback):
        try:
            carried = carry(solver, spec, origin)
            return solver.solve(replace(spec, guess={n: carried[n] for n in spec.free}))
        except RunError:
            continue
    raise NoFixedPoint("no gait here from the neighbour, nor continued from it or from the problem's gait")


def _basin_axes(record: dict) -> tuple[str, ...]:
    """The two section coordinates a controllers study's grid spreads (none if it is not one)."""
    return tuple(record.get("controllers", {}).get("axes", ()))


def _figure(problem: ModelProblem, kind: str, rows: list[dict], axes: tuple[str, ...] = ()):
    """The branch's, the atlas's or the basins' figure from its rows (``axes``: the basins'
    two section coordinates, by default the first two)."""
    from baslip.viz.modelplots import atlas_figure, basins_figure, branch_figure

    spec, units = problem.spec, _units(problem)
    if kind == "basins":
        x, y = axes or spec.model.section.coordinates[:2]
        return basins_figure(rows, x, y, units, f"{problem.name}: basins of {spec.model.name}'s controllers")
    if kind == "sweep" and problem.sweep is not None:
        swept = [name for name, _ in problem.sweep.axes]
        found = [r for r in rows if r["status"] == "verified"]
        x, y = (swept[0], swept[1]) if len(swept) == 2 else (swept[0], "spectral_radius")
        return atlas_figure(found, x, y, units, f"{problem.name}: sweep of {spec.model.name}'s gaits")
    free = spec.free
    if kind == "branch" and problem.continuation is not None:
        quantity = free[0] if free else spec.model.section.coordinates[0]
        return branch_figure(rows, problem.continuation.parameter, quantity, units,
                             f"{problem.name}: gaits of {spec.model.name} against {problem.continuation.parameter}")
    x, y = (free[0], free[1]) if len(free) > 1 else (free[0], "spectral_radius")
    if problem.atlas is not None and problem.atlas.plot:
        x, y = problem.atlas.plot
    return atlas_figure(rows, x, y, units, f"{problem.name}: atlas of {spec.model.name}'s gaits")


def _atlas(solver: ModelSolver, gait: ModelGait, problem: ModelProblem,
           study: ModelAtlasStudy) -> tuple[tuple[ModelChart, ...], dict, list[dict]]:
    """The atlas's chart centres, its summary (counting verified centres only) and rows."""

    def progress(charts: int, _seeds: int) -> None:
        LOG.info("%s: atlas: %d charts", problem.name, charts, extra=IN_PLACE)

    settings = AtlasSettings(radius=study.radius, max_radius=study.max_radius, max_charts=study.max_charts)
    atlas, charts = cover_model(solver, gait, settings, progress)
    tolerance = problem.spec.tolerance
    verified = [c for c in charts if c.verification <= tolerance]
    summary = {
        "charts": len(charts), "verified": len(verified), "pieces": atlas.piece_count, "dimension": atlas.dimension,
        "stable": sum(c.spectral_radius < 1.0 for c in verified), "complete": atlas.complete,
        "least_radius": min((c.spectral_radius for c in verified), default=float("nan")),
        "boundaries": {kind: sum(b.kind == kind for b in atlas.boundaries)
                       for kind in sorted({b.kind for b in atlas.boundaries})},
    }
    rows = _rows([c.values for c in charts], _names(problem),
                 [{"spectral_radius": c.spectral_radius, "stable": c.spectral_radius < 1.0, "piece": c.piece,
                   "verification": c.verification} for c in charts])
    return charts, summary, rows
