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
    found = re.search(r"(\d+) of (\d+) body angles .* at the other (\d+) the warm-started local solver found none, "
                      r"which does not show that none exist", text)
    assert found, text
    verified, scanned, others = map(int, found.groups())
    assert (verified, scanned) == (len(converged(rows)), len(rows))
    assert verified + others == scanned
