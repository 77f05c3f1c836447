"""Specification of baslip.report.page: the claims it writes count what the committed results
hold, and say what a count does and does not show."""

import re
from pathlib import Path

from baslip.report.evidence import Evidence, converged
from baslip.report.thesis import scan_claims

RESULTS = Path(__file__).resolve().parents[1] / "results"


def test_body_angle_scan_counts_its_points_and_does_not_claim_absence():
    evidence = Evidence(RESULTS)
    rows = evidence.points("body_angle_scan")
    text = scan_claims(evidence)[0]
    found = re.search(r"(\d+) of (\d+) body angles .* at the other (\d+) the warm-started local solver found no "
                      r"verified one \((\d+) solves failed, (\d+) ended at points that the independent re-simulation "
                      r"rejected\), which does not show that none exist", text)
    assert found, text
    verified, scanned, others, failed, rejected = map(int, found.groups())
    assert (verified, scanned) == (len(converged(rows)), len(rows))
    assert verified + others == scanned and failed + rejected == others
    assert rejected == sum(1 for r in rows if r["status"] == "not_verified")


def atlas_summary(least_apex, complete=True, polished=None):
    cell = {"ydot": 0.5, "z": 0.4, "pieces": 2, "seeds": 24, "seeds_failed": 10, "charts": 3000, "complete": complete,
            "boundaries": 500, "corrector_stops": 0 if complete else 120,
            "least_radius": least_apex, "least_radius_upright_apex": least_apex,
            "least_radius_upright_throughout": None, "stable_share": 0.0, "polished_radius": polished,
            "polished_upright_throughout_radius": None, "time_s": 1.0}
    problem = {"bounds": {"theta_h": [1.047, 2.094], "Kp": [-100, 100], "Kd": [-10, 10]}, "study": {"seeds": 24, "max_charts": 5000}}
    return {"complete": True, "cells": [cell], "provenance": {"problem": problem}}


def test_the_atlas_claim_is_as_wide_as_its_covering(tmp_path):
    """A stable chart (or polished end) makes the verdict "differs", covered whole or not (a
    stable gait found is a fact); otherwise it agrees only within the covering, and a cell
    that was not covered whole says why."""
    import json

    from baslip.report.atlas import atlas_claims

    for least, polished, complete, verdict in ((2.7, 1.4, False, "open: not covered whole"),
                                               (2.7, 1.4, True, "agreed within the covering"),
                                               (1.2, 0.7, True, "differs: a stable gait upright at the apex exists; "
                                                                "none was found upright throughout the stride"),
                                               (0.6, None, False, "differs: a stable gait upright at the apex exists")):
        folder = tmp_path / f"r{least}{complete}" / "atlas_upright_cell"
        folder.mkdir(parents=True)
        (folder / "result.json").write_text(json.dumps(atlas_summary(least, complete, polished)))
        [text] = atlas_claims(Evidence(folder.parent))
        assert f"**Verdict:** {verdict}" in text
        assert ("not covered whole: the corrector gave up at 120 of 500 edges" in text) == (not complete)
        assert ("covered whole: every edge" in text) == complete
        assert "24 seeds (10 failed)" in text and "3000 charts" in text


def test_a_covering_capped_at_a_spectral_radius_is_called_whole_only_up_to_it(tmp_path):
    """A study that grows from no chart above ``max_spectral_radius`` says so: a complete
    cell is covered whole up to that radius."""
    import json

    from baslip.report.atlas import atlas_claims

    summary = atlas_summary(2.7, True, 1.4)
    summary["provenance"]["problem"]["study"]["max_spectral_radius"] = 20
    folder = tmp_path / "atlas_upright_cell"
    folder.mkdir()
    (folder / "result.json").write_text(json.dumps(summary))
    [text] = atlas_claims(Evidence(tmp_path))
    assert ("covered whole up to spectral radius 20: every edge a bound, a fall or a singular chart, or a gait of "
            "radius above 20") in text


def test_the_capped_atlas_says_which_cells_it_covers_whole_and_where_the_uncapped_one_reached_lower(tmp_path):
    """Beside the upright atlas, the capped one names its cells covered whole up to its
    cap, the cells where its least radius is above the uncapped covering's, and what such
    a covering can miss; its polished gaits count in the short answer's least radii."""
    import json

    from baslip.report.answer import upright_answer
    from baslip.report.atlas import atlas_claims

    uncapped = atlas_summary(2.7, False, 0.9)
    capped = atlas_summary(4.1, True, 4.0)
    capped["provenance"]["problem"]["study"].update(max_spectral_radius=100, max_charts=12000)
    capped.update(charts=396, not_verified=1, kind="atlas", best=[
        {"meaning": "upright_throughout", "spectral_radius": 1.19, "ydot": 0.3, "z": 0.4, "upright_apex": True,
         "upright_throughout": True}])
    for name, summary in (("atlas_upright", uncapped), ("atlas_upright_capped", capped)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "result.json").write_text(json.dumps(summary))
    [text] = atlas_claims(Evidence(tmp_path))
    assert "1 of the 1 cells covered whole up to 100 ((0.5, 0.4))" in text
    assert "its least is higher: (0.5, 0.4): 4 against 0.9" in text
    assert "atlas_upright_capped/atlas.png" in text
    assert "a stable island ringed by gaits more unstable than that" in text
    short = upright_answer(Evidence(tmp_path))
    assert "1 of them covered whole up to spectral radius 100 by `atlas_upright_capped`" in short
    assert "least radius 1.190 (found by `atlas_upright_capped` at ydot = 0.3 m/s, z = 0.4 m" in short


def write_points(path, rows):
    import csv

    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def test_the_cross_check_compares_the_stability_nlp_with_the_atlas_cell_by_cell(tmp_path):
    """The stability NLP's least verified radius per cell stands beside the atlas's; the
    verdict says "differs" only where the NLP found a gait more stable (by over 1 %) than
    the atlas, and the runs from the atlas's gaits are counted and listed."""
    import json

    from baslip.report.atlas import crosscheck_claims

    for nlp_radius, verdict in ((2.09, "agrees with the atlas"), (0.5, "differs from the atlas")):
        root = tmp_path / str(nlp_radius)
        for name in ("atlas_upright", "optimal_upright_schur", "schur_from_atlas"):
            (root / name).mkdir(parents=True)
        (root / "atlas_upright" / "result.json").write_text(json.dumps(atlas_summary(1.2, False, 0.932)))
        problem = {"bounds": {"Kp": [-100, 100], "Kd": [-10, 10]}}
        study = {"complete": True, "starts": 2, "least_per_point": [{"ydot": 0.5, "z": 0.4, "spectral_radius": nlp_radius}],
                 "provenance": {"problem": problem}}
        (root / "optimal_upright_schur" / "result.json").write_text(json.dumps(study))
        ended = {"sweep_ydot": 0.5, "sweep_z": 0.4, "start_status": "converged", "status": "converged",
                 "spectral_radius": nlp_radius, "theta_h_dot": -0.2,
                 "descent_stop": f"stability NLP: Solve_Succeeded after 44 iterations, its bound {nlp_radius * 0.99:.4g}"}
        no_start = {**ended, "start_status": "failed", "status": "failed", "spectral_radius": "",
                    "descent_stop": "no starting fixed point: IPOPT: Infeasible_Problem_Detected"}
        write_points(root / "optimal_upright_schur" / "points.csv", [ended, no_start])
        back = {"ydot": 0.5, "z": 0.4, "meaning": "any", "atlas_radius": 0.932, "nlp_status": "Solve_Succeeded",
                "verified": True, "verified_radius": 0.9319}
        stalled = {**back, "meaning": "upright_throughout", "nlp_status": "Maximum_Iterations_Exceeded",
                   "verified": False, "verified_radius": None}
        (root / "schur_from_atlas" / "result.json").write_text(json.dumps(
            {"complete": True, "source": "atlas_upright", "rows": [back, stalled]}))
        [text] = crosscheck_claims(Evidence(root))
        assert f"**Verdict:** {verdict}" in text
        assert f"(0.5, 0.4): {nlp_radius:.3g} against 0.932" in text
        assert "2 starts, 1 starting fixed points, 1 NLP runs converged, 1 ends verified" in text
        assert "within 1.0% of the verified radius" in text
        assert "end was verified for 1: 1 at the atlas's radius" in text and "0.932 -> Maximum_Iterations_Exceeded" in text
        assert "0 lower, 0 higher" in text and "polish missed" not in text
    sharper = {**back, "atlas_radius": 1.012, "verified_radius": 0.9915}
    (root / "schur_from_atlas" / "result.json").write_text(json.dumps(
        {"complete": True, "source": "atlas_upright", "rows": [sharper]}))
    [text] = crosscheck_claims(Evidence(root))
    assert "1 lower, 0 higher" in text
    assert "a stable gait the atlas's polish missed at (0.5 m/s, 0.4 m): radius 0.9915 against 1.012" in text


def test_the_cross_check_sets_gaits_upright_throughout_against_the_least_of_both_atlases(tmp_path):
    """Upright throughout the stride, the NLP's least verified radius per cell stands
    beside the least of the upright atlas and the capped one (charts and polished gaits
    alike); the verdict names the cells where the NLP's is lower by over 1 %, and says
    whether that gait is stable and whether it undercuts the atlases' least of all cells."""
    import json

    from baslip.report.atlas import crosscheck_claims

    cases = ((1.60, "", "(0.5, 0.4): 1.6 against 1.5."),
             (1.45, "more stable gaits than the atlases in 1 of 1 cells ((0.5, 0.4): 1.45 against 1.5): none "
                    "stable, the least 1.45, below the atlases' least over all cells, 1.5", ""),
             (0.95, "among them a stable gait that the atlases missed, radius 0.95", ""))
    for nlp_radius, clause, beside in cases:
        root = tmp_path / str(nlp_radius)
        for name in ("atlas_upright", "atlas_upright_capped", "optimal_upright_schur"):
            (root / name).mkdir(parents=True)
        charts_only = atlas_summary(1.2, True, 0.932)
        charts_only["cells"][0]["least_radius_upright_throughout"] = 2.5
        capped = atlas_summary(1.2, True, 0.932)
        capped["cells"][0]["polished_upright_throughout_radius"] = 1.5
        (root / "atlas_upright" / "result.json").write_text(json.dumps({**charts_only, "name": "atlas_upright"}))
        (root / "atlas_upright_capped" / "result.json").write_text(json.dumps({**capped, "name": "atlas_upright_capped"}))
        study = {"complete": True, "starts": 1, "provenance": {"problem": {"bounds": {"Kp": [-1, 1], "Kd": [-1, 1]}}},
                 "least_per_point": [{"ydot": 0.5, "z": 0.4, "spectral_radius": 2.0}]}
        (root / "optimal_upright_schur" / "result.json").write_text(json.dumps(study))
        upright = {"sweep_ydot": 0.5, "sweep_z": 0.4, "start_status": "converged", "status": "converged",
                   "spectral_radius": nlp_radius, "theta_h_dot": -0.1, "upright_throughout": "true",
                   "descent_stop": f"stability NLP: Solve_Succeeded, its bound {nlp_radius:.4g}"}
        swinging = {**upright, "spectral_radius": 0.5, "upright_throughout": "false"}  # not upright throughout: not compared
        write_points(root / "optimal_upright_schur" / "points.csv", [upright, swinging])
        [text] = crosscheck_claims(Evidence(root))
        assert "against the least of `atlas_upright` and `atlas_upright_capped` (charts and polished gaits)" in text
        assert f"(0.5, 0.4): {nlp_radius:.3g} against 1.5" in text and beside in text
        verdict = text[text.index("**Verdict:**"):text.index("**Why:**")]
        assert verdict.startswith("**Verdict:** agrees with the atlas for gaits upright at the apex")
        assert (clause in verdict) and (("upright throughout the stride it found" in verdict) == bool(clause))


def test_the_atlas_claim_names_the_polished_gaits_and_maps_the_hanging_family(tmp_path):
    """The best polished gait of each meaning is described (radius, gait, trunk range), and
    a finished hanging-family atlas adds its least radius and stable share per cell."""
    import json

    from baslip.report.atlas import atlas_claims

    summary = atlas_summary(1.05, False, 0.74)
    gait = {"ydot": 0.5, "z": 0.4, "theta_h": 1.105, "theta_h_dot": -7.6, "Kp": 31.0, "Kd": 0.358, "theta2_des": 4.5,
            "theta_td": 0.384, "residual": 3e-13, "trunk_min_deg": -34.0, "trunk_max_deg": 155.0}
    summary["best"] = [{**gait, "meaning": "any", "spectral_radius": 0.74},
                       {**gait, "meaning": "any", "spectral_radius": 0.9},
                       {**gait, "meaning": "upright_throughout", "spectral_radius": 1.9}]
    hanging = atlas_summary(0.43, True, 0.4)
    hanging["cells"][0]["stable_share"] = 0.25
    for name, record in (("atlas_upright_cell", summary), ("atlas_downward", hanging)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "result.json").write_text(json.dumps(record))
    [text] = atlas_claims(Evidence(tmp_path))
    assert "The polished gait of least radius of all: radius 0.740" in text and "radius 0.900" not in text
    assert "The polished gait of upright throughout: radius 1.900" in text
    assert "between -34 and 155 deg" in text
    assert "theta_h_dot = -435.4 deg/s at the apex" in text and "rad/s" not in text  # issue 56: texts in deg/s
    assert "the hanging family" in text and "(0.5, 0.4): least radius 0.4, stable share 25.0%" in text
    assert "**Verdict:** differs: a stable gait upright at the apex exists; none was found upright throughout" in text


def basins(largest, last_share, cost, kept_up=0.0):
    return {"largest_90_box": largest, "per_box": [
        {"box": 1.0, "returned_fraction": 1.0 - kept_up, "bounded_fraction": kept_up, "ci95": [0.99, 1.0],
         "median_ms_per_stride": cost},
        {"box": 16.0, "returned_fraction": last_share, "ci95": [0.0, 1.0], "median_ms_per_stride": cost}]}


def test_the_local_search_claim_gives_the_hanging_range_that_its_search_found():
    """The comparison with the hanging trunk quotes the least and largest of the hanging
    search's least radius per cell, as committed, not a typed-in range."""
    from baslip.report.beyond import upright_section

    evidence = Evidence(RESULTS)
    radii = [p["spectral_radius"] for p in evidence.summary("optimal_downward")["least_per_point"]]
    [text] = [c for c in upright_section(evidence) if c.startswith("### Under constant PD, by the local multi-start")]
    assert f"while the hanging trunk reaches {min(radii):.2f} to {max(radii):.2f};" in text


def test_the_best_controller_has_the_largest_90_percent_box_then_the_most_returned_then_the_least_cost():
    from baslip.report.controllers import best_controller

    summary = {"basins": {"constant": basins(None, 0.0, 0.1), "feedback": basins(4.0, 0.4, 0.2),
                          "horizon": basins(8.0, 0.75, 30.0), "resolve": basins(8.0, 0.5, 4.0)}}
    assert best_controller(summary) == "horizon"
    summary["basins"]["resolve"] = basins(8.0, 0.75, 4.0)  # as far and as many: the cheaper one
    assert best_controller(summary) == "resolve"
    summary["basins"] = {"constant": basins(None, 0.0, 0.1), "feedback": basins(None, 0.01, 0.2)}
    assert best_controller(summary) == "feedback"  # no 90 % box: the most returned in the largest box


def test_a_controller_that_keeps_most_starts_up_without_returning_is_named_so():
    from baslip.report.controllers import _kept_up

    summary = {"basins": {"constant": basins(None, 0.0, 0.1, kept_up=1.0), "feedback": basins(4.0, 0.4, 0.2),
                          "pivot": basins(None, 0.0, 0.2, kept_up=0.4)}}
    assert _kept_up(summary) == [("constant", 1.0)]


def test_the_starts_of_each_re_solving_controller_are_stated_per_gait_where_the_gaits_differ():
    from baslip.report.controllers import _re_solve_starts

    def ran(horizon: int, resolve: int) -> dict:
        return {"basins": {"horizon": {"per_box": [{"samples": horizon}]}, "resolve": {"per_box": [{"samples": resolve}]}}}

    same = {"controllers_upright": ran(1000, 100), "controllers_downward": ran(1000, 100)}
    assert _re_solve_starts(same) == "the receding horizon from 1000, the one-stride re-solve from 100"
    mixed = {"controllers_upright": ran(4000, 100), "controllers_downward": ran(1000, 100)}
    assert _re_solve_starts(mixed) == ("the receding horizon from 4000 (upright (shipped, PD)), 1000 (hanging (PD)), "
                                       "the one-stride re-solve from 100")


def test_the_short_upright_answer_counts_what_the_committed_atlases_hold():
    from baslip.report.answer import upright_answer

    text = upright_answer(Evidence(RESULTS))
    cells = Evidence(RESULTS).rows("atlas_upright", "cells.csv")
    stable = sum(1 for c in cells if min(c["least_radius_upright_apex"], c["polished_radius"] or 9) < 1)
    assert f"a stable gait in {stable} of the {len(cells)} (ydot, z) cells" in text
    charts = [c for name in ("atlas_vpp", "atlas_vpp_human") for c in Evidence(RESULTS).rows(name, "atlas.csv")
              if c["status"] == "converged" and c["stable"] is True]
    upright = sum(1 for c in charts if c["upright_throughout"] is True)
    assert f"Of its {len(charts)} stable charts, {upright} are upright throughout" in text
    assert text.count("\n- **") == 3  # one bullet per law of control


def test_the_short_upright_answer_never_states_a_least_radius_above_a_gait_the_report_holds():
    """The least radius upright throughout is the least of the atlas's cells and of the
    committed multi-start and stability-NLP searches and the capped atlas's polished gaits;
    a search's is named with its cell."""
    from baslip.report.answer import UPRIGHT_SEARCHES, upright_answer

    evidence = Evidence(RESULTS)
    cells = evidence.rows("atlas_upright", "cells.csv")
    atlas = min(c[k] for c in cells for k in ("least_radius_upright_throughout", "polished_upright_throughout_radius")
                if isinstance(c[k], float))
    searched = []
    for name in UPRIGHT_SEARCHES:
        summary = evidence.summary(name)
        if summary is None:
            continue
        if summary["kind"] == "atlas":  # its polished gaits upright throughout
            searched += [b for b in summary["best"] if b["upright_throughout"] is True]
        else:
            searched.append(summary["least_upright_throughout"])
    best = min(searched, key=lambda gait: gait["spectral_radius"])
    text = upright_answer(evidence).split("Upright throughout the stride")[1]
    least = min(atlas, best["spectral_radius"])
    assert f"least radius {least:.3f}" in text
    if best["spectral_radius"] < atlas:
        assert f"at ydot = {best['ydot']:g} m/s, z = {best['z']:g} m; the atlas's own least is {atlas:.3f}" in text


def test_the_vpp_descent_claim_compares_each_cell_with_the_atlas_and_says_where_it_went_lower(tmp_path):
    """Each optimal_vpp cell is set beside atlas_vpp's polished least at its speed (whose
    family, z free, holds the cell's); a cell below it is named as the atlas's miss."""
    import json
    import shutil

    from baslip.report.vpp import optimal_claims

    (text,) = optimal_claims(Evidence(RESULTS))
    summary = Evidence(RESULTS).summary("optimal_vpp")
    assert text.count("\n| ") == len(summary["least_per_point"]) + 1  # a row per cell, and the header
    assert "At every cell the descent ends at or above the atlas's polished least" in text
    for name in ("optimal_vpp", "atlas_vpp"):
        shutil.copytree(RESULTS / name, tmp_path / name)
    summary["least_per_point"][0]["spectral_radius"] = 0.5  # below every polished radius
    (tmp_path / "optimal_vpp" / "result.json").write_text(json.dumps(summary))
    (text,) = optimal_claims(Evidence(tmp_path))
    assert "At 1 cell the descent ends below the atlas's polished least" in text


def test_the_vpp_descent_claim_counts_how_the_stability_nlps_starts_ended(tmp_path):
    """Each start of the stability NLP's cross-check (optimal_vpp_schur) is counted once:
    at its cell's descent least, above it, below it, or failed; and the cells where the
    two searches' least agree are counted."""
    import shutil

    from baslip.report.vpp import optimal_claims

    for name in ("optimal_vpp", "optimal_vpp_schur", "atlas_vpp"):
        shutil.copytree(RESULTS / name, tmp_path / name)
    (text,) = optimal_claims(Evidence(tmp_path))
    counts = re.search(r"Of its (\d+) starts, (\d+) end at their cell's least, (\d+) above it .*?, (\d+) fail, "
                       r"and (\d+) ends? below it", text)
    assert counts is not None
    total, *parts = (int(n) for n in counts.groups())
    assert total == 64 and sum(parts) == total
    rows = Evidence(tmp_path).rows("optimal_vpp_schur", "points.csv")
    assert parts[2] == sum(1 for r in rows if r["status"] != "converged")
    # Lower one verified end below every descent least: it is counted below, not at.
    for row in rows:
        if row["status"] == "converged":
            row["spectral_radius"] = 0.1
            break
    from baslip.studies.runner import csv_text

    (tmp_path / "optimal_vpp_schur" / "points.csv").write_text(csv_text(list(rows[0]), rows))
    (again,) = optimal_claims(Evidence(tmp_path))
    moved = [int(n) for n in re.search(r"(\d+) ends? below it", again).groups()]
    assert moved == [parts[3] + 1] and "0.1000 at ydot" in again  # counted, and named


def test_a_folder_of_a_users_own_runs_is_told_plainly_and_beside_the_thesis_comparison(tmp_path):
    """Runs under names the report does not know are told as the command line tells them;
    without any shipped study in the folder there is no thesis comparison at all."""
    import shutil

    from baslip.report.page import build_report

    shutil.copytree(RESULTS / "downward", tmp_path / "my_gait")
    shutil.copytree(RESULTS / "curve_slip_band", tmp_path / "my_band")
    text = build_report(tmp_path)
    assert text.startswith(f"# The runs in {tmp_path.name}/") and "Sec. 4.3" not in text
    assert "### my_band" in text and "period_doubling at theta_td = 21.1464 deg" in text
    assert "### my_gait" in text and "downward: converged, spectral radius 0.899" in text
    shutil.copytree(RESULTS / "speed_sweep", tmp_path / "speed_sweep")  # a shipped study: the comparison too
    text = build_report(tmp_path)
    assert "## Sec. 4.3" in text and "## Other runs in this folder" in text and "### speed_sweep" not in text


def test_the_body_claims_verify_each_reference_body_s_gaits_again_and_claim_no_more_than_their_searches():
    from baslip.report.bodies import BODIES, body_claims
    from baslip.report.evidence import Evidence

    human, robot, atlas, *families = body_claims(Evidence(Path(__file__).resolve().parents[1] / "results"))
    for text, (_, names) in zip((human, robot), BODIES):
        for name in names:
            entry = text[text.index(f"{name} ("):].split("; residual", 1)[1]
            assert float(entry.split("eps = ")[1].split(" ")[0]) <= 1e-10  # re-simulated here
        assert "of 3 stable" in text and "not whether a stable one exists" in text
    assert "m = 2.474 kg" in robot and "not published" in robot
    # the one-cell atlas: its best gait re-simulated here, stable, and the covering said
    assert float(atlas.split("independent re-simulation eps = ")[1].split(" ")[0]) <= 1e-10
    radius = float(atlas.split("most stable polished gait: spectral radius ")[1].split(" ")[0].rstrip(","))
    assert radius < 1 and "a stable PD gait of the human body exists" in atlas
    assert "not covered whole" in atlas and "200 charts" in atlas
    # each families answer: its best gait re-simulated here; a verdict no wider than its search
    assert len(families) == 2
    for text in families:
        assert float(text.split("independent re-simulation eps = ")[1].split(" ")[0]) <= 1e-10
        radius = float(text.split("most stable polished gait: spectral radius ")[1].split(" ")[0])
        verdict = "a stable gait exists at this cell" if radius < 1 else "no stable gait found in the search"
        assert verdict in text and "Searched: 6 seeds" in text
