"""Inside or outside a traced stability boundary.

The boundary is the set of segments of traced bifurcation curves (curve.csv of a
continuation with a second parameter) along which the curve bounds stable gaits (the
``stability_boundary`` column: every other multiplier is inside the unit circle, so that
crossing the curve turns a stable gait unstable). A point is inside when the straight
line from it to a verified stable reference point crosses those segments an even number
of times: the reference is stable, and each crossing changes stability.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baslip.files.rows import read_rows

Segment = tuple[np.ndarray, np.ndarray]


def read_curves(path: Path) -> list[dict]:
    """Rows of a curve.csv: numbers as floats, the boundary flag as bool."""
    rows: list[dict] = list(read_rows(path))
    for row in rows:
        for key, value in row.items():
            if key in ("type", "special", "kappa"):
                continue
            row[key] = value == "true" if key == "stability_boundary" else float(value)
    return rows


def boundary_segments(rows: list[dict], names: tuple[str, str]) -> list[Segment]:
    """The segments of the curves in the plane of ``names`` that bound stable gaits."""
    segments = []
    for number in sorted({r["curve"] for r in rows}):
        curve = [r for r in rows if r["curve"] == number]
        for a, b in zip(curve[:-1], curve[1:]):
            if a["stability_boundary"] and b["stability_boundary"]:
                segments.append((np.array([a[names[0]], a[names[1]]]), np.array([b[names[0]], b[names[1]]])))
    return segments


def crossings(p: np.ndarray, q: np.ndarray, segments: list[Segment]) -> int:
    """How many of ``segments`` the segment p-q crosses (proper intersections)."""
    count = 0
    for a, b in segments:
        d1, d2 = _side(a, b, p), _side(a, b, q)
        d3, d4 = _side(p, q, a), _side(p, q, b)
        if d1 * d2 < 0 and d3 * d4 < 0:
            count += 1
    return count


def inside(point, reference, segments: list[Segment]) -> bool:
    """Whether ``point`` is on the stable side: an even number of crossings from the
    stable ``reference``."""
    return crossings(np.asarray(point, dtype=float), np.asarray(reference, dtype=float), segments) % 2 == 0


def _side(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> float:
    return float((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]))
