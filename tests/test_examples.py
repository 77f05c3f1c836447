"""The examples run as they are shipped, and leave their files where they say."""

import subprocess
import sys

from runs import ROOT


def test_the_tour_runs_and_writes_only_into_its_folder(tmp_path):
    done = subprocess.run([sys.executable, str(ROOT / "examples" / "tour.py"), str(tmp_path)],
                          capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "<FixedPointResult downward: converged, stable" in done.stdout
    assert "fold at theta_td = 23.6945 deg" in done.stdout
    written = {p.name for p in tmp_path.iterdir()}
    assert written == {"downward_gait.png", "downward_trajectory.csv", "tour_sweep", "band_diagram.png"}
