"""The report's section on models of one's own, read from the committed runs: the SLIP's
band and its curves agree with the BA-SLIP limit's, the hopper's atlas is told with how
wide it searched, the walker's stable walks between their re-simulated edges beside the
runs of its body, the third law at two bodies, and the three hip laws under one study."""

from pathlib import Path

import pytest

from baslip.report.evidence import Evidence
from baslip.report.models import model_claims

RESULTS = Path(__file__).resolve().parents[1] / "results"


@pytest.fixture(scope="module")
def claims():
    return model_claims(Evidence(RESULTS))


def test_the_slips_band_and_curves_agree_with_the_ba_slip_limits(claims):
    verdicts = [line for text in claims[:2] for line in text.splitlines() if line.startswith("- **Verdict:**")]
    assert len(verdicts) == 2 and all(v.startswith("- **Verdict:** agrees") for v in verdicts)


def test_the_hoppers_claim_says_how_wide_and_re_simulates_its_best_gait(claims):
    hopper = claims[2]
    assert "How wide: one apex height, forward speeds from 2 to 12 m/s" in hopper
    assert "re-simulated here, eps = " in hopper and "stable chart centres at " in hopper


def test_without_the_runs_the_section_says_not_run(tmp_path):
    assert model_claims(Evidence(tmp_path)) == ["Not run.\n"]


def test_the_hoppers_controllers_are_told_with_their_intervals(claims):
    controllers = claims[3]
    assert "deadbeat" in controllers and "95 % Wilson intervals" in controllers


def test_the_walkers_stable_walks_are_told_between_their_edges_re_simulated(claims):
    walker = claims[4]
    assert "the symmetric walk (no leg speed at mid-stance) is stable from the symmetry-breaking branch point" in walker
    assert walker.count("eps = ") == 1 and "re-simulated here: eps = " in walker
    assert "How wide: one body and one energy" in walker and "Not set against Geyer et al." in walker


def test_the_walkers_claim_tells_its_atlas_and_its_basins(claims):
    walker = claims[4]
    assert "An atlas of the walks at 820 J in landing angle" in walker and "95 % Wilson intervals" in walker


def test_the_third_laws_claim_says_where_its_gaits_turn_stable(claims):
    law = claims[5]
    assert "stable from omega = " in law and "re-simulated here: eps = " in law
    assert "How wide: one body, one apex height and speed, one slope of the constraint" in law
    assert "lqr " in law and "95 % Wilson intervals" in law


def test_the_walkers_claim_sets_the_runs_of_its_body_and_energy_beside_it(claims):
    walker = claims[4]
    assert "Running at the same body, stiffness and energy" in walker and "every one unstable" in walker
    assert "walking_and_running/walking_and_running.png" in walker


def test_the_third_law_at_the_human_body_is_stable_for_a_band_of_slopes(claims):
    human = claims[6]
    assert human.startswith("### The third hip law at the human body")
    assert "stable for slopes from " in human and "re-simulated here: eps = " in human


def test_the_three_laws_sit_side_by_side_in_one_table_per_body(claims):
    laws = claims[7]
    assert laws.count("| law | gait's spectral radius | open loop | deadbeat | LQR |") == 2
    for law in ("pd", "vpp", "virtual_constraint"):
        assert laws.count(f"| {law} | ") == 2
    assert "| vpp | " in laws and "none" in laws  # two controls reach no deadbeat


def test_the_third_law_has_no_stable_gait_at_the_thesiss_own_cell(claims):
    law = claims[5]
    assert "At the thesis's own cell (0.4 m, 0.5 m/s, omega 100 1/s)" in law and "none of its gaits are stable" in law
