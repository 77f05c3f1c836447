"""The section beyond the thesis on other bodies: gaits found from the body alone."""

from __future__ import annotations

from baslip.model.dynamics import Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.quantities import posture_of, quantity_text
from baslip.model.similarity import groups
from baslip.report.evidence import Evidence, claim

#: The shipped problems of the human-sized body with no guess.
HUMAN_GAITS = ("human_pd_hanging", "human_pd_upright", "human_vpp_3ms")


def body_claims(ev: Evidence) -> list[str]:
    """The human-sized runner's gaits found from the body alone, each verified again."""
    records = [r for r in (ev.summary(name) for name in HUMAN_GAITS) if r is not None]
    if not records:
        return ["Not run.\n"]
    params = Params(**records[0]["params"])
    body = groups(params)
    gaits = "; ".join(_gait_text(ev, r) for r in records)
    stable = sum(1 for r in records if r["stable"])
    return [claim(
        "Gaits of a human-sized runner, found from the body alone",
        "one body (m 1 kg, rho0 0.2 m); its gaits start from guesses written by hand.",
        f"a body of m = {params.m:g} kg, I = {params.I:g} kg m^2, k = {params.k:g} N/m, rho0 = {params.rho0:g} m, "
        f"d = {params.d:g} m (groups k rho0/(m g) = {body.stiffness:.4g}, I/(m rho0^2) = {body.inertia:.4g}, "
        f"d/rho0 = {body.offset:.4g}; the thesis's: 20.39, 0.0825, 0.2), problems with no guess: {gaits}. "
        f"{stable} of {len(records)} stable.",
        "beyond the thesis: a gait at each law and posture asked, with no guess",
        "Each start is one shipped gait carried to this body and continued to the cell (baslip.gait.anybody); the "
        "answer is one gait per law and posture, the one nearest that start. No search for the most stable gait "
        "at this cell was made here, so these radii say that these gaits are unstable, not that no stable one "
        "exists; the VPP atlas of the human body (atlas_vpp_human) covers that law's family.",
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
