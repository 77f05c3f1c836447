"""``results/REPORT.md``: each claim of the thesis's chapter 4 beside what baslip finds.

    python -m baslip.report [--results DIR]    (the command: :mod:`baslip.cli.report`)

Reads the studies' CSV and JSON files (run ``make studies`` first). Where a result
contradicts the thesis, the report re-simulates the contradicting fixed point with an
integrator none of the solves used (erk at rtol = atol = 1e-13) and prints its eps.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

from baslip.problem.shipped import shipped_problems
from baslip.report.atlas import SCHUR_FROM_ATLAS
from baslip.report.beyond import branch_sections, curve_sections, upright_section
from baslip.report.bodies import body_claims
from baslip.report.evidence import Evidence
from baslip.report.models import model_claims
from baslip.report.thesis import (
    adaptive_claims,
    angle_claims,
    basin_claims,
    controllability_claim,
    dimension_claim,
    region_claims,
    scan_claims,
    speed_claims,
)
from baslip.results import run_summary_text

HEADER = """# baslip against the thesis, chapter 4

Each claim of chapter 4 of the MSc thesis *Identification and stability analysis of periodic
motions for a planar legged runner with a rigid body and a compliant leg* (2013) is set
beside what baslip finds. Every fixed point counted here was verified by an independent
re-simulation (Rosenbrock, rtol = atol = 1e-12) with eps (eq. 4.1) <= 1e-10. The thesis
accepted eps < 1e-5.

**Limits of the comparison.** The thesis prints the leg rest length (0.2 m) and the hip
offset (0.04 m) but not the mass, the inertia or the leg stiffness. baslip uses m = 1 kg,
I = 0.0033 kg m^2 and k = 1000 N/m (see docs/background/model.md). Stability margins, the size and
position of the stable region, and multiplier magnitudes all depend on these. So the
comparison is about qualitative structure and existence, not exact numbers. Also, the
fixed points form a manifold, and which point a solve returns depends on the objective.
Ours is `nearest_guess`, with the guesses given in each problem file.

Regenerate everything with `make studies`. The figures are in each study's folder under
`results/`.

"""


def build_report(results: Path) -> str:
    """REPORT.md of the folder ``results``: the thesis comparison, when any shipped study
    was run there, and an account of the other runs in it (a user's own)."""
    shipped = {path.stem for path in shipped_problems()} | {SCHUR_FROM_ATLAS}  # the runs the claims read
    runs = sorted(path.parent for path in results.glob("*/result.json"))
    others = [run for run in runs if run.name not in shipped]
    if runs and not any(run.name in shipped for run in runs):
        return f"# The runs in {results.name}/\n\n" + runs_account(others)
    account = f"## Other runs in this folder\n\n{runs_account(others)}" if others else ""
    return thesis_report(results) + account


def runs_account(runs: list[Path]) -> str:
    """Each run as the command line tells it (angles in degrees), under its folder's name."""
    parts = []
    for run in runs:
        record = json.loads((run / "result.json").read_text(encoding="utf-8"))
        parts.append(f"### {run.name}\n\n```\n{run_summary_text(record)}\n```\n")
    return "\n".join(parts) or "No runs.\n"


def thesis_report(results: Path) -> str:
    """The comparison with the thesis's chapter 4, from the shipped studies' results."""
    ev = Evidence(results)
    sections = [
        ("Sec. 4.3: fixed points for a given speed", speed_claims(ev)),
        ("Sec. 4.4: fixed points for a given speed and height", angle_claims(ev)),
        ("Sec. 4.5: stability region and convergence regions", region_claims(ev) + basin_claims(ev)),
        ("Sec. 4.6: the fixed-point manifold", scan_claims(ev) + dimension_claim(ev) + controllability_claim(ev)),
        ("Sec. 4.7: time-varying control", adaptive_claims(ev)),
        ("Can an upright BA-SLIP run stably?", upright_section(ev)),
        ("Beyond the thesis: branches of fixed points and their bifurcations", branch_sections(ev)),
        ("Beyond the thesis: bifurcation curves in two parameters", curve_sections(ev)),
        ("Beyond the thesis: other bodies, from the body alone", body_claims(ev)),
        ("Beyond the thesis: models of your own", model_claims(ev)),
    ]
    body = "".join(f"## {title}\n\n" + "\n".join(parts) + "\n" for title, parts in sections)
    return HEADER + verdict_table(body) + body


def verdict_table(body: str) -> str:
    """A table of every claim (a ``### `` heading with a ``**Verdict:**`` line) and its
    verdict, linked to its section, to open the report."""
    rows, title = [], None
    for line in body.splitlines():
        if line.startswith("### "):
            title = line[4:].strip()
        elif line.startswith("- **Verdict:** ") and title:
            anchor = re.sub(r"[^a-z0-9 -]", "", title.lower()).replace(" ", "-")
            shown = title.replace("|", "\\|")  # a bare | would end the table cell
            rows.append(f"| [{shown}](#{anchor}) | {line[len('- **Verdict:** '):]} |")
            title = None
    if not rows:
        return ""
    return "## Summary: every claim and its verdict\n\n| claim | verdict |\n|---|---|\n" + "\n".join(rows) + "\n\n"
