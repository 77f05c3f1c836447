"""The section beyond the thesis on models of one's own: the SLIP as a description of its
own against the BA-SLIP's SLIP limit, the guide's hopper, the bipedal walker, and the
BA-SLIP's third hip law, the virtual constraint.

Every point a claim quotes is re-simulated here by the described model's independent
stride (:meth:`baslip.gait.modelsolver.ModelSolver.verify`), as the BA-SLIP's claims are
by the event map.
"""

from __future__ import annotations

from dataclasses import replace

from baslip.engine.hybrid import Resolution
from baslip.gait.modelsolver import ModelSolver
from baslip.problem.model_file import ModelProblem, load_any_problem
from baslip.problem.shipped import problems_dir
from baslip.report.evidence import DEG, Evidence, claim

#: The SLIP's runs and the BA-SLIP limit's runs they are set against.
SLIP_BRANCH, SLIP_LIMIT_BRANCH = "slip_attack", "continuation_slip_attack"
SLIP_CURVES, SLIP_LIMIT_CURVES = "slip_band", "curve_slip_band"
#: The guide's hopper, covered at one height, and its controllers.
HOPPER_ATLAS, HOPPER_CONTROLLERS = "hopper_atlas", "hopper_controllers"
#: The bipedal walker's branch and the edges of its stable walks, its atlas and its controllers.
WALKER, WALKER_ATLAS, WALKER_CONTROLLERS = "walker", "walker_atlas", "walker_controllers"
#: The SLIP's runs at the walker's body and energy, and the figure of both.
RUNNING, WALKING_AND_RUNNING = "slip_walker_energy", "walking_and_running/walking_and_running.png"
#: The virtual-constraint law's gait continued in its gain, and its controllers.
VIRTUAL_CONSTRAINT, VIRTUAL_CONSTRAINT_CONTROLLERS = "virtual_constraint", "virtual_constraint_controllers"
#: The third law at the thesis's own cell, continued in the constraint's slope.
VIRTUAL_CONSTRAINT_SLOW = "virtual_constraint_slow"
#: The third law at the human body: its gait continued in the constraint's slope, and its controllers.
VIRTUAL_CONSTRAINT_HUMAN = "virtual_constraint_human"
#: The three hip laws' gaits under one controllers study, at each body's cell: law and run.
HIP_LAWS = (
    ("the thesis's body and cell (0.4 m, 0.5 m/s)", (("pd", "hip_laws_thesis_pd"), ("vpp", "hip_laws_thesis_vpp"),
                                                     ("virtual_constraint", "hip_laws_thesis_virtual_constraint"))),
    ("the human body and a cell of its (1.06 m, 3 m/s)", (("pd", "hip_laws_human_pd"), ("vpp", "hip_laws_human_vpp"),
                                                          ("virtual_constraint", "hip_laws_human_virtual_constraint"))),
)
#: Mid-stance leg speed [m/s] below which a walk counts as symmetric.
SYMMETRIC = 1e-8
#: The independent stride's grid [s] when re-simulating a quoted point.
CHECK_GRID = 0.005


def model_claims(ev: Evidence) -> list[str]:
    """The SLIP's band against the BA-SLIP limit's, the hopper's atlas and controllers,
    the walker's stable walks, the virtual constraint's gaits at two bodies, and the
    three hip laws under one controllers study."""
    claims = (_slip_band_claim(ev) + _slip_curves_claim(ev) + _hopper_claim(ev) + _controllers_claim(ev)
              + _walker_claim(ev) + _virtual_constraint_claim(ev) + _virtual_constraint_human_claim(ev) + _hip_laws_claim(ev))
    return claims or ["Not run.\n"]


def _problem(name: str) -> ModelProblem | None:
    problem = load_any_problem(problems_dir() / f"{name}.yaml")
    return problem if isinstance(problem, ModelProblem) else None


def _again(problem: ModelProblem, values: dict) -> float:
    """The independent stride's return error at ``values``, re-simulated here."""
    solver = ModelSolver(problem.spec)
    moved = {k: values[k] for k in problem.spec.fixed_invariants if k in values}
    spec = replace(problem.spec, fixed={**problem.spec.fixed, **moved})
    found = solver.verify(spec, values, Resolution(CHECK_GRID, 8))
    return float("inf") if isinstance(found, str) else found


def _slip_band_claim(ev: Evidence) -> list[str]:
    ours, limit = ev.summary(SLIP_BRANCH), ev.summary(SLIP_LIMIT_BRANCH)
    problem = _problem(SLIP_BRANCH)
    if ours is None or limit is None or problem is None:
        return []
    edges = {p["special"]: p for p in ours["branch"]["special_points"]}
    theirs = {p["type"]: p for p in limit["special_points"] if p["branch"] == 0}
    parts, worst = [], 0.0
    for kind in ("period_doubling", "fold"):
        if kind not in edges or kind not in theirs:
            return []
        difference = abs(edges[kind]["theta_td"] - theirs[kind]["theta_td"])
        worst = max(worst, difference)
        parts.append(f"{kind.replace('_', ' ')} at theta_td = {edges[kind]['theta_td'] * DEG:.6f} deg "
                     f"(BA-SLIP limit: {theirs[kind]['theta_td'] * DEG:.6f} deg; re-simulated here, "
                     f"eps = {_again(problem, edges[kind]):.1e})")
    verdict = "agrees" if worst <= 1e-6 else "differs"
    return [claim(
        "The SLIP as a model of its own has the BA-SLIP's SLIP band",
        "not in the thesis; the band is that of Seyfarth et al. (2002), at the energy of 5 m/s at 1 m.",
        f"`model: slip`, a description of a dozen lines of physics run by the generic engine, continued in the "
        f"touchdown angle from 20 to 25 deg ({ours['branch']['points']} points, {ours['branch']['verified']} "
        f"verified): {'; '.join(parts)}; largest difference {worst:.1e} rad.",
        f"{verdict}: the band's two edges, to {worst:.0e} rad",
        "Two implementations of one model: the SLIP described in baslip.model.catalogue.slip (point mass, polar "
        "stance coordinates, the generic DOP853 engine, CVODES verification) and the BA-SLIP with d = 0 and no "
        "torque on its compiled engine. How wide: one energy, one branch each.",
        (f"{SLIP_BRANCH}/branch.png",),
    )]


def _slip_curves_claim(ev: Evidence) -> list[str]:
    ours, theirs = ev.rows(SLIP_CURVES, "curve.csv"), ev.rows(SLIP_LIMIT_CURVES, "curve.csv")
    problem = _problem(SLIP_CURVES)
    if not ours or not theirs or problem is None:
        return []
    parts, worst = [], 0.0
    for kind in ("period_doubling", "fold"):
        mine = [r for r in ours if r["type"] == kind]
        limit = [r for r in theirs if r["type"] == kind]
        if not mine or not limit:
            return []
        for end in (0, -1):
            row = min(mine, key=lambda r: abs(r["energy"] - limit[end]["energy"]))
            if abs(row["energy"] - limit[end]["energy"]) > 1e-6:
                return []
            worst = max(worst, abs(row["theta_td"] - limit[end]["theta_td"]))
        parts.append(f"{kind.replace('_', ' ')} from {mine[0]['theta_td'] * DEG:.5f} deg at "
                     f"{mine[0]['energy']:.1f} J to {mine[-1]['theta_td'] * DEG:.5f} deg at {mine[-1]['energy']:.1f} J "
                     f"({len(mine)} points, largest eps {max(r['verification'] for r in mine):.1e}; an end "
                     f"re-simulated here: eps = {_again(problem, mine[-1]):.1e})")
    verdict = "agrees" if worst <= 1e-8 else "differs"
    return [claim(
        "The SLIP's band edges as curves in touchdown angle and energy",
        "not in the thesis.",
        f"`slip_band` follows both edges from 4 to 6 m/s at 1 m (1424.8 to 2224.8 J): {'; '.join(parts)}. At both "
        f"ends of both curves the touchdown angle is that of the BA-SLIP limit's curves (curve_slip_band) to "
        f"{worst:.1e} rad.",
        f"{verdict}: both curves, at both ends, to {worst:.0e} rad",
        "The described model's curves restrict the map to the energy's level set, and take second derivatives "
        "by differences of exact Jacobians; the BA-SLIP's deflate its structural multipliers and take exact "
        "Hessian-vector products. How wide: the energy range of the committed curves.",
        (f"{SLIP_CURVES}/curve.png",),
    )]


def _hopper_claim(ev: Evidence) -> list[str]:
    summary, charts = ev.summary(HOPPER_ATLAS), ev.rows(HOPPER_ATLAS, "charts.csv")
    problem = _problem(HOPPER_ATLAS)
    if summary is None or not charts or problem is None:
        return []
    atlas = summary["atlas"]
    stable = [c for c in charts if c["stable"] and c["verification"] <= problem.spec.tolerance]
    best = min(charts, key=lambda c: c["spectral_radius"])
    speeds = f"{min(c['ydot'] for c in stable):.2f} to {max(c['ydot'] for c in stable):.2f} m/s" if stable else "none"
    return [claim(
        "A model written by a user: the hopper with leg damping",
        "not in the thesis.",
        f"The guide's hopper (problems/models/hopper.py: a point mass on a damped spring leg that pushes at the "
        f"bottom) at a 1 m apex, its gaits covered by an atlas in forward speed, touchdown angle and push: "
        f"{atlas['charts']} charts, {atlas['verified']} verified, {atlas['pieces']} piece, "
        f"{'complete' if atlas['complete'] else 'not complete'}; stable chart centres at {speeds}. The least "
        f"spectral radius {best['spectral_radius']:.4f} at ydot = {best['ydot']:.3f} m/s, theta_td = "
        f"{best['theta_td'] * DEG:.3f} deg, push = {best['push'] * 100:.3f} cm (re-simulated here, "
        f"eps = {_again(problem, best):.1e}).",
        "beyond the thesis: a model of one's own, solved, verified and covered from its description",
        "How wide: one apex height, forward speeds from 2 to 12 m/s, push from 0 to 0.2 m; stability is read at "
        "the chart centres (the charts' radii bound how far between them it is known).",
        (f"{HOPPER_ATLAS}/atlas.png",),
    )]



def _controllers_claim(ev: Evidence) -> list[str]:
    summary = ev.summary(HOPPER_CONTROLLERS)
    if summary is None or "controllers" not in summary:
        return []
    study = summary["controllers"]
    parts = [f"{c['name']} {c['returned']} of {c['starts']} ({100 * c['interval'][0]:.0f}-"
             f"{100 * c['interval'][1]:.0f} %, closed-loop radius {c['spectral_radius']:.3g})"
             for c in study["controllers"]]
    gait = summary["gait"]
    return [claim(
        "Controllers with measured basins, for a model written by a user",
        "not in the thesis.",
        f"The guide's hopper at 1 m and 5 m/s, an unstable gait (spectral radius {gait['spectral_radius']:.4f}, "
        f"verified to {gait['verification']:.1e}); its controllers on the touchdown angle and the push, each run "
        f"{study['strides']} strides from a {study['grid']} x {study['grid']} grid within "
        f"{100 * study['spread']:.0f} % of the apex height and speed, returned within {study['returned_within']:g}: "
        f"{'; '.join(parts)} (95 % Wilson intervals).",
        "beyond the thesis: feedback designed from a description's exact Jacobians stabilises its unstable gait",
        "How wide: one gait, one grid in the two section coordinates, the law's two controls. A start below the "
        "touchdown height cannot land at the gait's angle, whatever the first stride's correction, which bounds "
        "every basin at small heights.",
        (f"{HOPPER_CONTROLLERS}/basins.png",),
    )]


def _walker_claim(ev: Evidence) -> list[str]:
    summary, curve = ev.summary(WALKER), ev.rows(WALKER, "curve.csv")
    problem = _problem(WALKER)
    if summary is None or not curve or problem is None:
        return []
    edges = {p["special"]: p for p in reversed(summary["branch"]["special_points"])}  # the first of each kind
    if "branch_point" not in edges or "neimark_sacker" not in edges:
        return []
    low, high = edges["branch_point"], edges["neimark_sacker"]
    if abs(high["rhodot"]) >= SYMMETRIC:  # the claim is of the symmetric walk's edge
        return []
    # Past a 1:1 resonance the curve goes on as a neutral saddle (real multipliers whose
    # product is 1), which is no edge of stability: the edge ends at the first one.
    curves = {c["type"]: c for c in summary.get("curves", [])}
    resonances = [p for p in curves.get("neimark_sacker", {}).get("codimension_two", [])
                  if p["type"] == "resonance_1_1"]
    if not resonances:
        return []
    resonance = max(resonances, key=lambda p: p["theta_td"])
    rows = [r for r in curve if r["type"] == "neimark_sacker" and r["verification"] <= problem.spec.tolerance
            and r["theta_td"] >= resonance["theta_td"]]
    softest = min(rows, key=lambda r: r["k"])
    stiffness = problem.spec.fixed["k"] / 1e3
    return [claim(
        "The bipedal spring-mass walker: two stances a step, no flight",
        "not in the thesis; the model is Geyer, Seyfarth and Blickhan's (2006).",
        f"`model: walker` at 80 kg, 1 m legs and 820 J. Its walks at {stiffness:g} kN/m, continued in the landing "
        f"angle from the reference walk with no guess ({summary['branch']['points']} points, "
        f"{summary['branch']['verified']} verified): the symmetric walk (no leg speed at mid-stance) is stable "
        f"from the symmetry-breaking branch point at theta_td = {low['theta_td'] * DEG:.3f} deg to the "
        f"Neimark-Sacker point at {high['theta_td'] * DEG:.3f} deg from the vertical, that is "
        f"{90 - high['theta_td'] * DEG:.2f} to {90 - low['theta_td'] * DEG:.2f} deg from the ground (re-simulated "
        f"here: eps = {_again(problem, low):.1e} and {_again(problem, high):.1e}). The Neimark-Sacker curve, "
        f"stiffer than which the symmetric walk is unstable, runs from {softest['k'] / 1e3:.2f} kN/m at "
        f"{softest['theta_td'] * DEG:.2f} deg to a 1:1 resonance at {resonance['k'] / 1e3:.2f} kN/m and "
        f"{resonance['theta_td'] * DEG:.2f} deg ({len(rows)} verified points), past which it is a neutral "
        f"saddle, no edge.{_walker_atlas_and_basins(ev)}{_running_beside(ev)}",
        "beyond the thesis: a walker's stable walks and their edges, from its description",
        "How wide: one body and one energy; the branch at one stiffness, from 14 to 28 deg, and the edges from "
        "5 to 40 kN/m. tests/test_catalogue.py solves walks 3 % either side of the curve at three angles: softer "
        "stable, stiffer unstable. Not set against Geyer et al.'s published region: its numbers were not at hand.",
        (f"{WALKER}/branch.png", f"{WALKER}/curve.png", f"{WALKER_ATLAS}/atlas.png", f"{WALKER_CONTROLLERS}/basins.png",
         *((WALKING_AND_RUNNING,) if (ev.results / WALKING_AND_RUNNING).exists() else ())),
    )]


def _running_beside(ev: Evidence) -> str:
    """The SLIP's runs at the walker's body and energy, as a sentence (empty where not run)."""
    rows = [r for r in ev.rows(RUNNING, "branch.csv") if r["verification"] <= 1e-10]
    if not rows:
        return ""
    steepest = max(rows, key=lambda r: r["theta_td"])
    stable = sum(r["stable"] for r in rows)
    verdict = (f"{stable} of them stable" if stable else
               f"every one unstable (radius {min(r['spectral_radius'] for r in rows):.3g} at least)")
    return (f" Running at the same body, stiffness and energy (the SLIP, {RUNNING}: {len(rows)} verified runs "
            f"continued in the landing angle): runs exist only from {min(r['theta_td'] for r in rows) * DEG:.1f} "
            f"to {steepest['theta_td'] * DEG:.2f} deg from the vertical, where the flight vanishes (apex "
            f"{steepest['z']:.4f} m), {verdict}. Both are drawn in {WALKING_AND_RUNNING}.")


def _walker_atlas_and_basins(ev: Evidence) -> str:
    """The walker's atlas in landing angle and stiffness, and its controllers' basins, as
    sentences of its claim (empty where not run)."""
    text = ""
    atlas = (ev.summary(WALKER_ATLAS) or {}).get("atlas")
    if atlas:
        text += (f" An atlas of the walks at 820 J in landing angle (15 to 28 deg) and stiffness (8 to 30 kN/m): "
                 f"{atlas['charts']} charts, {atlas['verified']} verified, {atlas['stable']} stable, "
                 f"{'complete' if atlas['complete'] else 'not complete'}; the stable ones lie below the curve.")
    controllers = (ev.summary(WALKER_CONTROLLERS) or {}).get("controllers")
    if controllers:
        parts = [f"{c['name']} {c['returned']} of {c['starts']} ({100 * c['interval'][0]:.0f}-"
                 f"{100 * c['interval'][1]:.0f} %, radius {c['spectral_radius']:.3g})"
                 for c in controllers["controllers"]]
        text += (f" The unstable reference walk (20 kN/m) under controllers on the landing angle, from starts on "
                 f"its energy level: {'; '.join(parts)} (95 % Wilson intervals).")
    return text


def _stable_branch(ev: Evidence, name: str) -> tuple[ModelProblem, list[dict], list[dict], list[dict]] | None:
    """A shipped branch's problem, its rows, its verified rows and its stable verified
    ones; None where it has not run or has no stable point."""
    summary, rows, problem = ev.summary(name), ev.rows(name, "branch.csv"), _problem(name)
    if summary is None or not rows or problem is None:
        return None
    verified = [r for r in rows if r["verification"] <= problem.spec.tolerance]
    stable = [r for r in verified if r["stable"]]
    return (problem, rows, verified, stable) if stable else None


def _virtual_constraint_claim(ev: Evidence) -> list[str]:
    found = _stable_branch(ev, VIRTUAL_CONSTRAINT)
    if found is None:
        return []
    problem, rows, verified, stable = found
    first, last = min(stable, key=lambda r: r["omega"]), max(verified, key=lambda r: r["omega"])
    fixed = problem.spec.fixed
    return [claim(
        "A third hip law: the trunk on a virtual constraint",
        "not in the thesis; the law is the hybrid-zero-dynamics view of Poulakakis and Grizzle (2009), on the "
        "thesis's model.",
        f"`model: ba-slip-described`, `law: virtual_constraint`: the hip torque holds the trunk angle on "
        f"trunk_angle + {fixed['trunk_slope']:g} theta1 by input-output linearisation, its error critically damped "
        f"at the gain omega. At the thesis's body, a {fixed['z']:g} m apex and {fixed['ydot']:g} m/s, continued in "
        f"omega from 10 to 400 1/s ({len(rows)} points, {len(verified)} verified): unstable at small gains, stable "
        f"from omega = {first['omega']:.1f} 1/s (spectral radius {first['spectral_radius']:.4f}) on, and at "
        f"{last['omega']:.0f} 1/s {last['spectral_radius']:.4f} (trunk angle {last['trunk_angle'] * DEG:.2f} deg at "
        f"a vertical leg; re-simulated here: eps = {_again(problem, last):.1e}). As omega grows the gait's "
        "radius falls towards a limit, the hybrid zero dynamics' (at slope 0, tests/test_virtual_constraint.py "
        f"shows the trunk's two multipliers dying out and the others staying).{_law_basins(ev)}",
        "beyond the thesis: a third hip law whose gaits are found, verified and stable from a gain on",
        "How wide: one body, one apex height and speed, one slope of the constraint. With the trunk held upright "
        "(slope 0) the zero dynamics keep a multiplier 1, the gaits at fixed controls forming a curve, so the slope "
        "is what makes them attract here. The basins are of the described model's controllers on the law's four "
        "controls, not of the BA-SLIP's controller studies of PD and VPP (another design and another box), so the "
        "two do not compare number for number; \"The three hip laws side by side\" below sets them under one "
        f"study, at this body's slow cell and at the human body.{_slow_cell(ev)}",
        (f"{VIRTUAL_CONSTRAINT}/branch.png", f"{VIRTUAL_CONSTRAINT_CONTROLLERS}/basins.png"),
    )]


def _slow_cell(ev: Evidence) -> str:
    """The third law at the thesis's own cell, continued in the slope, as a sentence (empty
    where not run)."""
    rows = [r for r in ev.rows(VIRTUAL_CONSTRAINT_SLOW, "branch.csv") if r["verification"] <= 1e-10]
    if not rows:
        return ""
    least = min(rows, key=lambda r: r["spectral_radius"])
    stable = sum(r["stable"] for r in rows)
    return (f" At the thesis's own cell (0.4 m, 0.5 m/s, omega 100 1/s), continued in the slope from -1 to 1.5 "
            f"({VIRTUAL_CONSTRAINT_SLOW}, {len(rows)} verified points), {stable or 'none'} of its gaits "
            f"{'is' if stable == 1 else 'are'} stable; the least radius is {least['spectral_radius']:.4f}, at "
            f"slope {least['trunk_slope']:.3f}.")


def _law_basins(ev: Evidence) -> str:
    """The third law's controllers and their basins, as a sentence (empty where not run)."""
    summary = ev.summary(VIRTUAL_CONSTRAINT_CONTROLLERS)
    if summary is None or "controllers" not in summary:
        return ""
    study = summary["controllers"]
    parts = [f"{c['name']} {c['returned']} of {c['starts']} ({100 * c['interval'][0]:.0f}-"
             f"{100 * c['interval'][1]:.0f} %, radius {c['spectral_radius']:.3g})" for c in study["controllers"]]
    return (f" At omega = {summary['gait']['values']['omega']:g} 1/s, from a {study['grid']} x {study['grid']} grid "
            f"within {100 * study['spread']:.0f} % of the apex height and trunk angle, back within "
            f"{study['returned_within']:g} in {study['strides']} strides: {'; '.join(parts)} (95 % Wilson "
            "intervals; at the open loop's radius an error of 20 % takes some 200 strides to shrink to 0.1 %).")


def _virtual_constraint_human_claim(ev: Evidence) -> list[str]:
    found = _stable_branch(ev, VIRTUAL_CONSTRAINT_HUMAN)
    if found is None:
        return []
    problem, rows, verified, stable = found
    low, high = min(stable, key=lambda r: r["trunk_slope"]), max(stable, key=lambda r: r["trunk_slope"])
    best = min(stable, key=lambda r: r["spectral_radius"])
    fixed = problem.spec.fixed
    return [claim(
        "The third hip law at the human body",
        "not in the thesis.",
        f"The virtual constraint at the human body (80 kg, leg 1 m, 20 kN/m, hip 0.1 m from the CoM), a "
        f"{fixed['z']:g} m apex and {fixed['ydot']:g} m/s, omega = {fixed['omega']:g} 1/s, continued in the "
        f"constraint's slope from -1 to 1.5 ({len(rows)} points, {len(verified)} verified): stable for slopes from "
        f"{low['trunk_slope']:.3f} to {high['trunk_slope']:.3f} (between two Neimark-Sacker points), the least "
        f"spectral radius {best['spectral_radius']:.4f} at slope {best['trunk_slope']:.3f} (re-simulated here: "
        f"eps = {_again(problem, best):.1e}); unstable at the slope 0.2 of the thesis body's study.",
        "beyond the thesis: the third law runs stably at the human body, for a band of slopes",
        "How wide: one body, one apex height and speed, one gain omega.",
        (f"{VIRTUAL_CONSTRAINT_HUMAN}/branch.png",),
    )]


def _hip_laws_claim(ev: Evidence) -> list[str]:
    tables = [(body, _hip_laws_table(ev, runs)) for body, runs in HIP_LAWS]
    tables = [(body, table) for body, table in tables if table]
    if not tables:
        return []
    text = "\n\n".join(f"At {body}:\n\n{table}" for body, table in tables)
    return [claim(
        "The three hip laws side by side, under one controllers study",
        "not in the thesis (it has the PD law alone).",
        "Each law's gait on the BA-SLIP's description (`model: ba-slip-described`) under the described model's "
        "controllers study: stride-to-stride feedback on all the law's controls (open loop, deadbeat where the "
        "controls reach every coordinate, LQR), from a 9 x 9 grid within 20 % of the gait's own apex height and "
        "trunk angle, each start run 100 strides and counted when back within 1e-3 of the gait (95 % Wilson "
        "intervals); the rest either fell or kept running elsewhere.\n\n"
        f"{text}\n",
        "beyond the thesis: the field's three hip laws measured by one yardstick, at two bodies",
        "How wide: one cell per body, one gait per law: the most stable one known at the cell (PD's from the "
        "shipped downward gait and atlas_human_pd; the virtual constraint's from its slope branches; VPP has no "
        "stable gait at either cell, per atlas_vpp and atlas_vpp_human, so its shipped upright gait stands). The "
        "grid is relative to each gait's own trunk angle, so the boxes differ by law; it is wide, and many "
        "starts fall within a stride. An upright VPP gait is one of a family whose multiplier 1 no control moves; "
        "a start that settles on a neighbour is not counted here, where the BA-SLIP's controllers study above "
        "counts it, and that study's small boxes and 4,000 starts are another design: the two do not compare "
        "number for number.",
        tuple(f"{name}/basins.png" for _, runs in HIP_LAWS for _, name in runs if ev.summary(name) is not None),
    )]


def _hip_laws_table(ev: Evidence, runs: tuple[tuple[str, str], ...]) -> str:
    """The laws' gaits at one cell and their controllers' basins, as a table ('' if none ran)."""
    lines = ["| law | gait's spectral radius | open loop | deadbeat | LQR |", "|---|---|---|---|---|"]
    for law, name in runs:
        summary = ev.summary(name)
        if summary is None or "controllers" not in summary:
            continue
        found = {c["name"]: c for c in summary["controllers"]["controllers"]}
        cells = [_share(found[c]) if c in found else "none" for c in ("constant", "deadbeat", "lqr")]
        lines.append(f"| {law} | {summary['gait']['spectral_radius']:.4g} | {' | '.join(cells)} |")
    return "\n".join(lines) if len(lines) > 2 else ""


def _share(controller: dict) -> str:
    low, high = controller["interval"]
    return (f"{controller['returned']} of {controller['starts']} ({100 * low:.0f}-{100 * high:.0f} %), "
            f"{controller['fell']} fell; radius {controller['spectral_radius']:.3g}")
