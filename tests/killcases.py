"""Test helper: one small problem of every study kind, for the kill-and-resume tests.

Each case is a shipped problem file with its study cut down to a few seconds of work
(every replaced text must occur in the shipped file, so a changed file fails loudly),
the tables a finished run writes, and the columns of them that hold timings.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class KillCase:
    """A small study: its folder name, problem text, the tables compared row by row,
    their timing columns (left out of the comparison), and the cases whose finished
    folders it reads (beside its own)."""

    name: str
    text: str
    tables: tuple[str, ...]
    timing: tuple[str, ...] = ("time_s",)
    sources: tuple[str, ...] = ()


def shipped(name: str, *replacements: tuple[str, str], rename: str | None = None) -> str:
    """``problems/<name>.yaml`` with each (old, new) replaced (old must occur), and its
    ``name:`` set to ``rename``."""
    text = (ROOT / "problems" / f"{name}.yaml").read_text()
    for old, new in replacements:
        if old not in text:
            raise AssertionError(f"{name}.yaml no longer contains {old!r}")
        text = text.replace(old, new)
    return re.sub(r"^name: .*$", f"name: {rename or name}", text, count=1, flags=re.M)


GRID = KillCase("grid_downward", shipped(
    "grid_downward", ("vary: {ydot: [0.1, 1.0, 0.1], z: [0.3, 0.7, 0.05]}", "vary: {ydot: [0.3, 0.6, 0.1], z: [0.4, 0.5, 0.05]}")),
    ("points.csv",))

CASES: tuple[KillCase, ...] = (
    GRID,
    KillCase("random", shipped("stable_region_random", ("count: 150", "count: 8"), rename="random"),
             ("points.csv",), sources=("grid_downward",)),
    KillCase("basin", shipped(
        "convergence_regions",
        ("stable_at: {ydot: 0.6, z: 0.4}", "stable_at: {ydot: 0.5, z: 0.4}"),
        ("grid: {ydot: [0.1, 1.0, 0.1], z: [0.3, 0.7, 0.025]}", "grid: {ydot: [0.3, 0.6, 0.1], z: [0.38, 0.5, 0.04]}"),
        ("strides: 300", "strides: 40"), rename="basin"),
        ("basin.csv", "trajectories.csv"), timing=(), sources=("grid_downward",)),
    KillCase("optimal", shipped(
        "optimal_downward",
        ("vary: {ydot: [0.3, 0.7, 0.2], z: [0.35, 0.45, 0.05]}", "vary: {ydot: [0.5, 0.5, 0.1], z: [0.45, 0.45, 0.05]}"),
        ("starts: 12", "starts: 4"), ("iterations: 150", "iterations: 3"), rename="optimal"),
        ("points.csv",)),
    KillCase("adaptive", shipped(
        "adaptive_upright", ("strides: 2048", "strides: 4"), ("frozen_strides: 1000", "frozen_strides: 6"),
        ("probe_strides: 200", "probe_strides: 4"), rename="adaptive"),
        ("strides.csv",), timing=("solve_time_s",)),
    KillCase("atlas", shipped(
        "atlas_upright_cell", ("seeds: 24", "seeds: 1\n  polish: 1\n  iterations: 20"), ("max_charts: 12000", "max_charts: 6"),
        rename="atlas"),
        ("atlas.csv", "cells.csv", "atlas_best.csv", "atlas_boundary.csv")),
    KillCase("controllers", shipped(
        "controllers_downward", ("samples: 4000        #", "samples: 4        #"),
        ("solve_samples: {horizon: 4000, resolve: 4000}", "solve_samples: {horizon: 2, resolve: 2}"),
        ("boxes: [1, 2, 4, 8, 16]", "boxes: [1, 4]"), ("strides: 100", "strides: 6"), rename="controllers")
        + "  lqr_scale: {z: 0.01, theta_h: 0.1, ydot: 0.1, theta_h_dot: 1.0}\n",
        ("controllers.csv",), timing=("ms_per_stride",)),
    KillCase("continuation", shipped("continuation_downward_speed", ("range: [0.05, 1.5]", "range: [0.4, 0.6]"),
                                     rename="continuation"),
             ("branch.csv",), timing=()),
    KillCase("curve", shipped("curve_slip_band", ("second_range: [1424.8, 2224.8]", "second_range: [1784.8, 1790.0]"),
                              rename="curve"),
             ("branch.csv", "curve.csv"), timing=()),
)
