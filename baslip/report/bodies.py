"""The section beyond the thesis on other bodies: gaits found from the body alone."""

from __future__ import annotations

from baslip.model.dynamics import Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.quantities import posture_of, quantity_text
from baslip.model.similarity import groups
from baslip.report.evidence import DEG, Evidence, claim

#: The shipped problems of the human-sized body with no guess.
HUMAN_GAITS = ("human_pd_hanging", "human_pd_upright", "human_vpp_3ms")
#: The one-cell PD atlas of the human body with no guess.
HUMAN_ATLAS = "atlas_human_pd"


def body_claims(ev: Evidence) -> list[str]:
    """The human-sized runner's gaits found from the body alone, each verified again."""
    records = [r for r in (ev.summary(name) for name in HUMAN_GAITS) if r is not None]
    if not records:
        return ["Not run.\n"]
    params = Params(**records[0]["params"])
    body = groups(params)
    gaits = "; ".join(_gait_text(ev, r) for r in records)
    stable = sum(1 for r in records if r["stable"])
    return [_first_gaits_claim(params, body, gaits, stable, len(records))] + _atlas_claim(ev, params)


def _first_gaits_claim(params: Params, body, gaits: str, stable: int, count: int) -> str:
    return claim(
        "Gaits of a human-sized runner, found from the body alone",
        "one body (m 1 kg, rho0 0.2 m); its gaits start from guesses written by hand.",
        f"a body of m = {params.m:g} kg, I = {params.I:g} kg m^2, k = {params.k:g} N/m, rho0 = {params.rho0:g} m, "
        f"d = {params.d:g} m (groups k rho0/(m g) = {body.stiffness:.4g}, I/(m rho0^2) = {body.inertia:.4g}, "
        f"d/rho0 = {body.offset:.4g}; the thesis's: 20.39, 0.0825, 0.2), problems with no guess: {gaits}. "
        f"{stable} of {count} stable.",
        "beyond the thesis: a gait at each law and posture asked, with no guess",
        "Each start is one shipped gait carried to this body and continued to the cell (baslip.gait.anybody); the "
        "answer is one gait per law and posture, the one nearest that start. These radii say that these gaits are "
        "unstable, not that no stable one exists: the atlases (atlas_human_pd below, atlas_vpp_human) search the "
        "families.",
    )


def _atlas_claim(ev: Evidence, params: Params) -> list[str]:
    """The one-cell PD atlas of the human body with no guess: what it covered and its most
    stable gait, re-simulated here."""
    summary, cells = ev.summary(HUMAN_ATLAS), ev.rows(HUMAN_ATLAS, "cells.csv")
    if summary is None or not summary.get("best") or not cells:
        return []
    cell, best = cells[0], min(summary["best"], key=lambda b: b["spectral_radius"])
    bounds = summary["provenance"]["problem"]["bounds"]
    independent = ev.resimulate(best, HIP_LAWS["pd"], params)
    stable = best["spectral_radius"] < 1
    covered = "covered whole" if cell["complete"] is True else "not covered whole (the chart limit was reached)"
    return [claim(
        "A human-sized runner under constant PD at 3 m/s: the most stable gait of its cell",
        "not studied (one body).",
        f"`{HUMAN_ATLAS}`, an atlas of the cell ydot = {best['ydot']:g} m/s, z = {best['z']:g} m with no guess: "
        f"{cell['seeds']:.0f} seeds ({cell['seeds_failed']:.0f} failed), {cell['pieces']:.0f} pieces, {cell['charts']:.0f} "
        f"charts, "
        f"{covered}, within theta_h in [{bounds['theta_h'][0] * DEG:.0f}, {bounds['theta_h'][1] * DEG:.0f}] deg, "
        f"Kp in [{bounds['Kp'][0]:g}, {bounds['Kp'][1]:g}] N m/rad, Kd in [{bounds['Kd'][0]:g}, {bounds['Kd'][1]:g}] "
        f"N m s/rad (the thesis atlas's bounds scaled to this body); stable share of the charts "
        f"{100 * cell['stable_share']:.1f}%. Its most stable polished gait: spectral radius "
        f"{best['spectral_radius']:.4g}, theta_h = {best['theta_h'] * DEG:.1f} deg at the apex, the trunk between "
        f"{best['trunk_min_deg']:.1f} and {best['trunk_max_deg']:.1f} deg over the stride, "
        + ", ".join(quantity_text(n, best[n], 4) for n in HIP_LAWS["pd"].controls.names)
        + f"; residual {best['residual']:.1e}, independent re-simulation eps = {independent:.1e} (erk, 1e-13).",
        "beyond the thesis: a stable PD gait of the human body exists" if stable
        else "beyond the thesis: no stable PD gait found in the covered part",
        "A stable gait found is a fact whatever the covering; where none is found, the answer is only as wide as "
        "the covering: this one cell, these bounds, the pieces its seeds reached and the charts it made.",
        [f"{HUMAN_ATLAS}/atlas.png", f"{HUMAN_ATLAS}/best_gaits_trunk.png"],
    )]


def _gait_text(ev: Evidence, record: dict) -> str:
    """One gait: its problem, law, posture, apex and control, radius, and both residuals."""
    law = HIP_LAWS[record["hip_law"]]
    row = {**record["apex"], **record["control"]}
    independent = ev.resimulate(row, law, Params(**record["params"]))
    controls = ", ".join(quantity_text(n, row[n], 4) for n in law.controls.names)
    return (f"{record['name']} ({law.name.upper()}, {posture_of(row['theta_h'])}; ydot = {row['ydot']:g} m/s, "
            f"z = {row['z']:g} m, {controls}): spectral radius {record['spectral_radius']:.4g}, "
            f"{'stable' if record['stable'] else 'unstable'}; residual {record['residual']:.1e}, independent "
            f"re-simulation eps = {independent:.1e} (erk, 1e-13)")
