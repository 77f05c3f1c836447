"""The report's answer from the atlases: the whole family of upright gaits, covered."""

from __future__ import annotations

import math

from baslip.report.evidence import Evidence, claim

#: The atlas studies the report reads, most cells first.
ATLASES = ("atlas_upright", "atlas_upright_cell")
#: The atlas of the hanging family, the comparison.
HANGING = "atlas_downward"


def atlas_claims(ev: Evidence) -> list[str]:
    """The claim of the first atlas of upright gaits that has finished (with the hanging
    family's atlas for comparison, if it has finished), or nothing."""
    hanging = _finished(ev.summary(HANGING))
    for name in ATLASES:
        summary = _finished(ev.summary(name))
        if summary is not None:
            return [_claim(name, summary, hanging)]
    return []


def _finished(summary: dict | None) -> dict | None:
    """``summary`` if it is of a finished atlas with cells, else None."""
    return summary if summary and summary.get("complete") and summary.get("cells") else None


def _claim(name: str, summary: dict, hanging: dict | None) -> str:
    cells = summary["cells"]
    problem = summary["provenance"]["problem"]
    bounds, study = problem["bounds"], problem["study"]
    apex = _least(cells, "least_radius_upright_apex", "polished_radius")
    throughout = _least(cells, "least_radius_upright_throughout", "polished_upright_throughout_radius")
    per_cell = "; ".join(
        f"({c['ydot']:g} m/s, {c['z']:g} m): {c['pieces']} piece(s) from {c['seeds']} seeds ({c['seeds_failed']} failed), "
        f"{c['charts']} charts{_whole(c, study)}, least radius "
        f"{_value(c['least_radius_upright_apex'])} upright at the apex ({_descended(c['polished_radius'])}), "
        f"{_value(c['least_radius_upright_throughout'])} upright throughout "
        f"({_descended(c['polished_upright_throughout_radius'])}), stable share {_share(c['stable_share'])}"
        for c in cells)
    gaits = " ".join(_gait(b) for b in _best_gaits(summary.get("best", [])))
    figures = [f"{name}/atlas.png"] + ([f"{name}/best_gaits_trunk.png"] if summary.get("best") else [])
    if hanging is not None:
        figures.append(f"{HANGING}/atlas.png")
    return claim(
        "Under constant PD, over the whole family of gaits (atlas)",
        "every upright fixed point found was unstable under the constant PD hip law (sec. 4.4.3.1, 4.7).",
        f"`{name}` covers the manifold of fixed points (theta2_dot_des pinned, so a 2-D family per cell) with charts, "
        f"grown from {study['seeds']} independent solves per cell, within the bounds theta_h in "
        f"[{math.degrees(bounds['theta_h'][0]):.0f}, {math.degrees(bounds['theta_h'][1]):.0f}] deg, "
        f"Kp in [{bounds['Kp'][0]:g}, {bounds['Kp'][1]:g}] N m/rad, Kd in [{bounds['Kd'][0]:g}, {bounds['Kd'][1]:g}] "
        f"N m s/rad; every chart verified by the independent re-simulation, and the least-radius charts of each cell "
        f"polished by the stability descent (its end verified too). Least radius, upright at the apex: "
        f"{_value(apex)}; upright throughout: {_value(throughout)}. {gaits} Per cell: {per_cell}."
        + _hanging_map(hanging),
        _verdict(apex, throughout, all(c["complete"] for c in cells)),
        "The answer is only as wide as the covering: within the bounds, for the pieces the seeds reached, and, "
        "where a cell is not covered whole (chart limit or corrector stops, said above), for the part covered. "
        "A stable gait found is a fact whatever the covering; its absence is only as wide as the covering. Upright at "
        "the apex: |theta_h - 90 deg| <= 30 deg; upright throughout: within 45 deg of vertical at every instant.",
        figures,
    )


def _least(cells: list[dict], *columns: str) -> float | None:
    """The least of ``columns`` over ``cells`` (None where none has a value)."""
    values = [c[column] for c in cells for column in columns if c.get(column) is not None]
    return min(values) if values else None


def _best_gaits(best: list[dict]) -> list[dict]:
    """The most stable polished gait of each meaning."""
    chosen: dict[str, dict] = {}
    for row in sorted(best, key=lambda b: b["spectral_radius"]):
        chosen.setdefault(row["meaning"], row)
    return list(chosen.values())


def _gait(row: dict) -> str:
    what = "upright throughout" if row["meaning"] == "upright_throughout" else "least radius of all"
    return (f"The polished gait of {what}: radius {row['spectral_radius']:.3f} at ydot = {row['ydot']:g} m/s, "
            f"z = {row['z']:g} m, theta_h = {math.degrees(row['theta_h']):.1f} deg and theta_h_dot = "
            f"{row['theta_h_dot']:.2f} rad/s at the apex, Kp = {row['Kp']:.3g} N m/rad, Kd = {row['Kd']:.3g} N m s/rad, "
            f"theta2_des = {math.degrees(row['theta2_des']):.1f} deg, theta_td = {math.degrees(row['theta_td']):.1f} deg; "
            f"the trunk between {row['trunk_min_deg']:.0f} and {row['trunk_max_deg']:.0f} deg over the stride; "
            f"independent eps {row['residual']:.1e}.")


def _hanging_map(hanging: dict | None) -> str:
    if hanging is None:
        return ""
    cells = "; ".join(f"({c['ydot']:g}, {c['z']:g}): least radius {_value(_least([c], 'least_radius', 'polished_radius'))}, "
                      f"stable share {_share(c['stable_share'])}, {c['charts']} charts, {c['pieces']} piece(s)"
                      + ("" if c["complete"] else ", not covered whole") for c in hanging["cells"])
    return f" For comparison, the hanging family (`{HANGING}`, the same bounds but theta_h within 30 deg of hanging): {cells}."


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


def _verdict(apex: float | None, throughout: float | None, complete: bool) -> str:
    if apex is not None and apex < 1:
        upright = ("it is upright throughout as well" if throughout is not None and throughout < 1
                   else "none was found upright throughout the stride")
        return f"differs: a stable gait upright at the apex exists; {upright}"
    if not complete:
        return "open: not covered whole; no stable upright gait in the part covered"
    return "agreed within the covering"


def _descended(radius) -> str:
    return "no verified descent" if radius is None else f"{radius:.3g} polished"


def _value(radius) -> str:
    return "none" if radius is None else f"{radius:.3g}"


def _share(share) -> str:
    if share is None:
        return "n/a"
    return "below 0.1%" if 0 < share < 0.001 else f"{share:.1%}"
