"""One cell of an atlas study, in a worker: seeds, the covering, the chart reports and the
polished best gaits (see :mod:`baslip.studies.atlas`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from baslip import diagnostics
from baslip.analysis.atlas import Atlas as Covering
from baslip.analysis.atlas import AtlasSettings, cover, local_minima
from baslip.analysis.descent import StabilityDescent
from baslip.analysis.gaitatlas import ChartChecker, ChartReport, GaitManifold, chart_report
from baslip.diagnostics import logger
from baslip.engine.returnmap import ReturnMap, RunnerFell, Tolerances
from baslip.gait.anybody import started_from_body
from baslip.gait.draws import random_start
from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import HipLaw
from baslip.model.quantities import design_values
from baslip.problem.reader import Problem
from baslip.problem.study import Atlas
from baslip.status import VERIFY_EPS
from baslip.studies.optimal import UPRIGHT_AT_APEX, UPRIGHT_THROUGHOUT, task_rng
from baslip.studies.sweep import key_column

_log = logger(__name__)

#: Tolerance of the map whose AD Jacobian gives the charts' tangents and multipliers (the
#: equations themselves are solved on the 1e-12 map): a Jacobian at 1e-10 costs a third
#: less and moves the multipliers by less than 1e-8.
JACOBIAN_TOLERANCE = 1e-10
#: Seconds between two progress lines of a cell.
PROGRESS_EVERY_S = 15.0
#: The gaits a cell polishes: the least radius of all (the bounds make it upright at the
#: apex, for an upright problem), and the least of those upright throughout the stride.
MEANINGS = ("any", "upright_throughout")
#: Least chart radius, as a fraction of the study's radius.
LEAST_RADIUS_FRACTION = 1 / 16


class CellAtlas:
    """The solvers and maps of a worker, built once, and the atlas of one cell at a time."""

    def __init__(self, problem: Problem, study: Atlas, quiet: bool = True):
        self.problem, self.study, self.quiet = problem, study, quiet
        self.solver = solver_for(problem)
        self.jacobian_map = ReturnMap(Tolerances(JACOBIAN_TOLERANCE, JACOBIAN_TOLERANCE), law=problem.hip_law)
        self.checker = ChartChecker(problem.hip_law, problem.params)
        self.descent = StabilityDescent(self.solver.residual_map, max_iterations=study.iterations,
                                        compass_trials=study.compass_trials)
        self.base = fixed_point_spec(problem)
        self.settings = AtlasSettings(radius=study.radius, max_radius=study.max_radius,
                                      min_radius=study.radius * LEAST_RADIUS_FRACTION, max_charts=study.max_charts,
                                      max_priority=math.inf if study.max_spectral_radius is None
                                      else study.max_spectral_radius)

    def run(self, task: dict) -> dict:
        """The cells.csv row of ``task``, with ``charts`` and ``boundaries`` (row lists)."""
        held = {a.name: task[key_column(a.name)] for a in self.study.axes}
        spec = self._started(replace(self.base, fixed={**self.base.fixed, **held}))
        manifold = GaitManifold(spec, self.solver.residual_map, self.jacobian_map)
        rng = task_rng(self.study, {**task, "start": 0})
        say = self._progress(held)
        seeds = []
        for number in range(self.study.seeds):
            say(f"solving seed {number + 1} of {self.study.seeds}", always=number == 0)
            seeds.append(self._seed(spec, manifold, rng if number else None))
        atlas, reports = self.cover_and_check(manifold, seeds, say)
        charts = chart_rows(atlas, reports, self.problem.hip_law)
        row = {k: v for k, v in task.items() if k.startswith("sweep_")}
        row.update(_cell_counts(atlas, charts))
        descents: dict[int, dict | None] = {}  # by chart: a chart best in both meanings descends once
        best = [self._polished(spec, charts, atlas.neighbours, meaning, descents, say) for meaning in MEANINGS]
        row["polished_radius"], row["polished_upright_throughout_radius"] = (
            None if b is None else b["spectral_radius"] for b in best)
        return {**row, "chart_rows": charts, "boundary_rows": boundary_rows(atlas, manifold),
                "best_rows": [b for b in best if b is not None]}

    def cover_and_check(self, manifold: GaitManifold, seeds: Sequence[np.ndarray | None],
                        say: Callable[..., None] = lambda text, always=False: None) -> tuple[Covering, list[ChartReport]]:
        """The atlas of ``manifold`` from ``seeds`` and each chart's report. The charts'
        independent checks (:class:`ChartChecker`) run in a second thread as the charts
        are made, on the other core; the reports do not depend on it."""
        with ThreadPoolExecutor(max_workers=1) as pool:
            checks: list[Future] = []

            def check(chart) -> None:
                design = manifold.to_design(chart.center)
                checks.append(pool.submit(self.checker, design[: APEX.size], design[APEX.size :]))

            atlas = cover(manifold, seeds, manifold.dimension, self.settings,
                          lambda charts, taken: say(f"{charts} charts from {taken} seeds"), on_chart=check)
            say(f"{len(atlas.charts)} charts covered; finishing their independent verification", always=True)
            done = [future.result() for future in checks]
        return atlas, [chart_report(manifold, c.center, d) for c, d in zip(atlas.charts, done)]

    def _progress(self, held: dict):
        """``say(text, always=False)``: logs a progress line of the cell (a worker sends it to
        the parent's progress line), at most every :data:`PROGRESS_EVERY_S` seconds unless
        ``always`` (nothing if quiet)."""
        cell = ", ".join(f"{n} = {v:g}" for n, v in held.items())
        last = [diagnostics.CLOCK.now()]

        def say(text: str, always: bool = False) -> None:
            if not self.quiet and (always or diagnostics.CLOCK.now() - last[0] >= PROGRESS_EVERY_S):
                last[0] = diagnostics.CLOCK.now()
                _log.info(f"{self.problem.name}: cell {cell}: {text}")

        return say

    def _started(self, spec):
        """``spec`` with its guess from the body alone where the problem gives none
        (:func:`~baslip.gait.anybody.start_from_body`): every seed of the cell then starts
        from the gait found there."""
        if self.problem.guess or self.problem.strides != 1:
            return spec
        return started_from_body(spec, self.solver, self.problem.posture)

    def _seed(self, spec, manifold: GaitManifold, rng) -> np.ndarray | None:
        """An independent, verified gait in atlas coordinates (None if the solve failed):
        the problem's own from its guess (without ``rng``), or one with the gains drawn
        over their bounds and held while it is solved."""
        held = {} if rng is None else random_start(spec, rng)
        result = self.solver.solve(replace(spec, fixed={**spec.fixed, **held}))
        if not result.converged:
            return None
        return manifold.to_atlas(np.concatenate([result.X, result.u]))

    def _polished(self, spec, charts: list[dict], neighbours: Sequence[Sequence[int]], meaning: str,
                  descents: dict[int, dict | None], say: Callable[..., None]) -> dict | None:
        """The atlas_best.csv row of a cell for ``meaning`` (see :data:`MEANINGS`): the
        stability descent from each of the ``study.polish`` least local minima of the radius
        over the verified charts of that meaning (on the chart graph, ``neighbours``), its
        end verified independently; the verified end of least radius that still has that
        meaning (None if there is none). Local minima, not the least charts: the least
        charts crowd one valley, and their descents end at its one bottom. ``descents``
        keeps the ends by chart, so a chart that is a candidate in both meanings (every
        chart, where all gaits are upright throughout) descends once."""
        def has_meaning(row: dict) -> bool:
            return meaning == "any" or bool(row[meaning])

        radii = [c["spectral_radius"] if c["status"] == "converged" and has_meaning(c) else None for c in charts]
        candidates = [charts[i] for i in local_minima(radii, neighbours)[: self.study.polish]]
        ends = []
        for number, chart in enumerate(candidates):
            say(f"polishing ({meaning.replace('_', ' ')}): descent {number + 1} of {len(candidates)}",
                always=number == 0)
            if chart["chart"] not in descents:
                descents[chart["chart"]] = self._descend(spec, chart)
            end = descents[chart["chart"]]
            if end is not None and has_meaning(end):
                ends.append({"meaning": meaning, **end})
        return min(ends, key=lambda end: end["spectral_radius"], default=None)

    def _descend(self, spec, chart: dict) -> dict | None:
        """Where the descent from ``chart`` ends, verified, as a row of atlas_best.csv
        but for its meaning; None if a stride of the descent falls or its end is not verified."""
        X = np.array([chart[n] for n in APEX.names])
        u = np.array([chart[n] for n in self.problem.hip_law.controls.names])
        try:
            found = self.descent.run(spec, X, u)
        except RunnerFell:
            return None
        end = self.solver.verify_point(spec, found.best.X, found.best.u, self.problem.name)
        if not end.converged:
            return None
        low, high = self.checker.trunk_range(end.X, end.u, spec.params)
        return {"from_chart": chart["chart"], "start_radius": chart["spectral_radius"],
                **design_values(end.X, end.u, self.problem.hip_law),
                "spectral_radius": end.spectral_radius, "stable": bool(end.stable),
                "residual": end.residual, "theta_h_min": low, "theta_h_max": high,
                **_upright(end.X, low, high), "descent_stop": found.stop_reason}


def _cell_counts(atlas, charts: list[dict]) -> dict:
    verified = [c for c in charts if c["status"] == "converged"]
    total = sum(c["area"] for c in verified)
    stable = sum(c["area"] for c in verified if c["stable"])

    def least(where=lambda c: True):
        radii = [c["spectral_radius"] for c in verified if where(c)]
        return min(radii) if radii else None

    return {
        "seeds": len(atlas.seeds),
        "seeds_failed": sum(s.outcome == "failed" for s in atlas.seeds),
        "seeds_on_covered_pieces": sum(s.outcome == "on a covered piece" for s in atlas.seeds),
        "seeds_not_taken": sum(s.outcome == "not taken" for s in atlas.seeds),
        "pieces": atlas.piece_count, "charts": len(charts), "not_verified": len(charts) - len(verified),
        "complete": atlas.complete, "boundaries": len(atlas.boundaries),
        "corrector_stops": sum(b.kind == "corrector" for b in atlas.boundaries),
        "least_radius": least(), "least_radius_upright_apex": least(lambda c: c["upright_apex"]),
        "least_radius_upright_throughout": least(lambda c: c["upright_throughout"]),
        "stable_share": stable / total if total > 0 else None,
    }


def chart_rows(atlas, reports, law: HipLaw) -> list[dict]:
    """The atlas.csv rows of a cell's charts (without the cell's columns), under ``law``."""
    rows = []
    for chart, report, piece, area, near in zip(atlas.charts, reports, atlas.pieces, atlas.areas, atlas.neighbours):
        rows.append({
            "chart": chart.index, "piece": piece,
            **design_values(report.X, report.u, law),
            "spectral_radius": report.spectral_radius, "stable": report.stable,
            "status": "converged" if report.residual <= VERIFY_EPS else "not_verified",
            "residual": report.residual, "theta_h_min": report.theta_h_min, "theta_h_max": report.theta_h_max,
            **_upright(report.X, report.theta_h_min, report.theta_h_max),
            "radius": chart.radius, "area": area, "neighbours": ";".join(map(str, near)),
        })
    return rows


def _upright(X: np.ndarray, low: float, high: float) -> dict:
    """Both meanings of upright for the gait of apex ``X`` whose trunk ranges over
    [``low``, ``high``] [rad] in its stride."""
    upright = math.pi / 2
    return {"upright_apex": bool(abs(X[APEX.index("theta_h")] - upright) <= UPRIGHT_AT_APEX),
            "upright_throughout": bool(max(abs(low - upright), abs(high - upright)) <= UPRIGHT_THROUGHOUT)}


def boundary_rows(atlas, manifold: GaitManifold) -> list[dict]:
    """The atlas_boundary.csv rows of a cell (without the cell's columns)."""
    return [{"chart": b.chart, "piece": atlas.pieces[b.chart], "kind": b.kind, "reason": b.reason,
             **dict(zip(manifold.design, map(float, manifold.to_design(b.point))))} for b in atlas.boundaries]
