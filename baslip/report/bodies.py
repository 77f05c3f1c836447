"""The section beyond the thesis on other bodies: gaits found from the body alone."""

from __future__ import annotations

from baslip.model.dynamics import Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.quantities import posture_of, quantity_text
from baslip.model.similarity import groups
from baslip.report.evidence import DEG, Evidence, claim

#: The reference bodies other than the thesis's: what each is, and its shipped problems
#: with no guess (one per law and posture).
BODIES = (
    ("a human-sized runner", ("human_pd_hanging", "human_pd_upright", "human_vpp_3ms")),
    ("a robot of a few kilograms (the Penn Jerboa's mass, leg and leg stiffness from its public controller's "
     "parameters; its inertia and hip offset, not published, at the thesis body's proportions)",
     ("robot_pd_hanging", "robot_pd_upright", "robot_vpp")),
)
#: The one-cell PD atlas of the human body with no guess.
HUMAN_ATLAS = "atlas_human_pd"
#: The families studies (which gaits exist at one cell, with no guess) of the bodies.
FAMILIES = ("families_human_pd", "families_robot_pd")


def body_claims(ev: Evidence) -> list[str]:
    """Each reference body's gaits found from the body alone, each verified again; the
    human's one-cell atlas; the families studies' answers."""
    claims = [c for what, names in BODIES for c in _gaits_claim(ev, what, names)]
    if not claims:
        return ["Not run.\n"]
    return claims + _atlas_claim(ev) + [c for name in FAMILIES for c in _families_claim(ev, name)]


def _gaits_claim(ev: Evidence, what: str, names: tuple[str, ...]) -> list[str]:
    """One claim: the body's problems with no guess, each gait re-simulated here."""
    records = [r for r in (ev.summary(name) for name in names) if r is not None]
    if not records:
        return []
    params = Params(**records[0]["params"])
    body = groups(params)
    gaits = "; ".join(_gait_text(ev, r) for r in records)
    stable = sum(1 for r in records if r["stable"])
    return [claim(
        f"Gaits of {what.split(' (')[0]}, found from the body alone",
        "one body (m 1 kg, rho0 0.2 m); its gaits start from guesses written by hand.",
        f"{what}: m = {params.m:g} kg, I = {params.I:g} kg m^2, k = {params.k:g} N/m, rho0 = {params.rho0:g} m, "
        f"d = {params.d:g} m (groups k rho0/(m g) = {body.stiffness:.4g}, I/(m rho0^2) = {body.inertia:.4g}, "
        f"d/rho0 = {body.offset:.4g}; the thesis's: 20.39, 0.0825, 0.2), problems with no guess: {gaits}. "
        f"{stable} of {len(records)} stable.",
        "beyond the thesis: a gait at each law and posture asked, with no guess",
        "Each start is one shipped gait carried to this body and continued to the cell (baslip.gait.anybody); the "
        "answer is one gait per law and posture, the one nearest that start. These radii say whether these gaits "
        "are stable, not whether a stable one exists: the families studies and atlases below search the families.",
    )]


def _atlas_claim(ev: Evidence) -> list[str]:
    """The one-cell PD atlas of the human body with no guess: what it covered and its most
    stable gait, re-simulated here."""
    summary, cells = ev.summary(HUMAN_ATLAS), ev.rows(HUMAN_ATLAS, "cells.csv")
    if summary is None or not summary.get("best") or not cells:
        return []
    params = Params(**summary["provenance"]["problem"]["params"])
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


def _families_claim(ev: Evidence, name: str) -> list[str]:
    """A families study's answer: its pieces, its best gait re-simulated here, and how
    wide its search was."""
    summary = ev.summary(name)
    if summary is None or "answer" not in summary:
        return []
    answer, problem = summary["answer"], summary["provenance"]["problem"]
    params, law = Params(**problem["params"]), HIP_LAWS[problem.get("hip_law", "pd")]
    cell = ", ".join(quantity_text(n, v, 4) for n, v in answer["cell"].items())
    searched = answer["searched"]
    region = ", ".join(f"{n} in [{_bound_text(n, lo)}, {_bound_text(n, hi)}]" for n, (lo, hi) in searched["region"].items()
                       if n in law.drawn or n == "theta_h")
    best = min(answer["best"], key=lambda b: b["spectral_radius"], default=None)
    if best is None:
        found = "no gait found" if not answer["pieces"] else "no polished gait"
        verdict = f"beyond the thesis: {found} in the search"
    else:
        independent = ev.resimulate(best, law, params)
        found = (f"most stable polished gait: spectral radius {best['spectral_radius']:.4g} "
                 f"({'stable' if best['stable'] else 'unstable'}), theta_h = {best['theta_h'] * DEG:.1f} deg at the apex, "
                 f"trunk {best['trunk_min_deg']:.1f} to {best['trunk_max_deg']:.1f} deg, "
                 + ", ".join(quantity_text(n, best[n], 4) for n in law.controls.names)
                 + f"; independent re-simulation eps = {independent:.1e} (erk, 1e-13)")
        verdict = ("beyond the thesis: a stable gait exists at this cell" if best["stable"]
                   else "beyond the thesis: no stable gait found in the search")
    pieces = "; ".join(f"piece {p['piece']}: {p['charts']} charts, least radius {p['least_radius']:.4g}, stable share "
                       f"{100 * (p['stable_share'] or 0):.1f}%" for p in answer["pieces"]) or "none"
    return [claim(
        f"Which gaits exist: `{name}`",
        "not asked (one body, gaits from hand-written guesses).",
        f"a families study at {cell} ({problem.get('posture', 'any')} trunk, no guess): pieces: {pieces}; {found}. "
        f"Searched: {searched['seeds']} seeds ({searched['seeds_failed']} failed), {searched['charts']} of at most "
        f"{searched['max_charts']} charts, {'covered whole' if searched['covered_whole'] else 'not covered whole'}, "
        f"within {region}.",
        verdict,
        "A stable gait found is a fact whatever the covering; where none is found, the answer is only as wide as "
        "the search: this cell, these bounds, the pieces its seeds reached and the charts it made.",
        [f"{name}/atlas.png"],
    )]


def _bound_text(name: str, value: float) -> str:
    return f"{value * DEG:.0f} deg" if name.startswith("theta") else f"{value:.4g}"
