"""The evidence the report reads: the studies' files, verified rows, and how a claim is set out."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.files.rows import read_points
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import CONTROL, PD, HipLaw
from baslip.model.quantities import quantity_text
from baslip.status import Status

DEG = 180 / math.pi


class Evidence:
    """Loads study outputs on demand and re-simulates points independently."""

    def __init__(self, results: Path):
        self.results = results
        self._maps: dict[str, ReturnMap] = {}

    def points(self, name: str) -> list[dict]:
        path = self.results / name / "points.csv"
        return read_points(path) if path.exists() else []

    def summary(self, name: str) -> dict | None:
        path = self.results / name / "result.json"
        return json.loads(path.read_text()) if path.exists() else None

    def rows(self, name: str, file: str) -> list[dict]:
        path = self.results / name / file
        return read_points(path) if path.exists() else []

    def dimensions(self, name: str) -> dict[tuple, int]:
        """Tally of manifold dimensions (see baslip.analysis.manifold) over a study's fixed points."""
        from baslip.analysis.manifold import manifold_dimension

        rmap = ReturnMap(Tolerances(1e-10, 1e-10))
        tally: dict[tuple, int] = {}
        for row in converged(self.points(name)):
            X = np.array([row[n] for n in APEX.names])
            u = np.array([row[n] for n in CONTROL.names])
            d = manifold_dimension(*rmap.jacobians(X, u, Params()), u)
            key = (d.dimension, d.gait_dimension, d.apex_rank, d.ydot_z_rank, d.control_rank)
            tally[key] = tally.get(key, 0) + 1
        return tally

    def resimulate(self, row: dict, law: HipLaw = PD, params: Params = Params()) -> float:
        """eps of the row's fixed point under an independent map (erk, 1e-13) of hip law
        ``law``, with ``params``."""
        if law.name not in self._maps:
            self._maps[law.name] = ReturnMap(Tolerances(1e-13, 1e-13), law=law)
        X = np.array([row[n] for n in APEX.names])
        u = np.array([row[n] for n in law.controls.names])
        stride = self._maps[law.name].stride(X, u, params)
        if stride.apex is None:
            return math.nan
        return float(np.linalg.norm(stride.apex - X) / np.linalg.norm(X))


def converged(rows):
    return [r for r in rows if r["status"] == Status.CONVERGED]


def claim(title: str, thesis: str, ours: str, verdict: str, why: str, figures: Sequence[str] = ()) -> str:
    lines = [f"### {title}", "", f"- **Thesis:** {thesis}", f"- **baslip:** {ours}"]
    if figures:
        lines.append("- **Figures:** " + ", ".join(f"[{f}]({f})" for f in figures))
    lines += [f"- **Verdict:** {verdict}", f"- **Why:** {why}", ""]
    return "\n".join(lines)


def point_evidence(ev: Evidence, row: dict, what: str) -> str:
    return (
        f"{what}: ydot = {row['ydot']:.4g} m/s, z = {row['z']:.4g} m, theta_h = {row['theta_h'] * DEG:.4f} deg, "
        f"theta_h_dot = {row['theta_h_dot'] * DEG:.4g} deg/s, u = ({', '.join(quantity_text(n, row[n], 4) for n in CONTROL.names)}); "
        f"verified residual {row['residual']:.1e} (Rosenbrock, 1e-12), independent re-simulation "
        f"eps = {ev.resimulate(row):.1e} (erk, 1e-13)"
    )


def _shown(name: str, value: float) -> str:
    return f"{value * DEG:.6g} deg" if name.startswith("theta") else f"{value:.6g}"
