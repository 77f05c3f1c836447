"""The report's answer from the atlases: the whole family of upright gaits, covered."""

from __future__ import annotations

import math

from baslip.report.evidence import Evidence, claim

#: The atlas studies the report reads, most cells first.
ATLASES = ("atlas_upright", "atlas_upright_cell")


def atlas_claims(ev: Evidence) -> list[str]:
    """The claim of the first atlas of upright gaits that has finished, or nothing."""
    for name in ATLASES:
        summary = ev.summary(name)
        if summary and summary.get("complete") and summary.get("cells"):
            return [_claim(name, summary)]
    return []


def _claim(name: str, summary: dict) -> str:
    cells = summary["cells"]
    problem = summary["provenance"]["problem"]
    bounds, study = problem["bounds"], problem["study"]
    apex = [c["least_radius_upright_apex"] for c in cells if c["least_radius_upright_apex"] is not None]
    polished = [c["polished_radius"] for c in cells if c["polished_radius"] is not None]
    best_apex = min(apex) if apex else None
    per_cell = "; ".join(
        f"({c['ydot']:g} m/s, {c['z']:g} m): {c['pieces']} piece(s) from {c['seeds']} seeds ({c['seeds_failed']} failed), "
        f"{c['charts']} charts{_whole(c, study)}, least radius "
        f"{_value(c['least_radius_upright_apex'])} upright at the apex, {_value(c['least_radius_upright_throughout'])} "
        f"upright throughout, {_descended(c['polished_radius'])}, stable share {_share(c['stable_share'])}"
        for c in cells)
    stable = best_apex is not None and (min(polished + [best_apex]) < 1)
    return claim(
        "Under constant PD, over the whole family of gaits (atlas)",
        "every upright fixed point found was unstable under the constant PD hip law (sec. 4.4.3.1, 4.7).",
        f"`{name}` covers the manifold of fixed points (theta2_dot_des pinned, so a 2-D family per cell) with charts, "
        f"grown from {study['seeds']} independent solves per cell, within the bounds theta_h in "
        f"[{math.degrees(bounds['theta_h'][0]):.0f}, {math.degrees(bounds['theta_h'][1]):.0f}] deg, "
        f"Kp in [{bounds['Kp'][0]:g}, {bounds['Kp'][1]:g}] N m/rad, Kd in [{bounds['Kd'][0]:g}, {bounds['Kd'][1]:g}] "
        f"N m s/rad; every chart verified by the independent re-simulation. Per cell: {per_cell}.",
        _verdict(stable, all(c["complete"] for c in cells)),
        "The answer is only as wide as the covering: within the bounds, for the pieces the seeds reached, and for "
        "cells covered whole (a cell that reached its chart limit says so above). Upright at the apex: "
        "|theta_h - 90 deg| <= 30 deg; upright throughout: within 45 deg of vertical at every instant.",
        [f"{name}/atlas.png"],
    )


def _whole(cell: dict, study: dict) -> str:
    """Why a cell is not covered whole ("" if it is)."""
    if cell["complete"]:
        return " (covered whole: every edge a bound, a fall or a singular chart)"
    why = []
    if cell.get("corrector_stops"):
        why.append(f"the corrector gave up at {cell['corrector_stops']} of {cell['boundaries']} edges")
    if cell["charts"] >= study.get("max_charts", float("inf")):
        why.append("the chart limit was reached")
    return f" (not covered whole: {' and '.join(why) or 'see atlas_boundary.csv'})"


def _verdict(stable: bool, complete: bool) -> str:
    if stable:
        return "differs: a stable upright gait exists"
    if not complete:
        return "open: not covered whole; no stable upright gait in the part covered"
    return "agreed within the covering"


def _descended(radius) -> str:
    return "no verified end of the descent from the best chart" if radius is None else f"{radius:.3g} after the descent"


def _value(radius) -> str:
    return "none" if radius is None else f"{radius:.3g}"


def _share(share) -> str:
    return "n/a" if share is None else f"{share:.1%}"
