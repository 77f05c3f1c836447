"""The sections beyond the thesis: stable upright gaits, branches, bifurcation curves, period two."""

from __future__ import annotations

import math

import numpy as np

from baslip.report.answer import upright_answer
from baslip.report.atlas import atlas_claims, crosscheck_claims
from baslip.report.controllers import controller_claims
from baslip.report.evidence import DEG, Evidence, _shown, claim
from baslip.report.vpp import vpp_claims
from baslip.status import Status
from baslip.viz.labels import SPECIAL_NAMES


def upright_section(ev: Evidence) -> list[str]:
    """Can an upright BA-SLIP run stably? The short answer under the three laws of control,
    then the claims under constant PD, constant VPP, and controllers."""
    answer = upright_answer(ev)
    out = [answer] if answer else []
    upright, hanging = ev.summary("optimal_upright"), ev.summary("optimal_downward")
    if upright and upright.get("least"):
        least, problem = upright["least"], upright["provenance"]["problem"]
        bounds = problem["bounds"]
        through = upright.get("least_upright_throughout")
        study = problem["study"]
        through_text = f"{through['spectral_radius']:.3f}" if through else "none found"
        hanging_text = ""
        if hanging and hanging.get("least"):
            hanging_text = (f" For comparison, the same search with the trunk hanging finds stable gaits in every cell "
                            f"({sum(1 for p in hanging['least_per_point'] if p['stable'])} of {len(hanging['least_per_point'])}), "
                            f"least radius {hanging['least']['spectral_radius']:.3f}.")
        out.append(claim(
            "Under constant PD, by the local multi-start search",
            "every upright fixed point found was unstable under the constant PD hip law (sec. 4.4.3.1, 4.7).",
            f"the most stable gait was searched for at {len(upright['least_per_point'])} (ydot, z) cells, "
            f"{study['starts']} starts each with Kp in [{bounds['Kp'][0]:g}, {bounds['Kp'][1]:g}] N m/rad and Kd in "
            f"[{bounds['Kd'][0]:g}, {bounds['Kd'][1]:g}] N m s/rad drawn over their whole range, each descended for at "
            f"most {study['iterations']} quasi-Newton steps ({upright['solved']} verified end points). Least spectral "
            f"radius, upright at the apex: {least['spectral_radius']:.3f} at ydot = {least['ydot']:g} m/s, z = {least['z']:g} m "
            f"(trunk between {least['trunk_range_deg'][0]:.1f} and {least['trunk_range_deg'][1]:.1f} deg over the stride); "
            f"upright throughout (within 45 deg of vertical at every instant): {through_text}. Per cell: "
            + ", ".join(f"({p['ydot']:g}, {p['z']:g}): {p['spectral_radius']:.3g}" for p in upright["least_per_point"])
            + "." + hanging_text,
            "agreed, by this local search only" if least["spectral_radius"] >= 1 else "differs: a stable upright gait exists",
            "The search minimises a smooth bound of the spectral radius on the manifold of fixed points (gradient from "
            "AD second derivatives of the stride), from many starts, then polishes the radius itself by a compass "
            "search. It is local: a valley between starts can be missed, and gains beyond the bounds were not "
            "searched. Among the gaits it reached the least radius stays above 1 in every cell" + _hanging_range(hanging)
            + "; that says nothing of the gaits it did not reach. The atlas below covers the "
            "whole family and polishes its best charts: where it finds a stable gait, this search missed it.",
            ["optimal_upright/spectral_radius_map.png", "optimal_upright/best_gaits_trunk.png",
             "optimal_downward/spectral_radius_map.png"],
        ))
    out += atlas_claims(ev) + crosscheck_claims(ev) + vpp_claims(ev)
    out += controller_claims(ev)
    return out or ["Not run.\n"]


BRANCHES = ("continuation_slip_attack", "continuation_downward_speed", "continuation_downward_height")


def branch_sections(ev: Evidence) -> list[str]:
    """What each shipped continuation found: branches, stop reasons, special points."""
    out = []
    for name in BRANCHES:
        summary = ev.summary(name)
        if not summary or "branches" not in summary:
            out.append(f"### {name}\n\nNot run.\n")
            continue
        parameter = summary["parameter"]
        lines = [f"### {name}", "", f"Parameter `{parameter}` over [{summary['range'][0]:.6g}, {summary['range'][1]:.6g}]; "
                 f"{summary['points']} verified points in {summary['wall_time_s']:.0f} s. "
                 f"Figure: [{name}/diagram.png]({name}/diagram.png).", ""]
        for b in summary["branches"]:
            origin = ""
            if b["switched_from"]:
                origin = (f", switched at the {SPECIAL_NAMES[b['switched_from']['type']]} at "
                          f"{parameter} = {_shown(parameter, b['switched_from'][parameter])}")
            special = [p for p in summary["special_points"] if p["branch"] == b["branch"]]
            found = "; ".join(f"{SPECIAL_NAMES[p['type']]} at {parameter} = {_shown(parameter, p[parameter])}"
                              for p in special) or "no special points"
            lines.append(f"- Branch {b['branch']} ({b['strides']}-stride orbits{origin}): {b['points']} points, "
                         f"stopped at: {b['stop_reason']}. {found}.")
        for f in summary.get("failed_switches", []):
            lines.append(f"- Could not switch at the {SPECIAL_NAMES[f['type']]} at {parameter} = "
                         f"{_shown(parameter, f[parameter])}: {f['reason']}.")
        rows = ev.rows(name, "branch.csv")
        doubled = [r for r in rows if r["strides"] > 1]
        if doubled:
            radii = [r["spectral_radius"] for r in doubled]
            stable = sum(r["stable"] is True for r in doubled)
            lines.append(f"- On the switched branches: {stable} of {len(doubled)} points stable; spectral radius "
                         f"{min(radii):.4g} to {max(radii):.4g} (multipliers of each orbit's own N-stride map).")
        if any(p["type"] == "turning_point" for p in summary["special_points"]):
            lines.append(f"- A turning point is where the path turns back in `{parameter}` with no multiplier "
                         "crossing +1: the branch folds over in that apex coordinate, but the map has no "
                         "saddle-node there (earlier versions of this report called it a fold).")
        out.append("\n".join(lines) + "\n")
    out.append(period_two_gait(ev))
    return out


#: Speeds [m/s] at which the SLIP band is tabulated, and the apex height [m] that turns a
#: speed into an energy, E = m g h + m v^2 / 2 (as in continuation_slip_attack).
BAND_SPEEDS = (4.0, 4.5, 5.0, 5.5, 6.0)
BAND_HEIGHT = 1.0


def curve_sections(ev: Evidence) -> list[str]:
    """The traced bifurcation curves: the SLIP band, the hanging gaits' exact stability
    boundary, a Neimark-Sacker curve, and the codimension-two points on them."""
    return [slip_band_section(ev), boundary_section(ev), neimark_sacker_section(ev), codim2_section(ev)]


def _curve(rows: list[dict], kind: str) -> list[dict]:
    return [r for r in rows if r["type"] == kind]


def _interpolate(rows: list[dict], along: str, value: float, wanted: str) -> float:
    """``wanted`` where the curve (rows in order) passes ``along`` = value: quadratic in the
    point index through the crossing segment and its nearer neighbour (so that a curve
    turning in ``along`` is followed), linear where there is no third point."""
    for i, (a, b) in enumerate(zip(rows[:-1], rows[1:])):
        if not (min(a[along], b[along]) <= value <= max(a[along], b[along]) and a[along] != b[along]):
            continue
        t = (value - a[along]) / (b[along] - a[along])
        first = i - 1 if i > 0 and (t < 0.5 or i + 2 >= len(rows)) else i
        if first + 2 >= len(rows):
            return a[wanted] + t * (b[wanted] - a[wanted])
        three = rows[first:first + 3]
        index = np.arange(3.0)
        shape = np.polyfit(index, [r[along] for r in three], 2) - np.array([0.0, 0.0, value])
        roots = [r.real for r in np.roots(shape) if abs(r.imag) < 1e-12 and i - first <= r.real <= i - first + 1]
        at = roots[0] if roots else i - first + t
        return float(np.polyval(np.polyfit(index, [r[wanted] for r in three], 2), at))
    return math.nan


def slip_band_section(ev: Evidence) -> str:
    summary, rows = ev.summary("curve_slip_band"), ev.rows("curve_slip_band", "curve.csv")
    if not summary or not rows:
        return "### The SLIP self-stable band in two parameters\n\nNot run.\n"
    m, g = 80.0, 9.81
    doubling, fold = _curve(rows, "period_doubling"), _curve(rows, "fold")
    table = ["| speed [m/s] | energy [J] | period-doubling edge theta_td [deg] | fold edge theta_td [deg] | "
             "width [deg] | angles of attack [deg] |", "|---|---|---|---|---|---|"]
    band = []
    for v in BAND_SPEEDS:
        energy = m * g * BAND_HEIGHT + 0.5 * m * v**2
        lo = _interpolate(doubling, "energy", energy, "theta_td") * DEG
        hi = _interpolate(fold, "energy", energy, "theta_td") * DEG
        band.append((lo, hi))
        table.append(f"| {v:g} | {energy:.1f} | {lo:.4f} | {hi:.4f} | {hi - lo:.3f} | {90 - hi:.2f} to {90 - lo:.2f} |")
    widths = [hi - lo for lo, hi in band]
    widening = all(b > a for a, b in zip(widths, widths[1:]))
    flatter = all(b[0] > a[0] and b[1] > a[1] for a, b in zip(band, band[1:]))
    bounding = sum(r["stability_boundary"] is True for r in rows)
    codim2 = summary["curves"]["codimension_two_points"]
    edges = {p["type"]: p["theta_td"] for p in summary["special_points"]}
    at_start = {kind: [r for r in _curve(rows, kind) if abs(r["energy"] - 1784.8) < 1e-6] for kind in edges}
    agreement = max(abs(at_start[k][0]["theta_td"] - edges[k]) for k in edges if at_start[k]) if all(at_start.values()) else math.nan
    curves = summary["curves"]["curves"]
    return "\n".join([
        "### The SLIP self-stable band in two parameters (curve_slip_band)", "",
        f"Both edges of the band found by continuation_slip_attack are followed from 5 m/s over the energies of 4 to "
        f"6 m/s at a {BAND_HEIGHT:g} m apex height: the period doubling ({curves[0]['points']} verified points) and "
        f"the fold ({curves[1]['points']}), each ending on both ends of the energy range. "
        f"Figure: [curve_slip_band/curve.png](curve_slip_band/curve.png).", "",
        *table, "",
        f"- At 1784.8 J both curves pass through the edges that the one-parameter branch locates (21.1464 and "
        f"23.6945 deg) to {agreement:.1e} rad.",
        "- Against Seyfarth et al. (2002), *A movement criterion for running*, J. Biomech. 35:649: they find that "
        "self-stable running needs a minimum speed and that \"with increasing speed, the leg adjustment becomes "
        "less critical\". "
        + (f"The traced band agrees: it {'narrows steadily as the speed drops' if widening else 'does not narrow steadily'}, "
           f"its width growing {widths[-1] / widths[0]:.2g}-fold from {BAND_SPEEDS[0]:g} to {BAND_SPEEDS[-1]:g} m/s"
           + (", while both edges move to flatter legs (larger theta_td) as the speed rises. " if flatter else ". "))
        + "We compared with the paper's statements, not with numbers read off its figures.",
        f"- {bounding} of {len(rows)} curve points bound the stable band: apart from the critical multiplier (-1, "
        "respectively +1, on the energy level) every multiplier on the energy level is inside the unit circle; the "
        "remaining ones are the structural multipliers at 1 (energy, free spin).",
        f"- Codimension-two points on these curves: {len(codim2) or 'none'}.", "",
    ])


def boundary_section(ev: Evidence) -> str:
    summary, rows = ev.summary("curve_downward_boundary"), ev.rows("curve_downward_boundary", "curve.csv")
    if not summary or not rows:
        return "### The exact stability boundary of the hanging-trunk gaits\n\nNot run.\n"
    lines = ["### The exact stability boundary of the hanging-trunk gaits (curve_downward_boundary)", "",
             "The gaits of grid_downward fix only the apex speed and height; of the many fixed points there, the solve "
             "picks the one nearest the guess. The branch and the curves follow that same family, through its "
             "optimality conditions, so the boundary is the boundary of the grid's map. "
             "Figure: [curve_downward_boundary/curve.png](curve_downward_boundary/curve.png).", ""]
    for c in summary["curves"]["curves"]:
        curve = [r for r in rows if r["curve"] == c["curve"]]
        zs = [r["z"] for r in curve]
        kappas = [r["kappa"] for r in curve if isinstance(r["kappa"], float)]
        bounding = all(r["stability_boundary"] is True for r in curve)
        angle = (f"; the critical pair turns by {math.degrees(math.acos(max(kappas))):.3g} to "
                 f"{math.degrees(math.acos(min(kappas))):.3g} deg per stride" if kappas else "")
        lines.append(f"- Curve {c['curve']}, {SPECIAL_NAMES[c['type']]}: {c['points']} points, z from "
                     f"{min(zs):.4f} to {max(zs):.4f} m over ydot in [0.1, 1] m/s"
                     f"{angle}; {'bounds the stable gaits' if bounding else 'unstable on both sides'}; "
                     f"stopped: {c['stop_reason']}.")
    interpolated, traced = ev.summary("stable_region_random"), ev.summary("stable_region_traced")
    if interpolated and traced:
        lines.append(f"- **Sampling inside it.** stable_region_traced draws {traced['points']} random (ydot, z) points "
                     f"inside the traced boundary and solves them as the grid's cells are: {traced['stable']} of "
                     f"{traced['solved']} are stable. Drawn inside the bilinear interpolation of the grid's radius "
                     f"instead (stable_region_random), {interpolated['stable']} of {interpolated['solved']} are. "
                     "Figure: [stable_region_traced/samples.png](stable_region_traced/samples.png), with the "
                     "boundary drawn over the grid's stable cells.")
    edges = [c for c in summary["curves"]["curves"] if all(r["stability_boundary"] is True for r in rows if r["curve"] == c["curve"])]
    if len(edges) == 2 and all(c["type"] == "neimark_sacker" for c in edges):
        lower, upper = sorted(([r for r in rows if r["curve"] == c["curve"]] for c in edges), key=lambda c: c[0]["z"])
        height = _interpolate(upper, "ydot", 0.5, "z") - _interpolate(lower, "ydot", 0.5, "z")
        turn_low = math.degrees(math.acos(float(np.mean([r["kappa"] for r in lower]))))
        turn_high = [math.degrees(math.acos(r["kappa"])) for r in upper]
        lines.append(
            f"- **What it means for the runner.** The band of stable hanging-trunk gaits, {100 * height:.1f} cm of apex "
            "height at 0.5 m/s, is bounded above and below by Neimark-Sacker curves: past either edge the gait "
            "still exists, but a stride-to-stride oscillation grows around it. At the lower edge the oscillation "
            f"turns by about {turn_low:.0f} deg per stride, a wobble of {360 / turn_low:.1f} strides; at the upper "
            f"edge by {min(turn_high):.2g} to {max(turn_high):.2g} deg, a slow drift of {360 / max(turn_high):.0f} to "
            f"{360 / min(turn_high):.0f} strides. The period doubling lies above the band, where the gaits are "
            "already unstable, so no stable two-stride gait appears at this boundary.")
    return "\n".join(lines) + "\n"


def neimark_sacker_section(ev: Evidence) -> str:
    summary, rows = ev.summary("curve_downward_neimark_sacker"), ev.rows("curve_downward_neimark_sacker", "curve.csv")
    if not summary or not rows:
        return "### A Neimark-Sacker curve of the BA-SLIP\n\nNot run.\n"
    top = max(rows, key=lambda r: r["ydot"])
    upper_edge = sorted((r for r in rows if r["z"] > top["z"]), key=lambda r: r["ydot"])[:5]
    ratios = [(1 - r["kappa"]) / r["ydot"] ** 2 for r in upper_edge]
    lines = ["### A Neimark-Sacker curve of the BA-SLIP (curve_downward_neimark_sacker)", "",
             "The hanging gait of problems/downward.yaml with its gains held (Kp = -0.75 N m/rad, Kd = 1.5 N m s/rad, "
             "theta2_des = -3 deg), followed from its upper Neimark-Sacker point at 0.5 m/s over ydot in "
             f"[0.005, 1.6] m/s: {len(rows)} verified points, stopped: {summary['curves']['curves'][0]['stop_reason']}. "
             "Figure: [curve_downward_neimark_sacker/curve.png](curve_downward_neimark_sacker/curve.png).", "",
             f"- The two edges of the stable band are one curve. It closes over the band at ydot = {top['ydot']:.4g} m/s "
             f"(z = {top['z']:.4g} m): no stable gait of this family runs faster.",
             f"- Towards hopping in place the critical pair closes in on +1: on the upper edge cos(theta) = "
             f"{upper_edge[0]['kappa']:.6f} at ydot = {upper_edge[0]['ydot']:g} m/s, and over its {len(upper_edge)} "
             f"slowest points 1 - cos(theta) = c ydot^2 with c from {min(ratios):.4f} to {max(ratios):.4f}. The pair "
             "reaches +1 only at ydot = 0, where the family ends; cos(theta) - 1 changes sign nowhere inside the "
             "range, so no 1:1 resonance is claimed."]
    speed = ev.summary("continuation_downward_speed")
    ns = [p for p in (speed or {}).get("special_points", []) if p["type"] == "neimark_sacker"]
    if ns:
        right = [r for r in rows if r["z"] > top["z"] and r["ydot"] > 1.0]  # the upper edge
        z_there = _interpolate(sorted(right, key=lambda r: r["ydot"]), "ydot", ns[0]["ydot"], "z")
        lines.append(f"- Cross-check: continuation_downward_speed (z = 0.4 m) meets a Neimark-Sacker point at "
                     f"ydot = {ns[0]['ydot']:.6g} m/s; the curve passes that speed at z = {z_there:.6f} m.")
    return "\n".join(lines) + "\n"


def codim2_section(ev: Evidence) -> str:
    from baslip.viz.labels import CODIM2_NAMES

    lines = ["### Codimension-two points", ""]
    found = []
    for name in ("curve_slip_band", "curve_downward_boundary", "curve_downward_neimark_sacker"):
        summary = ev.summary(name)
        if summary and "curves" in summary:
            first, second = summary["parameter"], summary["curves"]["second"]
            for p in summary["curves"]["codimension_two_points"]:
                mu = max((complex(*m) for m in p["multipliers"]), key=abs)
                found.append(f"- {CODIM2_NAMES[p['type']]} on the {SPECIAL_NAMES[p['on']]} curve of {name}: "
                             f"{first} = {_shown(first, p[first])}, {second} = {_shown(second, p[second])}; largest "
                             f"|multiplier| there {abs(mu):.4g}.")
    lines += found or ["- None on the shipped curves."]
    if any("generalised" in line for line in found):
        lines.append("- A generalised period doubling is where the flip's cubic coefficient changes sign. Two "
                     "independent branch runs (tests/test_curve_runs.py) confirm it: switching onto the two-stride "
                     "orbits born at the period doubling, their multiplier near +1 lies above 1 at 0.5 m/s and below "
                     "1 at 0.6 m/s. For the runner it changes little: a complex pair is already outside the unit "
                     "circle there, so neither the period-1 gait nor the two-stride orbits near it are stable.")
    return "\n".join(lines) + "\n"


def period_two_gait(ev: Evidence) -> str:
    """The shipped two-stride gait, solved directly by the two-stride NLP."""
    record = ev.summary("downward_period2")
    if not record:
        return "### downward_period2\n\nNot run.\n"
    if record["status"] != Status.CONVERGED or not record.get("orbit"):
        return f"### downward_period2\n\nThe two-stride solve did not converge: status {record['status']}.\n"
    apexes = "; ".join(f"z = {a['z']:.5g} m, theta_h = {a['theta_h'] * DEG:.4g} deg, ydot = {a['ydot']:.4g} m/s, "
                       f"theta_h_dot = {a['theta_h_dot'] * DEG:.4g} deg/s" for a in record["orbit"])
    return "\n".join([
        "### downward_period2", "",
        f"`problems/downward_period2.yaml` asks the NLP directly for a {record['strides']}-stride orbit at the first "
        f"apex's z = {record['apex']['z']:.4g} m and ydot = {record['apex']['ydot']:.4g} m/s: {record['status']}, "
        f"residual {record['residual']:.1e} over the whole orbit, minimal period {record['minimal_period']}, "
        f"spectral radius {record['spectral_radius']:.4g} ({'stable' if record['stable'] else 'unstable'}). "
        f"Its apexes: {apexes}. It lies on the switched branch of continuation_downward_height.", "",
    ])


def _hanging_range(hanging: dict | None) -> str:
    """", while the hanging trunk reaches ..." : the range of the hanging search's least
    radius per cell ("" if it has not run)."""
    radii = [p["spectral_radius"] for p in (hanging or {}).get("least_per_point", [])]
    return f", while the hanging trunk reaches {min(radii):.2f} to {max(radii):.2f}" if radii else ""
