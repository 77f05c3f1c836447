"""The report's answer from the atlases: the whole family of upright gaits, covered."""

from __future__ import annotations

import math
import re

from baslip.report.evidence import Evidence, claim

#: The atlas studies the report reads, most cells first.
ATLASES = ("atlas_upright", "atlas_upright_cell")
#: The atlas of the hanging family, the comparison.
HANGING = "atlas_downward"
#: The upright atlas grown from no gait above a spectral radius, so that cells can be
#: covered whole up to it.
CAPPED_ATLAS = "atlas_upright_capped"
#: The stability NLP's runs, the cross-check: from drawn starts over the upright grid, and
#: from the upright atlas's polished gaits (``examples/schur_from_atlas.py``).
SCHUR_STUDY = "optimal_upright_schur"
SCHUR_FROM_ATLAS = "schur_from_atlas"
#: Relative difference of two radii below which the report calls them the same.
SAME_RADIUS = 0.01


def atlas_claims(ev: Evidence) -> list[str]:
    """The claim of the first atlas of upright gaits that has finished (with the hanging
    family's atlas for comparison, if it has finished), or nothing."""
    hanging = _finished(ev.summary(HANGING))
    for name in ATLASES:
        summary = _finished(ev.summary(name))
        if summary is not None:
            return [_claim(name, summary, hanging, ev.summary(CAPPED_ATLAS))]
    return []


def crosscheck_claims(ev: Evidence) -> list[str]:
    """The stability NLP against the upright atlas, if both have run."""
    study, atlas = ev.summary(SCHUR_STUDY), _finished(ev.summary(ATLASES[0]))
    if not study or not study.get("complete", True) or atlas is None:
        return []
    rows = ev.rows(SCHUR_STUDY, "points.csv")
    atlas_least = {(c["ydot"], c["z"]): _least([c], "least_radius_upright_apex", "polished_radius") for c in atlas["cells"]}
    nlp_least = {(p["ydot"], p["z"]): p["spectral_radius"] for p in study["least_per_point"]}
    per_cell = "; ".join(f"({ydot:g}, {z:g}): {_value(nlp_least.get((ydot, z)))} against {_value(radius)}"
                         for (ydot, z), radius in sorted(atlas_least.items()))
    below = [cell for cell, radius in nlp_least.items()
             if (least := atlas_least.get(cell)) is not None and radius < least * (1 - SAME_RADIUS)]
    started = sum(1 for r in rows if r["start_status"] == "converged")
    solved = sum(1 for r in rows if "Solve_Succeeded" in str(r["descent_stop"]) or "Acceptable" in str(r["descent_stop"]))
    verified = [r for r in rows if r["status"] == "converged" and "its bound" in str(r["descent_stop"])]
    gaps = [abs(_bound(r) - r["spectral_radius"]) / r["spectral_radius"] for r in verified]
    bounds = study["provenance"]["problem"]["bounds"]
    throughout, throughout_below = _throughout(rows, [atlas, _finished(ev.summary(CAPPED_ATLAS))])
    ours = (f"`{SCHUR_STUDY}` runs the stride NLP that bounds every multiplier by a complex Schur form of the shot "
            f"stride's dr/dX and minimises the bound (arXiv 2312.10647), from {study['starts']} starts per cell with Kp "
            f"and Kd drawn where its RK4 intervals are accurate, inside Kp in [{bounds['Kp'][0]:g}, {bounds['Kp'][1]:g}] "
            f"N m/rad and Kd in [{bounds['Kd'][0]:g}, {bounds['Kd'][1]:g}] N m s/rad: {len(rows)} starts, {started} "
            f"starting fixed points, {solved} NLP runs converged, {len(verified)} ends verified (the NLP's own bound "
            f"within {max(gaps, default=0):.1%} of the verified radius). Least verified radius per cell, NLP against "
            f"the atlas (upright at the apex): {per_cell}." + throughout + _from_atlas(ev.summary(SCHUR_FROM_ATLAS)))
    verdict = ("differs from the atlas for gaits upright at the apex: the NLP found a more stable one at "
               + ", ".join(f"{c}" for c in below) if below else
               "agrees with the atlas for gaits upright at the apex: from its starts the NLP found none more stable "
               "than the atlas's in any cell") + throughout_below
    return [claim(
        "Under constant PD, by the stability NLP (cross-check of the atlas)",
        "every upright fixed point found was unstable under the constant PD hip law (sec. 4.4.3.1, 4.7).",
        ours, verdict,
        "The NLP is local: IPOPT goes from each start to a nearby minimum of its bound. Its starts are solved from "
        f"the problem's guess, and its verified ends spin the trunk at most {math.degrees(_spin(verified)):.3g} deg/s at the apex. The "
        f"atlas's most stable gait spins it at {math.degrees(_spin(_best_gaits(atlas.get('best', []))[:1])):.3g} deg/s, swinging it "
        "through most of a turn over the stride, on a part of the family no drawn start reached; the runs from the "
        "atlas's own gaits test the NLP there. Where the NLP's bound and the verified radius differ by a few per "
        "cent, the minimum it found is a point where several multipliers coincide (in an earlier cross-check, at "
        "two upright-throughout ends three of the four, 1.5286 and 1.4395): an error e in the matrix moves a k-fold "
        "multiplier by about e^(1/k), so the RK4 orbit's error of about 1e-6 (the polish moved those ends by 1.5e-6 and 9e-7) splits "
        "them by about 1e-2. The Schur form is degenerate there too, which is where IPOPT's quasi-Newton iterations "
        "stall; such runs count as failures. So every end is polished and verified on the compiled map, and the "
        "verified radius is the one compared.",
        [f"{SCHUR_STUDY}/spectral_radius_map.png"],
    )]


def _throughout(rows: list[dict], atlases: list[dict | None]) -> tuple[str, str]:
    """The cross-check for gaits upright throughout the stride: (the sentence that sets the
    NLP's least verified radius per cell beside the least of ``atlases``' charts and
    polished gaits, the verdict's clause naming the cells where the NLP's is lower)."""
    atlas_least: dict[tuple, float] = {}
    for summary in filter(None, atlases):
        for cell in summary["cells"]:
            least = _least([cell], "least_radius_upright_throughout", "polished_upright_throughout_radius")
            if least is not None:
                key = (cell["ydot"], cell["z"])
                atlas_least[key] = min(least, atlas_least.get(key, math.inf))
    nlp_least: dict[tuple, float] = {}
    for row in rows:
        if row["status"] == "converged" and row.get("upright_throughout") is True:
            key = (row["sweep_ydot"], row["sweep_z"])
            nlp_least[key] = min(row["spectral_radius"], nlp_least.get(key, math.inf))
    if not nlp_least:
        return "", ""
    names = " and ".join(f"`{s['name']}`" for s in filter(None, atlases))
    per_cell = "; ".join(f"({ydot:g}, {z:g}): {_value(radius)} against {_value(atlas_least.get((ydot, z)))}"
                         for (ydot, z), radius in sorted(nlp_least.items()))
    below = [(cell, radius) for cell, radius in sorted(nlp_least.items())
             if radius < atlas_least.get(cell, math.inf) * (1 - SAME_RADIUS)]
    sentence = (f" Upright throughout the stride, the NLP's least verified radius per cell against the least of "
                f"{names} (charts and polished gaits): {per_cell}.")
    if not below:
        return sentence, ""
    overall = min(atlas_least.values(), default=math.inf)
    listed = ", ".join(f"({ydot:g}, {z:g}): {radius:.3g} against {_value(atlas_least.get((ydot, z)))}"
                       for (ydot, z), radius in below)
    least = min(radius for _, radius in below)
    if least < 1:
        outcome = f"among them a stable gait that the atlases missed, radius {least:.4g}"
    elif least >= overall:
        outcome = f"none stable, and none below the atlases' least over all cells, {overall:.4g}"
    else:
        outcome = f"none stable, the least {least:.4g}, below the atlases' least over all cells, {overall:.4g}"
    return sentence, (f"; upright throughout the stride it found more stable gaits than the atlases in {len(below)} of "
                      f"{len(nlp_least)} cells ({listed}): {outcome}")


def _spin(rows: list[dict]) -> float:
    """The largest |theta_h_dot| at the apex [rad/s] of ``rows`` (nan for none)."""
    return max((abs(r["theta_h_dot"]) for r in rows), default=math.nan)


def _bound(row: dict) -> float:
    """The stability NLP's own bound, from its note in ``descent_stop``."""
    found = re.search(r"its bound ([-+0-9.eE]+)", str(row["descent_stop"]))
    return float(found.group(1)) if found else math.nan


def _from_atlas(summary: dict | None) -> str:
    if not summary or not summary.get("rows"):
        return ""
    rows = summary["rows"]
    verified = [r for r in rows if r["verified"]]
    same = [r for r in verified if abs(r["verified_radius"] - r["atlas_radius"]) <= SAME_RADIUS * r["atlas_radius"]]
    lower = [r for r in verified if r["verified_radius"] < r["atlas_radius"] * (1 - SAME_RADIUS)]
    higher = [r for r in verified if r["verified_radius"] > r["atlas_radius"] * (1 + SAME_RADIUS)]
    newly = [r for r in lower if r["verified_radius"] < 1 <= r["atlas_radius"]]
    stable = "".join(f" It found a stable gait the atlas's polish missed at ({r['ydot']:g} m/s, {r['z']:g} m): radius "
                     f"{r['verified_radius']:.4g} against {r['atlas_radius']:.4g}." for r in newly)
    listed = "; ".join(f"({r['ydot']:g}, {r['z']:g}) {r['meaning'].replace('_', ' ')}: {r['atlas_radius']:.4g} -> "
                       + (f"{r['verified_radius']:.4g}" if r["verified"] else r["nlp_status"]) for r in rows)
    return (f" Started from the {len(rows)} polished gaits of `{summary['source']}` (`{SCHUR_FROM_ATLAS}`), the NLP's "
            f"end was verified for {len(verified)}: {len(same)} at the atlas's radius (within {SAME_RADIUS:.0%}), "
            f"{len(lower)} lower, {len(higher)} higher; atlas -> NLP: {listed}.{stable}")


def _finished(summary: dict | None) -> dict | None:
    """``summary`` if it is of a finished atlas with cells, else None."""
    return summary if summary and summary.get("complete") and summary.get("cells") else None


def _claim(name: str, summary: dict, hanging: dict | None, capped: dict | None) -> str:
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
    if _finished(capped) is not None:
        figures.append(f"{CAPPED_ATLAS}/atlas.png")
    if hanging is not None:
        figures.append(f"{HANGING}/atlas.png")
    return claim(
        "Under constant PD, over the whole family of gaits (atlas)",
        "every upright fixed point found was unstable under the constant PD hip law (sec. 4.4.3.1, 4.7).",
        f"`{name}` covers the manifold of fixed points (theta2_dot_des pinned, so a 2-D family per cell) with charts, "
        f"grown from {study['seeds']} independent solves per cell, within the bounds theta_h in "
        f"[{math.degrees(bounds['theta_h'][0]):.0f}, {math.degrees(bounds['theta_h'][1]):.0f}] deg, "
        f"Kp in [{bounds['Kp'][0]:g}, {bounds['Kp'][1]:g}] N m/rad, Kd in [{bounds['Kd'][0]:g}, {bounds['Kd'][1]:g}] "
        f"N m s/rad; every chart verified by the independent re-simulation, and the {study.get('polish', 3)} least local "
        f"minima of the radius on each cell's chart graph polished by the stability descent (each end verified too). "
        f"Least radius, upright at the apex: "
        f"{_value(apex)}; upright throughout: {_value(throughout)}. {gaits} Per cell: {per_cell}."
        + _capped(capped, cells) + _hanging_map(hanging),
        _verdict(apex, throughout, all(c["complete"] for c in cells)),
        "The answer is only as wide as the covering: within the bounds, for the pieces the seeds reached, and, "
        "where a cell is not covered whole (chart limit or corrector stops, said above), for the part covered. "
        + _cap_caveat(_finished(capped)) +
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
            f"{math.degrees(row['theta_h_dot']):.1f} deg/s at the apex, Kp = {row['Kp']:.3g} N m/rad, Kd = {row['Kd']:.3g} N m s/rad, "
            f"theta2_des = {math.degrees(row['theta2_des']):.1f} deg, theta_td = {math.degrees(row['theta_td']):.1f} deg; "
            f"the trunk between {row['trunk_min_deg']:.0f} and {row['trunk_max_deg']:.0f} deg over the stride; "
            f"independent eps {row['residual']:.1e}.")


def capped_whole(ev: Evidence) -> str:
    """", and K of them covered whole up to spectral radius R by the capped atlas" ("" if
    it has not finished)."""
    summary = _finished(ev.summary(CAPPED_ATLAS))
    if summary is None:
        return ""
    whole = sum(1 for c in summary["cells"] if c["complete"] is True)
    return f"; {whole} of them {covered_whole(summary['provenance']['problem']['study'])} by `{CAPPED_ATLAS}`"


def _capped(summary: dict | None, uncapped: list[dict]) -> str:
    """What the capped covering adds: its cells covered whole up to its cap, its least
    radii, and the cells where the uncapped covering reached lower."""
    summary = _finished(summary)
    if summary is None:
        return ""
    study, cells = summary["provenance"]["problem"]["study"], summary["cells"]
    cap = study["max_spectral_radius"]
    whole = [f"({c['ydot']:g}, {c['z']:g})" for c in cells if c["complete"] is True]
    stops = sum(c["corrector_stops"] for c in cells)
    limited = sum(1 for c in cells if c["charts"] >= study["max_charts"])
    others = f"corrector stops at {stops} edges in all" + (f", the chart limit in {limited} cells" if limited else "")
    before = {(c["ydot"], c["z"]): _least([c], "least_radius_upright_apex", "polished_radius") for c in uncapped}
    short = []
    for c in cells:
        least, uncapped_least = _least([c], "least_radius_upright_apex", "polished_radius"), before.get((c["ydot"], c["z"]))
        if least is not None and uncapped_least is not None and least > uncapped_least * (1 + SAME_RADIUS):
            short.append(f"({c['ydot']:g}, {c['z']:g}): {_value(least)} against {_value(uncapped_least)}")
    throughout = _least(cells, "least_radius_upright_throughout", "polished_upright_throughout_radius")
    return (f" `{CAPPED_ATLAS}` grows the same cells from the same seeds, but from no gait more unstable than spectral "
            f"radius {cap:g} (at most {study['max_charts']} charts a cell): {summary['charts']} charts, "
            f"{summary['not_verified']} not confirmed by the independent check; {len(whole)} of the {len(cells)} cells "
            f"covered whole up to {cap:g} ({', '.join(whole) or 'none'}); elsewhere {others}. Least radius, upright at "
            f"the apex: "
            f"{_value(_least(cells, 'least_radius_upright_apex', 'polished_radius'))}; upright throughout: "
            f"{_value(throughout)}."
            + (f" Where its seeds' pieces reach the uncapped covering's lower gaits only through gaits above {cap:g}, "
               f"its least is higher: {'; '.join(short)}." if short else ""))


def _hanging_map(hanging: dict | None) -> str:
    if hanging is None:
        return ""
    cells = "; ".join(f"({c['ydot']:g}, {c['z']:g}): least radius {_value(_least([c], 'least_radius', 'polished_radius'))}, "
                      f"stable share {_share(c['stable_share'])}, {c['charts']} charts, {c['pieces']} piece(s)"
                      + ("" if c["complete"] else ", not covered whole") for c in hanging["cells"])
    return f" For comparison, the hanging family (`{HANGING}`, the same bounds but theta_h within 30 deg of hanging): {cells}."


def covered_whole(study: dict) -> str:
    """"covered whole", and up to which spectral radius if the study's covering stops at
    one (``max_spectral_radius``)."""
    cap = study.get("max_spectral_radius")
    return "covered whole" if cap is None else f"covered whole up to spectral radius {cap:g}"


def _cap_caveat(capped: dict | None) -> str:
    """What a cell covered whole by the capped atlas holds, and what it can miss."""
    if capped is None:
        return ""
    cap = capped["provenance"]["problem"]["study"]["max_spectral_radius"]
    return (f"`{CAPPED_ATLAS}` grows from no gait more unstable than spectral radius {cap:g}: a cell covered whole holds every "
            f"gait its seeds' pieces reach through gaits of radius up to {cap:g}, and a stable island ringed by gaits "
            f"more unstable than that would be found only by a seed landing on it. ")


def _whole(cell: dict, study: dict) -> str:
    """Why a cell is not covered whole ("" if it is)."""
    if cell["complete"]:
        cap = study.get("max_spectral_radius")
        edges = "a bound, a fall or a singular chart" + ("" if cap is None else f", or a gait of radius above {cap:g}")
        return f" ({covered_whole(study)}: every edge {edges})"
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
