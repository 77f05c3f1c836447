"""The ``atlas`` study: the whole manifold of fixed points at every cell of a grid, covered.

Each task is one cell (a point of ``vary``, usually a speed and a height). Its worker

1. solves ``seeds`` independent gaits with the gains drawn over their whole bounds (as the
   optimal search draws them), each verified;
2. covers the fixed-point manifold from them (:func:`baslip.analysis.atlas.cover` on
   :class:`baslip.analysis.gaitatlas.GaitManifold`): a seed on a covered piece joins it,
   any other starts a new piece;
3. reports every chart (:func:`baslip.analysis.gaitatlas.chart_report`): multipliers,
   spectral radius, the trunk's range over the stride, and the independent re-simulation's
   eps (charts it does not confirm to eps <= 1e-10 are marked ``not_verified`` and take no
   part in the answers);
4. polishes, with the stability descent, the ``polish`` least local minima of the radius
   on the chart graph (over all charts, and over those upright throughout the stride),
   verifies where each descent ends, and keeps the best verified end (for the second
   meaning, the best that is still upright throughout).

Files: ``cells.csv`` (one row per cell: pieces, seeds, charts, least radii, stable share),
``atlas.csv`` (one row per chart), ``atlas_boundary.csv`` (where the covering stopped, and
why), ``atlas_best.csv`` (the polished gaits), ``atlas.png`` and ``best_gaits_trunk.png``
(the trunk's angle over a stride of each polished gait). The charts of a finished cell are kept, until the study is
complete, in ``.cells.csv.charts`` (one JSON line per cell, synced before the cell's row),
so that a resumed study rebuilds the same ``atlas.csv``.
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

from baslip.diagnostics import logger
from baslip.files.atomic import write_files_atomically
from baslip.files.rows import read_points, row_damage
from baslip.model.hiplaw import PD, HipLaw
from baslip.model.quantities import design_names
from baslip.problem.reader import Problem
from baslip.problem.study import Atlas
from baslip.studies.common import run_info
from baslip.studies.optimal import UPRIGHT_AT_APEX, UPRIGHT_THROUGHOUT, best_gait_motions
from baslip.studies.runner import ResumableCsv, StateLog, Workers, csv_text, run_tasks, split_lanes
from baslip.studies.sweep import key_column, sweep_tasks
from baslip.viz.labels import problem_title

_log = logger(__name__)


def chart_columns(law: HipLaw = PD) -> list[str]:
    """Columns of atlas.csv after the cell's own (one row per chart), under ``law``."""
    return ["chart", "piece", *design_names(law), "spectral_radius", "stable", "status", "residual", "theta_h_min",
            "theta_h_max", "upright_apex", "upright_throughout", "radius", "area", "neighbours"]


def boundary_columns(law: HipLaw = PD) -> list[str]:
    """Columns of atlas_boundary.csv after the cell's own."""
    return ["chart", "piece", "kind", "reason", *design_names(law)]


def best_columns(law: HipLaw = PD) -> list[str]:
    """Columns of atlas_best.csv after the cell's own (one row per cell and meaning of "best")."""
    return ["meaning", "from_chart", "start_radius", *design_names(law), "spectral_radius", "stable", "residual",
            "theta_h_min", "theta_h_max", "upright_apex", "upright_throughout", "descent_stop"]


#: Columns of cells.csv after the cell's own.
CELL_COLUMNS = [
    "seeds", "seeds_failed", "seeds_on_covered_pieces", "seeds_not_taken", "pieces", "charts", "not_verified",
    "complete", "boundaries", "corrector_stops",
    "least_radius", "least_radius_upright_apex", "least_radius_upright_throughout", "stable_share",
    "polished_radius", "polished_upright_throughout_radius", "time_s",
]


def atlas_worker(chunk: list[dict], context: tuple[Problem, bool], queue) -> None:
    """Worker process: cover the manifold of each cell not yet done and put its row, with
    its charts and boundaries (``chart_rows``, ``boundary_rows``), on the queue.
    ``context`` is the problem and whether to be quiet (else a cell's progress goes to the
    parent's progress line every :data:`~baslip.studies.atlascell.PROGRESS_EVERY_S` seconds)."""
    from baslip.studies.atlascell import CellAtlas

    problem, quiet = context
    study = problem.study
    assert isinstance(study, Atlas)
    cells = CellAtlas(problem, study, quiet)
    for task in chunk:
        if task.get("done"):
            continue
        started = time.perf_counter()
        row = cells.run(task)
        queue.put({**row, "time_s": time.perf_counter() - started})


class AtlasTable(ResumableCsv):
    """``cells.csv``, whose rows bring their cell's charts and boundaries along: those are
    kept in a synced log beside it until the study is complete, then written out as
    ``atlas.csv``, ``atlas_boundary.csv`` and ``atlas_best.csv`` in task order."""

    def __init__(self, path: Path, columns: list[str], key_columns: list[str], law: HipLaw = PD):
        super().__init__(path, columns, key_columns)
        self.charts = StateLog(self.path.with_name(f".{self.path.name}.charts"))
        self.cell_columns, self.law = key_columns, law
        self._recover_products()

    def _recover_products(self) -> None:
        """A finished atlas (its cells' charts no longer logged) whose ``atlas.csv``,
        ``atlas_boundary.csv`` or ``atlas_best.csv`` was damaged since (a row torn, or
        changed by hand): the cells before the first damaged row get their rows back in
        the log; that cell and the ones after it (in task order, the files' order) are
        dropped from ``cells.csv``, with a note, and solved again."""
        logged = self.charts.read()
        if not self.rows or any(self.key(row) in logged for row in self.rows):
            return  # nothing finished yet, or a study still under way: its log is whole
        order = [self.key(row) for row in self.rows]
        parts: dict = {key: {part: [] for part in PRODUCTS} for key in order}
        first_bad = len(order)
        for part, name in PRODUCTS.items():
            rows, damage = _whole_rows_by_cell(self.path.with_name(name), len(self.cell_columns))
            for key, row in rows:
                if key in parts:
                    parts[key][part].append(row)
            if damage is not None:
                self.notes.append(f"{name}: {damage}")
                # The damaged row is of the last whole row's cell, or of a later one.
                first_bad = min(first_bad, order.index(rows[-1][0]) if rows and rows[-1][0] in order else 0)
        if first_bad == len(order):
            return
        for key in order[:first_bad]:
            self.charts.append(key, parts[key])
        self.notes.append(f"{self.path.name}: {len(order) - first_bad} cells from the damaged rows' on are solved again")
        self.rewrite(self.rows[:first_bad])

    def append(self, row: dict) -> None:
        self.charts.append(self.key(row), {"charts": row["chart_rows"], "boundaries": row["boundary_rows"],
                                           "best": row["best_rows"]})
        super().append(row)

    def finish(self, order) -> None:
        super().finish(order)
        logged = self.charts.read()
        keys = [self.key(task) for task in order]
        if not all(key in logged for key in keys):
            return  # a rerun of a finished study: atlas.csv is already written
        cells = {key: dict(zip(self.cell_columns, key)) for key in keys}
        write_files_atomically({
            self.path.with_name("atlas.csv"): csv_text(self.cell_columns + chart_columns(self.law),
                                                     [{**cells[k], **c} for k in keys for c in logged[k]["charts"]]),
            self.path.with_name("atlas_boundary.csv"): csv_text(
                self.cell_columns + boundary_columns(self.law), [{**cells[k], **b} for k in keys for b in logged[k]["boundaries"]]),
            self.path.with_name("atlas_best.csv"): csv_text(
                self.cell_columns + best_columns(self.law), [{**cells[k], **b} for k in keys for b in logged[k]["best"]]),
        })
        self.charts.clear()


#: The files a finished atlas writes from its log, by the log's part.
PRODUCTS = {"charts": "atlas.csv", "boundaries": "atlas_boundary.csv", "best": "atlas_best.csv"}


def _whole_rows_by_cell(path: Path, key_count: int) -> tuple[list[tuple[tuple[str, ...], dict]], str | None]:
    """The rows of ``path`` before its first damaged one, each as (its cell's key, its
    cells after the key's), and what the damage is (None if there is none)."""
    try:
        with open(path, encoding="utf-8", newline="") as handle:
            lines = list(csv.reader(handle))
    except FileNotFoundError:
        return [], "it is missing"
    except (UnicodeDecodeError, csv.Error):
        return [], "it is not UTF-8 CSV"
    if not lines:
        return [], "it is empty"
    header = lines[0]
    rows: list[tuple[tuple[str, ...], dict]] = []
    for number, cells in enumerate(lines[1:], start=2):
        damage = row_damage(cells, header)
        if damage is not None:
            return rows, f"line {number}: {damage}"
        rows.append((tuple(cells[:key_count]), dict(zip(header[key_count:], cells[key_count:]))))
    return rows, None


def run_atlas(problem: Problem, study: Atlas, out_dir: Path, sources: Path, quiet: bool, lanes: int,
              workers: Workers) -> dict:
    """Cover the gait manifold at every cell; the answers of each, and over all cells."""
    names = [a.name for a in study.axes]
    keys = [key_column(n) for n in names]
    table = AtlasTable(out_dir / "cells.csv", keys + CELL_COLUMNS, keys, problem.hip_law)
    for note in () if quiet else table.notes:
        _log.warning(f"note: {note}")
    report = run_tasks(split_lanes(sweep_tasks(study), lanes), atlas_worker, (problem, quiet), table, problem.name,
                       quiet=quiet, workers=workers)
    cells = read_points(out_dir / "cells.csv")
    summary = {**run_info(report), "swept": names, "cells": _cell_summaries(cells, names)}
    if report.complete:
        from baslip.viz.atlasmap import atlas_figure  # drawn in this process only (see baslip.studies)
        from baslip.viz.figures import trunk_motion_figure

        charts = read_points(out_dir / "atlas.csv")
        atlas_figure(charts, names, (study.plot[0], study.plot[1]), out_dir, problem_title(problem))
        best = read_points(out_dir / "atlas_best.csv")
        if best:  # none without polishing (polish: 0)
            trunk_motion_figure(best_gait_motions(best, names, problem.params, count=2 * len(cells), note=_meaning,
                                                  law=problem.hip_law),
                                out_dir, problem=problem_title(problem))
        summary.update(_totals(cells, charts), best=[_best_summary(b, names, problem.hip_law) for b in best])
    return summary


def _meaning(row: dict) -> str:
    """A polished gait's label: which best it is."""
    return ", upright throughout" if row["meaning"] == "upright_throughout" else ""


def _best_summary(row: dict, names: list[str], law: HipLaw) -> dict:
    """A polished gait for result.json: its cell, meaning, gait and trunk range [deg]."""
    return {**{n: row[key_column(n)] for n in names}, "meaning": row["meaning"],
            "spectral_radius": row["spectral_radius"], "start_radius": row["start_radius"],
            "residual": row["residual"], **{n: row[n] for n in design_names(law)},
            "trunk_min_deg": math.degrees(row["theta_h_min"]), "trunk_max_deg": math.degrees(row["theta_h_max"]),
            "upright_apex": row["upright_apex"], "upright_throughout": row["upright_throughout"]}


def _cell_summaries(cells: list[dict], names: list[str]) -> list[dict]:
    fields = ("pieces", "seeds", "seeds_failed", "charts", "complete", "boundaries", "corrector_stops", "least_radius", "least_radius_upright_apex",
              "least_radius_upright_throughout", "stable_share", "polished_radius", "polished_upright_throughout_radius",
              "time_s")
    return [{**{n: c[key_column(n)] for n in names}, **{f: _plain(c[f]) for f in fields}} for c in cells]


def _plain(value):
    """A CSV cell as JSON: whole numbers as ints, empty cells as None."""
    if value == "":
        return None
    if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
        return int(value)
    return value


def _totals(cells: list[dict], charts: list[dict]) -> dict:
    verified = [c for c in charts if c["status"] == "converged"]
    best = min(verified, key=lambda c: c["spectral_radius"], default=None)
    upright = [c for c in verified if c["upright_throughout"] is True]
    best_upright = min(upright, key=lambda c: c["spectral_radius"], default=None)
    return {
        "charts": len(charts),
        "not_verified": len(charts) - len(verified),
        "pieces": int(sum(c["pieces"] for c in cells)),
        "all_cells_complete": all(c["complete"] is True for c in cells),
        "least_radius": None if best is None else best["spectral_radius"],
        "least_radius_upright_throughout": None if best_upright is None else best_upright["spectral_radius"],
        "max_residual": max((c["residual"] for c in verified), default=None),
        "upright_at_apex_deg": math.degrees(UPRIGHT_AT_APEX),
        "upright_throughout_deg": math.degrees(UPRIGHT_THROUGHOUT),
    }
