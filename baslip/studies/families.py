"""The ``families`` study: which gaits exist at one cell, and the most stable one.

A problem says its cell by what it fixes (a speed and an apex height, usually); a families
study covers the gaits there with an atlas of that one cell (:mod:`baslip.studies.atlas`,
same files), from seeds that start, where the problem gives no guess, from the body alone
(:mod:`baslip.gait.anybody`), on a short budget (:class:`~baslip.problem.study.Families`).
Its ``result.json`` then answers, under ``answer``:

* ``pieces``: each piece of the covering with its charts, its least spectral radius and
  its share of stable gaits (by chart area);
* ``best``: the most stable gait, polished by the stability descent and verified by the
  independent re-simulation (eps <= 1e-10), and the most stable one upright throughout;
* ``searched``: how wide the claim is: the region (the bounds of every free quantity),
  the seeds and how their gains were drawn, the charts made against the budget, and where
  the covering stopped and why (a bound, the chart limit, a fall);
* ``none_found``: where no gait was found, why: the limits that bind where the problem's
  own solve stopped (foot clearance at the apex, a leg angle, ...), and what to change.

``lines`` tells the same in words, as the command line prints it.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import fields, replace
from pathlib import Path

from baslip.files.rows import read_points
from baslip.gait.from_problem import fixed_point_spec, solve_start
from baslip.model.quantities import design_names, quantity_text
from baslip.problem.reader import Problem
from baslip.problem.study import Atlas, Axis, Families
from baslip.studies.atlas import run_atlas
from baslip.studies.runner import Workers

#: The quantities that name a cell, where the problem fixes them; otherwise the first
#: two design quantities it fixes.
CELL_QUANTITIES = ("ydot", "z")


def cell_axes(problem: Problem) -> tuple[Axis, ...]:
    """The axes of one point each that name ``problem``'s cell: the fixed values of
    :data:`CELL_QUANTITIES`, else of the first two design quantities it fixes."""
    fixed = [n for n in problem.design if n in problem.fix]
    named = [n for n in CELL_QUANTITIES if n in fixed] or fixed[:2]
    return tuple(Axis(n, (problem.fix[n],)) for n in named)


def as_atlas(problem: Problem) -> Problem:
    """``problem`` with its families study as the atlas of its own cell (same budget)."""
    study = problem.study
    assert isinstance(study, Families)
    settings = {f.name: getattr(study, f.name) for f in fields(Atlas) if f.name not in ("axes", "kind", "plot")}
    return replace(problem, study=Atlas(cell_axes(problem), plot=study.plot or _plotted(problem), **settings))


def _plotted(problem: Problem) -> tuple[str, str]:
    """The figure's two quantities: the first two the problem leaves free, the drawn gains first."""
    free = [n for n in (*problem.hip_law.drawn, *problem.design) if n not in problem.fix]
    ordered = list(dict.fromkeys(free))
    return ordered[0], ordered[1]


def run_families(problem: Problem, study: Families, out_dir: Path, sources: Path, quiet: bool, lanes: int,
                 workers: Workers) -> dict:
    """Cover the gaits at ``problem``'s cell; the atlas's summary with the ``answer``."""
    cell = as_atlas(problem)
    assert isinstance(cell.study, Atlas)
    summary = run_atlas(cell, cell.study, out_dir, sources, quiet, lanes, workers)
    if summary["complete"]:
        summary["answer"] = families_answer(problem, out_dir)
    return summary


def families_answer(problem: Problem, out_dir: Path) -> dict:
    """The answer of a finished families study in ``out_dir`` (see the module's text)."""
    charts = read_points(out_dir / "atlas.csv")
    verified = [c for c in charts if c["status"] == "converged"]
    controls = problem.hip_law.controls.names
    answer = {
        "cell": {n: problem.fix[n] for n in problem.design if n in problem.fix},
        "pieces": _pieces(verified),
        "best": [_gait(row, problem) for row in read_points(out_dir / "atlas_best.csv")],
        "searched": _searched(problem, read_points(out_dir / "cells.csv")[0],
                              read_points(out_dir / "atlas_boundary.csv")),
    }
    if not verified:
        answer["none_found"] = _why_none(problem)
    answer["lines"] = _lines(answer, controls)
    return answer


def _pieces(verified: list[dict]) -> list[dict]:
    """Each piece's verified charts: count, least radius, stable share (by area)."""
    pieces = []
    for piece in sorted({int(c["piece"]) for c in verified}):
        mine = [c for c in verified if int(c["piece"]) == piece]
        area = sum(c["area"] for c in mine)
        stable = sum(c["area"] for c in mine if c["stable"] is True)
        pieces.append({"piece": piece, "charts": len(mine),
                       "least_radius": min(c["spectral_radius"] for c in mine),
                       "stable_share": stable / area if area > 0 else None,
                       "upright_apex_share": sum(c["upright_apex"] is True for c in mine) / len(mine)})
    return pieces


def _gait(row: dict, problem: Problem) -> dict:
    """A polished gait of atlas_best.csv: its meaning, gait, radius, eps, trunk range [deg]."""
    return {"meaning": row["meaning"], **{n: row[n] for n in design_names(problem.hip_law)},
            "spectral_radius": row["spectral_radius"], "stable": row["stable"], "residual": row["residual"],
            "trunk_min_deg": math.degrees(row["theta_h_min"]), "trunk_max_deg": math.degrees(row["theta_h_max"])}


def _searched(problem: Problem, cell: dict, boundaries: list[dict]) -> dict:
    """How wide the search was: region, seeds, charts against the budget, where it stopped."""
    study = problem.study
    assert isinstance(study, Families)
    spec = fixed_point_spec(problem)
    free = [n for n in spec.design if n not in spec.fixed]
    # A reason's numbers (the angle the tangent turned, ...) differ from chart to chart.
    stops = Counter(re.sub(r"-?\d+(\.\d+)?(e-?\d+)?", "#", b["reason"]) for b in boundaries)
    return {
        "region": {n: list(spec.bounds_of(n)) for n in free},
        "posture": problem.posture,
        "seeds": study.seeds, "seed": study.seed, "seeds_failed": int(cell["seeds_failed"]),
        "drawn": [n for n in problem.hip_law.drawn if n not in spec.fixed],
        "charts": int(cell["charts"]), "max_charts": study.max_charts,
        "covered_whole": cell["complete"] is True and int(cell["charts"]) > 0,
        "stopped": dict(stops.most_common()),
    }


def _why_none(problem: Problem) -> dict:
    """Why the cell has no gait: the problem's own solve (from the body alone where it has
    no guess), its message and the limits that bind where it stopped."""
    result = solve_start(replace(problem, study=None))
    diagnosis = result.diagnosis.to_json_dict() if result.diagnosis is not None else None
    return {"status": str(result.status), "message": result.message, "diagnosis": diagnosis}


def _distinct(best: list[dict]) -> list[dict]:
    """The polished gaits, the one upright throughout left out where it is the best of all."""
    if len(best) == 2 and best[0]["spectral_radius"] == best[1]["spectral_radius"]:
        return best[:1]
    return best


def _lines(answer: dict, controls: tuple[str, ...]) -> list[str]:
    """The answer in words: what was found (or why nothing was), then how wide the search was."""
    cell = ", ".join(quantity_text(n, v, 6) for n, v in answer["cell"].items())
    found = _none_lines(cell, answer["none_found"]) if "none_found" in answer else _found_lines(cell, answer, controls)
    return [*found, f"  {_width_line(answer['searched'])}"]


def _width_line(searched: dict) -> str:
    """How wide the search was, in one line."""
    drawn = f"then gains {', '.join(searched['drawn'])} drawn over their bounds" if searched["drawn"] else "no gains drawn"
    line = (f"searched: {searched['seeds']} seeds (the problem's own start, {drawn}; {searched['seeds_failed']} "
            f"failed), {searched['charts']} charts of at most {searched['max_charts']}")
    if searched["charts"]:
        line += ((", the pieces covered whole" if searched["covered_whole"] else ", not covered whole")
                 + "; stopped at: " + ", ".join(f"{reason} ({count})" for reason, count in searched["stopped"].items()))
    return line


def _none_lines(cell: str, why: dict) -> list[str]:
    """No gait found: the solve's message, the limits that bind and what to change."""
    lines = [f"at {cell}: no gait found ({why['message']})"]
    if why["diagnosis"] is not None:
        binding = why["diagnosis"]["binding"] or why["diagnosis"]["near"]
        if binding:
            lines.append("  bounded by: " + "; ".join(limit["name"] for limit in binding))
        lines += [f"  suggest: {text}" for text in why["diagnosis"]["suggestions"]]
    return lines


def _found_lines(cell: str, answer: dict, controls: tuple[str, ...]) -> list[str]:
    """The pieces and the polished gaits."""
    pieces, best = answer["pieces"], _distinct(answer["best"])
    lines = [f"at {cell}: {len(pieces)} piece{'s' * (len(pieces) != 1)} of gaits"]
    for piece in pieces:
        share = "" if piece["stable_share"] is None else f", stable share {piece['stable_share']:.1%}"
        lines.append(f"  piece {piece['piece']}: {piece['charts']} charts, least spectral radius "
                     f"{piece['least_radius']:.4g}{share}")
    for gait in best:
        what = "most stable" if gait["meaning"] == "any" else "most stable upright throughout"
        if len(answer["best"]) > len(best):
            what = "most stable (upright throughout)"
        values = ", ".join(quantity_text(n, gait[n], 5) for n in controls)
        lines.append(f"  {what}: spectral radius {gait['spectral_radius']:.4g} "
                     f"({'stable' if gait['stable'] else 'unstable'}), eps {gait['residual']:.1e}, {values}, trunk "
                     f"{gait['trunk_min_deg']:.1f} to {gait['trunk_max_deg']:.1f} deg")
    return lines
