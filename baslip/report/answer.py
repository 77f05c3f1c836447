"""The report's short answer to "can an upright BA-SLIP run stably?", under three laws of
control (constant PD, constant VPP, event-based feedback), read off the committed atlases
and controller comparisons; the claims that follow it give the evidence."""

from __future__ import annotations

import math

from baslip.model.dynamics import Params
from baslip.report.atlas import CAPPED_ATLAS, capped_whole, covered_whole
from baslip.report.controllers import CONTROLLER_GAITS, best_controller
from baslip.report.evidence import DEG, Evidence
from baslip.report.vpp import VPP_ATLASES


def upright_answer(ev: Evidence) -> str:
    """Three bullets, one per law, each only as wide as the study behind it; empty if none ran."""
    bullets = [text for text in (_pd(ev), _vpp(ev), _feedback(ev)) if text]
    if not bullets:
        return ""
    return "**In short**, for the studies below:\n\n" + "\n".join(f"- {b}" for b in bullets) + "\n"


#: The other searches of the upright PD family whose verified gaits the short answer
#: counts beside the atlas's: its least radii are the least over all of them.
UPRIGHT_SEARCHES = ("optimal_upright", "optimal_upright_schur", CAPPED_ATLAS)


def _pd(ev: Evidence) -> str:
    summary = ev.summary("atlas_upright")
    if summary is None or not summary.get("complete"):
        return ""
    cells = summary["cells"]

    def least(*keys: str) -> float:
        values = [c[k] for c in cells for k in keys if c.get(k) is not None]
        return min(values) if values else math.inf

    apex = least("least_radius_upright_apex", "polished_radius")
    throughout = least("least_radius_upright_throughout", "polished_upright_throughout_radius")
    stable_cells = sum(1 for c in cells if min(c.get("least_radius_upright_apex") or math.inf,
                                               c.get("polished_radius") or math.inf) < 1)
    searched_apex, searched_throughout = (_searched_least(ev, key)
                                          for key in ("least_upright_at_apex", "least_upright_throughout"))
    if apex < 1:
        at_apex = f"yes: a stable gait in {stable_cells} of the {len(cells)} (ydot, z) cells of `atlas_upright`"
    elif searched_apex[0] < 1:
        at_apex = f"yes, by `{searched_apex[1]}`: none in the {len(cells)} (ydot, z) cells of `atlas_upright`"
    else:
        at_apex = f"no stable gait in its {len(cells)} (ydot, z) cells"
    at_apex_radius = _least_text(apex, searched_apex)
    throughout_found = "yes" if min(throughout, searched_throughout[0]) < 1 else "none found"
    whole = sum(1 for c in cells if c["complete"] is True)
    return (f"**Constant PD:** upright at the apex, {at_apex}, least spectral radius {at_apex_radius}. Upright "
            f"throughout the stride (within 45 deg of vertical at every instant): "
            f"{throughout_found}, least radius {_least_text(throughout, searched_throughout)}. Within the bounds "
            f"and the pieces its seeds reached; {whole} of the {len(cells)} cells "
            f"{covered_whole(summary['provenance']['problem']['study'])}{capped_whole(ev)}.")


def _searched_least(ev: Evidence, key: str) -> tuple[float, str, dict]:
    """(least radius, study, its gait's record) of ``key`` (a meaning of upright) over the
    committed :data:`UPRIGHT_SEARCHES`; (inf, "", {}) where none has one."""
    found: tuple[float, str, dict] = (math.inf, "", {})
    for name in UPRIGHT_SEARCHES:
        gait = _least_gait(ev.summary(name) or {}, key)
        if gait and gait["spectral_radius"] < found[0]:
            found = (gait["spectral_radius"], name, gait)
    return found


#: The meaning of upright each key of a search's summary stands for, as an atlas's
#: polished gaits (``best``) mark it.
_ATLAS_MEANING = {"least_upright_at_apex": "upright_apex", "least_upright_throughout": "upright_throughout"}


def _least_gait(summary: dict, key: str) -> dict | None:
    """The least-radius gait of ``key`` in a search's summary: its own record, or, for an
    atlas, the least of its polished gaits with that meaning of upright."""
    if summary.get("kind") != "atlas":
        return summary.get(key)
    gaits = [b for b in summary.get("best", []) if b.get(_ATLAS_MEANING[key]) is True]
    return min(gaits, key=lambda b: b["spectral_radius"], default=None)


def _least_text(atlas: float, searched: tuple[float, str, dict]) -> str:
    """The least radius of the atlas, or the searches' where one found less (named, so
    that the short answer never states a least above a gait the report shows)."""
    radius, name, gait = searched
    if radius >= atlas:
        return f"{atlas:.3f}"
    return (f"{radius:.3f} (found by `{name}` at ydot = {gait['ydot']:g} m/s, z = {gait['z']:g} m; the atlas's "
            f"own least is {atlas:.3f})")


def _vpp(ev: Evidence) -> str:
    parts, stable_charts = [], []
    for name, scale in VPP_ATLASES.items():
        summary = ev.summary(name)
        if summary is None or not summary.get("complete"):
            continue
        params = Params(**summary["provenance"]["problem"]["params"])
        cells = ev.rows(name, "cells.csv")
        stable_charts += [c for c in ev.rows(name, "atlas.csv") if c["status"] == "converged" and c["stable"] is True]
        stable = sorted(c["sweep_ydot"] for c in cells if isinstance(c["stable_share"], float) and c["stable_share"] > 0)
        # The polished gaits where the atlas polished its best charts, else the charts.
        radius = min(min(c["least_radius"], c["polished_radius"] or math.inf) for c in cells)
        speeds = f"{min(c['sweep_ydot'] for c in cells):g} to {max(c['sweep_ydot'] for c in cells):g} m/s"
        if stable:
            froude = stable[0] / math.sqrt(params.g * params.rho0)
            parts.append(f"at the {scale} from {stable[0]:g} m/s (Froude number {froude:.2f}) of {speeds}, "
                         f"least radius {radius:.3f}")
        else:
            parts.append(f"at the {scale}, no stable gait over {speeds}")
    if not parts:
        return ""
    if not stable_charts:
        return "**Constant VPP:** no stable gait in `" + "`, `".join(VPP_ATLASES) + "`: " + "; ".join(parts) + "."
    upright = sum(1 for c in stable_charts if c["upright_throughout"] is True)
    low = min(c["theta_h_min"] for c in stable_charts) * DEG
    high = max(c["theta_h_max"] for c in stable_charts) * DEG
    return ("**Constant VPP:** yes: " + "; ".join(parts) + f". Of its {len(stable_charts)} stable charts, "
            f"{upright} are upright throughout the stride (the trunk between {low:.1f} and {high:.1f} deg).")


def _feedback(ev: Evidence) -> str:
    parts = []
    for name, gait in CONTROLLER_GAITS.items():
        summary = ev.summary(name)
        if summary is None or "basins" not in summary:
            continue
        controller = best_controller(summary)
        basin = summary["basins"][controller]
        largest = basin["largest_90_box"]
        reach = f"90 % back up to the {largest:g}x box" if largest is not None else "no box with 90 % back"
        parts.append(f"{gait}: {controller} ({reach})")
    if not parts:
        return ""
    return ("**Event-based feedback:** the best controller of each gait, by its measured basin: "
            + "; ".join(parts) + ".")
