"""Walking and running at one body and one energy, in one figure: the walker's walks of
``results/walker`` and the SLIP's runs of ``results/slip_walker_energy`` (80 kg, 1 m legs,
15 kN/m, 820 J), their spectral radii against the landing angle from the vertical.

    python examples/walking_and_running.py results results/walking_and_running

Writes ``walking_and_running.png`` into the output folder (made if missing).
"""

import math
import sys
from pathlib import Path

from baslip.files.atomic import write_files_atomically
from baslip.files.rows import read_points
from baslip.viz.modelplots import png, radii_figure

#: The runs that hold the two branches, and their labels.
BRANCHES = (("walks (walker)", "walker"), ("runs (SLIP)", "slip_walker_energy"))


def figure(results: Path):
    """The figure of the two committed branches under ``results``."""
    branches = []
    for label, name in BRANCHES:
        rows = read_points(results / name / "branch.csv")
        branches.append((label, [{**r, "theta_td": math.degrees(r["theta_td"])} for r in rows]))
    return radii_figure(branches, "theta_td", "deg from the vertical",
                        "Walking and running at 80 kg, 1 m legs, 15 kN/m and 820 J")


def main(results: str, out: str) -> Path:
    """Write the figure into ``out``; its path."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    write_files_atomically({folder / "walking_and_running.png": png(figure(Path(results)))})
    return folder / "walking_and_running.png"


if __name__ == "__main__":
    print(f"wrote {main(*sys.argv[1:3])}")
