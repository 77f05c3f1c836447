"""The report's answer under the virtual-pivot-point hip law: where constant VPP gives
stable upright running, from the committed sweeps and the branch in r_vpp, and over the
whole family of gaits at each speed from the VPP atlases."""

from __future__ import annotations

import math

from baslip.model.dynamics import Params
from baslip.model.hiplaw import VPP
from baslip.report.evidence import DEG, Evidence, claim, converged

#: The VPP sweeps the report reads, and how it describes each.
VPP_SWEEPS = {
    "vpp_sweep_thesis": "thesis scale, z = 0.4 m",
    "vpp_sweep_thesis_low": "thesis scale, z = 0.25 m",
    "vpp_sweep_human": "human scale, z = 1.1 m",
    "vpp_sweep_human_height": "human scale, 5 m/s",
}


#: The VPP atlases the report reads, and how it describes each.
VPP_ATLASES = {"atlas_vpp": "thesis scale", "atlas_vpp_human": "human scale"}


def vpp_claims(ev: Evidence) -> list[str]:
    """The sweeps' claim (:func:`sweep_claims`), the atlases' (:func:`atlas_claims`) and the
    stability-optimal search's (:func:`optimal_claims`)."""
    return sweep_claims(ev) + atlas_claims(ev) + optimal_claims(ev)


def sweep_claims(ev: Evidence) -> list[str]:
    """One claim: the stable part of each VPP sweep (pivot off the CoM), the best gait
    re-simulated independently, and the branch's loss of stability."""
    found = {name: ev.points(name) for name in VPP_SWEEPS}
    found = {name: rows for name, rows in found.items() if rows}
    if not found:
        return []
    lines, best = [], None
    for name, rows in found.items():
        off_com = [r for r in converged(rows) if r["r_vpp"] > 0]
        stable = [r for r in off_com if r["stable"] is True]
        least = min(off_com, key=lambda r: r["spectral_radius"])
        lines.append(f"| {VPP_SWEEPS[name]} | {len(rows)} | {len(converged(rows))} | {len(stable)} | "
                     + (_span(stable) if stable else "-") + f" | {least['spectral_radius']:.3f} |")
        if stable and (best is None or least["spectral_radius"] < best[1]["spectral_radius"]):
            best = (name, least)
    table = ("| sweep | gaits | verified | stable, r_vpp > 0 | where | least radius, r_vpp > 0 |\n"
             "|---|---|---|---|---|---|\n" + "\n".join(lines) + "\n\n")
    evidence = ""
    if best is not None:
        name, row = best
        summary = ev.summary(name)
        params = Params(**summary["provenance"]["problem"]["params"]) if summary else Params()
        evidence = (f" The most stable: radius {row['spectral_radius']:.3f} at ydot = {row['ydot']:g} m/s, z = "
                    f"{row['z']:g} m, r_vpp = {row['r_vpp']:g} m, theta_td = {row['theta_td'] * DEG:.2f} deg "
                    f"({VPP_SWEEPS[name]}); independent re-simulation eps = {ev.resimulate(row, VPP, params):.1e} "
                    f"(erk, 1e-13).")
    return [claim(
        "Under constant VPP: yes, in a band of speed and pivot height",
        "not studied (the thesis knows the PD law only).",
        "gaits under the virtual-pivot-point law, each nearest its guess (the symmetric gait, upright at the apex), "
        "over the pivot's height above the CoM r_vpp and the speed or apex height:\n\n" + table + evidence
        + _branch_text(ev),
        "goes further",
        "The stable band needs a low apex (1.1 to 1.25 leg lengths), a Froude number ydot / sqrt(g rho0) of about "
        "1.4 or more, and the pivot a little above the CoM; the margins are thin (radii 0.93 to 0.99). A pivot below "
        "the CoM is unstable everywhere swept. Gaits with r_vpp = 0 are left out: the trunk spin is then neutral. "
        "Each sweep holds the touchdown angle constant and picks one gait per point: the claim is as wide as these "
        "grids.",
        [f"{name}/spectral_radius_map.png" for name in found],
    )]


def _tilt(summary: dict) -> float:
    """The trunk's largest angle from vertical [deg] over the least gaits of an optimal study."""
    return max(abs(angle - 90.0) for cell in summary["least_per_point"] for angle in cell["trunk_range_deg"])


def _span(rows: list[dict]) -> str:
    """The ranges of ydot, z and r_vpp over ``rows``, those that vary."""
    parts = []
    for name, unit in (("ydot", "m/s"), ("z", "m"), ("r_vpp", "m")):
        lo, hi = min(r[name] for r in rows), max(r[name] for r in rows)
        parts.append(f"{name} {lo:g} to {hi:g} {unit}" if hi > lo else f"{name} {lo:g} {unit}")
    return ", ".join(parts)


def _branch_text(ev: Evidence) -> str:
    summary = ev.summary("continuation_vpp_pivot")
    if summary is None:
        return ""
    points = summary["special_points"]
    special = ", ".join(f"{p['type'].replace('_', ' ')} at r_vpp = {p['r_vpp']:.4g} m" for p in points)
    at_com = any(p["type"] == "branch_point" and abs(p["r_vpp"]) < 1e-6 for p in points)
    return (f" The branch in r_vpp of the human-scale gait at 5 m/s (continuation_vpp_pivot, {summary['points']} "
            f"verified points over [{summary['range'][0]:g}, {summary['range'][1]:g}] m): {special}"
            + ("; the branch point at r_vpp = 0 is where the trunk-spin pair becomes 1 by structure." if at_com else ".")
            + _curve_text(ev))


def _curve_text(ev: Evidence) -> str:
    """Where the period-doubling curve of curve_vpp_pivot bounds stable gaits, and its
    codimension-two points."""
    summary = ev.summary("curve_vpp_pivot")
    rows = [r for r in ev.rows("curve_vpp_pivot", "curve.csv") if r["type"] == "period_doubling"]
    if summary is None or not rows:
        return ""
    bounding = [r for r in rows if r["stability_boundary"] is True]
    lo, hi = summary["curves"]["second_range"]
    points = "; ".join(f"{p['type'].replace('_', '-')} at r_vpp = {p['r_vpp']:.4g} m, ydot = {p['ydot']:.4g} m/s"
                       for p in summary["curves"]["codimension_two_points"]) or "no codimension-two point"
    where = (f"it bounds stable gaits for ydot {min(r['ydot'] for r in bounding):.4g} to "
             f"{max(r['ydot'] for r in bounding):.4g} m/s (r_vpp {min(r['r_vpp'] for r in bounding):.4g} to "
             f"{max(r['r_vpp'] for r in bounding):.4g} m)" if bounding else "it bounds no stable gaits")
    return (f" Its period doubling followed in (r_vpp, ydot) over {lo:g} to {hi:g} m/s (curve_vpp_pivot, {len(rows)} "
            f"verified points, the symmetry multiplier deflated): {where}; {points}." + _fold_text(ev, summary))


def _fold_text(ev: Evidence, period_doubling: dict) -> str:
    """Where the fold curve of curve_vpp_fold (a second multiplier at +1) bounds stable
    gaits, and how near its fold-flip is to the period-doubling curve's."""
    summary = ev.summary("curve_vpp_fold")
    rows = [r for r in ev.rows("curve_vpp_fold", "curve.csv") if r["type"] == "fold"]
    if summary is None or not rows:
        return ""
    bounding = [r for r in rows if r["stability_boundary"] is True]
    where = (f"it bounds stable gaits for r_vpp {min(r['r_vpp'] for r in bounding):.4g} to "
             f"{max(r['r_vpp'] for r in bounding):.4g} m (ydot {max(r['ydot'] for r in bounding):.4g} down to "
             f"{min(r['ydot'] for r in bounding):.4g} m/s)" if bounding else "it bounds no stable gaits")
    ours = [p for p in summary["curves"]["codimension_two_points"] if p["type"] == "fold_flip"]
    theirs = [p for p in period_doubling["curves"]["codimension_two_points"] if p["type"] == "fold_flip"]
    meeting = (f"; its fold-flip, at r_vpp = {ours[0]['r_vpp']:.6g} m, ydot = {ours[0]['ydot']:.6g} m/s, is the "
               f"period-doubling curve's to {abs(ours[0]['r_vpp'] - theirs[0]['r_vpp']):.1g} m and "
               f"{abs(ours[0]['ydot'] - theirs[0]['ydot']):.1g} m/s" if ours and theirs else "")
    return (f" The fold curve, where a second multiplier crosses +1 (curve_vpp_fold, {len(rows)} verified points, "
            f"from the branch's crossing at 3.9 m/s, which the symmetric gaits pass without turning): {where}"
            f"{meeting}.")


def optimal_claims(ev: Evidence) -> list[str]:
    """One claim: the least radius per cell of the VPP stability-optimal search, beside
    the thesis-scale atlas's polished least at the same speed (whose family, with z free,
    holds the cell's)."""
    summary = ev.summary("optimal_vpp")
    if summary is None or not summary.get("complete"):
        return []
    polished = {c["sweep_ydot"]: c["polished_radius"] for c in ev.rows("atlas_vpp", "cells.csv")}
    nlp = _least_by_cell(ev.summary(SCHUR_STUDY))
    lines = []
    for cell in summary["least_per_point"]:
        atlas = polished.get(cell["ydot"])
        shown = f"{atlas:.4f}" if isinstance(atlas, float) else "-"
        by_nlp = nlp.get((cell["ydot"], cell["z"]))
        lines.append(f"| {cell['ydot']:g} | {cell['z']:g} | {cell['spectral_radius']:.4f} | "
                     f"{'yes' if cell['stable'] else 'no'} | {'-' if by_nlp is None else f'{by_nlp:.4f}'} | {shown} |")
    table = ("| ydot [m/s] | z [m] | least radius | stable | stability NLP | atlas_vpp, polished, z free |\n"
             "|---|---|---|---|---|---|\n" + "\n".join(lines) + "\n")
    below = [c for c in summary["least_per_point"] if isinstance(polished.get(c["ydot"]), float)
             and c["spectral_radius"] < polished[c["ydot"]] * (1 - 1e-9)]
    agreement = ("At every cell the descent ends at or above the atlas's polished least at its speed, as it must if "
                 "the atlas found the family's best" if not below else
                 f"At {len(below)} cell{'s' if len(below) != 1 else ''} the descent ends below the atlas's polished least at its speed: the atlas's "
                 "two polished minima missed a better valley there")
    least = summary["least"]
    return [claim(
        "Under constant VPP, the most stable gait per cell (descent)",
        "not studied (the thesis knows the PD law only).",
        f"optimal_vpp: at each (ydot, z) cell, {summary['starts']} starts with r_vpp drawn over its bounds, each "
        f"descended along the cell's family of gaits (the symmetry multiplier left out), {summary['points']} starts, "
        f"{summary['solved']} verified:\n\n" + table + f"\n{agreement}. The least: {least['spectral_radius']:.4f} at "
        f"ydot = {least['ydot']:g} m/s, z = {least['z']:g} m, r_vpp = {least['control']['r_vpp']:.4g} m.\n"
        + _schur_crosscheck(ev, summary),
        "goes further",
        f"The search is local from each start; the claim is as wide as its {len(summary['least_per_point'])} cells "
        f"and their starts. The least gait of every cell stays within {_tilt(summary):.2f} deg of vertical "
        "throughout its stride.",
        ["optimal_vpp/spectral_radius_map.png"],
    )]


#: The stability NLP's cross-check of ``optimal_vpp``: the same cells, starts and draws.
SCHUR_STUDY = "optimal_vpp_schur"
#: Relative distance within which a stability NLP's end is the descent's least of its cell.
SAME_RADIUS = 1e-4


def _least_by_cell(summary: dict | None) -> dict[tuple, float]:
    """(ydot, z) -> the least verified radius of a finished optimal study's cell."""
    if summary is None or not summary.get("complete"):
        return {}
    return {(c["ydot"], c["z"]): c["spectral_radius"] for c in summary["least_per_point"]
            if isinstance(c.get("spectral_radius"), float)}


def _schur_crosscheck(ev: Evidence, descent: dict) -> str:
    """How the stability NLP's starts (:data:`SCHUR_STUDY`) ended against the descent's
    least of their cells: at it, above it, below it (each named), or failed."""
    summary = ev.summary(SCHUR_STUDY)
    if summary is None or not summary.get("complete"):
        return ""
    least = _least_by_cell(descent)
    rows = ev.rows(SCHUR_STUDY, "points.csv")
    at, above, below, failed = 0, 0, [], 0
    for row in rows:
        best = least.get((row["sweep_ydot"], row["sweep_z"]))
        if row["status"] != "converged" or best is None:
            failed += 1
        elif abs(row["spectral_radius"] - best) <= SAME_RADIUS * best:
            at += 1
        elif row["spectral_radius"] > best:
            above += 1
        else:
            below.append(row)
    cells = sum(1 for key, value in _least_by_cell(summary).items()
                if key in least and abs(value - least[key]) <= SAME_RADIUS * least[key])
    named = "; ".join(f"{r['spectral_radius']:.4f} at ydot = {r['sweep_ydot']:g} m/s, z = {r['sweep_z']:g} m, "
                      f"r_vpp = {r['r_vpp']:.2g} m" for r in below)
    return (f"\nThe stability NLP ({SCHUR_STUDY}: the same cells, starts and draws; every multiplier but the "
            f"symmetry one bounded by a Schur form): its least equals the descent's (to {SAME_RADIUS:g}) at {cells} of "
            f"{len(least)} cells. Of its {len(rows)} starts, {at} end at their cell's least, {above} above it (at "
            f"other minima of its bound, or at IPOPT's acceptable level), {failed} fail, and {len(below)} "
            f"end{'s' if len(below) == 1 else ''} below it"
            + (f" ({named})" if below else "") + ".\n")


def atlas_claims(ev: Evidence) -> list[str]:
    """One claim: per speed of each finished VPP atlas, the covering (pieces, seeds,
    charts, whether whole), the least radius, the stable share of the family and where its
    stable gaits lie."""
    found: dict[str, dict] = {}
    for name in VPP_ATLASES:
        summary = ev.summary(name)
        if summary is not None and summary.get("complete"):
            found[name] = summary
    if not found:
        return []
    lines = []
    for name in found:
        charts = [c for c in ev.rows(name, "atlas.csv") if c["status"] == "converged"]
        for cell in ev.rows(name, "cells.csv"):
            speed = cell["sweep_ydot"]
            stable = [c for c in charts if c["sweep_ydot"] == speed and c["stable"] is True]
            covered = "whole" if cell["complete"] is True else f"not whole ({_why_not_whole(cell)})"
            lines.append(f"| {VPP_ATLASES[name]} | {speed:g} | {cell['pieces']:g} from {cell['seeds']:g} "
                         f"({cell['seeds_failed']:g} failed) | {cell['charts']:g}, {covered} | "
                         f"{cell['least_radius']:.3f} | {_polished(cell)} | {cell['stable_share']:.1%} | "
                         + (_ranges(stable) if stable else "-") + " |")
    table = ("| atlas | ydot [m/s] | pieces from seeds | charts | least radius | polished | stable share | "
             "stable gaits |\n|---|---|---|---|---|---|---|---|\n" + "\n".join(lines) + "\n")
    wide = "; ".join(f"{VPP_ATLASES[name]}: " + ", ".join(
        f"{k} in [{_shown_bound(k, lo)}, {_shown_bound(k, hi)}]" for k, (lo, hi) in
        found[name]["provenance"]["problem"]["bounds"].items()) for name in found)
    least = min(cell["least_radius"] for name in found for cell in ev.rows(name, "cells.csv"))
    return [claim(
        "Under constant VPP, over the whole family of gaits (atlas)",
        "not studied (the thesis knows the PD law only).",
        "at each speed, the 2-D manifold of fixed points in the apex height, the pivot and the touchdown angle, "
        "covered by charts from independent solves (r_vpp drawn over its bounds), every chart verified by the "
        "independent re-simulation; the least local minima of the radius polished by the stability descent "
        "(its end verified too). The stable share is of the family's area in atlas coordinates:\n\n" + table
        + "\n" + "; ".join(_onset(ev, name, summary) for name, summary in found.items()) + ".\n",
        "goes further",
        "Every gait found is symmetric (theta_h = 90 deg at the apex): the one family per speed that the seeds "
        "reached. The claim holds within the bounds (" + wide + ") and for the pieces reached; where a speed is not "
        f"covered whole, for the part covered. The margins are thin: no chart's radius below {least:.3f}, no "
        f"polished gait's below {_least_polished(ev, found):.3f}.",
        [f"{name}/atlas.png" for name in found],
    )]


def _least_polished(ev: Evidence, found: dict) -> float:
    radii = [c["polished_radius"] for name in found for c in ev.rows(name, "cells.csv")
             if isinstance(c["polished_radius"], float)]
    return min(radii, default=math.nan)


def _onset(ev: Evidence, name: str, summary: dict) -> str:
    """The slowest speed of an atlas with a stable gait, and its Froude number."""
    params = Params(**summary["provenance"]["problem"]["params"])
    cells = ev.rows(name, "cells.csv")
    speeds = sorted(c["sweep_ydot"] for c in cells if isinstance(c["stable_share"], float) and c["stable_share"] > 0)
    if not speeds:
        return f"{VPP_ATLASES[name]}: no stable gait at any speed covered"
    froude = speeds[0] / math.sqrt(params.g * params.rho0)
    slower = [c["sweep_ydot"] for c in cells if c["sweep_ydot"] < speeds[0]]
    before = f" (none at {max(slower):g} m/s)" if slower else ""
    return (f"{VPP_ATLASES[name]}: stable gaits from {speeds[0]:g} m/s{before}, Froude number ydot / sqrt(g rho0) = "
            f"{froude:.2f}")


def _polished(cell: dict) -> str:
    """The radius the descent reached from the cell's best charts ('-' if not polished)."""
    radius = cell["polished_radius"]
    return f"{radius:.3f}" if isinstance(radius, float) else "-"


def _why_not_whole(cell: dict) -> str:
    return ("the corrector gave up at some edges" if cell["corrector_stops"] else "the chart limit was reached")


def _ranges(rows: list[dict]) -> str:
    """The ranges of z, r_vpp and theta_td over ``rows``."""
    parts = []
    for name, unit, factor in (("z", "m", 1.0), ("r_vpp", "m", 1.0), ("theta_td", "deg", DEG)):
        lo, hi = min(r[name] for r in rows) * factor, max(r[name] for r in rows) * factor
        parts.append(f"{name} {lo:.3g} to {hi:.3g} {unit}")
    return ", ".join(parts)


def _shown_bound(name: str, value: float) -> str:
    return f"{value * DEG:.0f} deg" if name.startswith("theta") else f"{value:g} m"
