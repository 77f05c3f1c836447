"""Figures of an ``adaptive`` run (the thesis's time-varying control, sec. 4.7): the
apex states and controls stride by stride, where the adaptive phase ended (its control
frozen, or a fall), and the strides under the frozen control.

Drawing only, with the conventions of :mod:`baslip.viz.figures`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from baslip.model.dynamics import APEX
from baslip.model.quantities import ANY_DESIGN
from baslip.viz.figures import LABELS, _in, _save, plt, shown


def adaptive_figures(rows: list[dict], out_dir: Path | None, *, problem: str = "") -> list[Path | None]:
    """The figures of an adaptive run's strides.csv rows: the apex states and the controls
    stride by stride (where the adaptive phase ended marked), and the strides under the
    frozen control if there were any.

    Parameters
    ----------
    rows
        strides.csv rows (``phase``, ``n``, the apex, the law's controls, ``eps``).
    out_dir
        Where the PNGs go; None returns the figures open instead.
    problem
        The problem's name, shown on each figure.
    """
    adaptive = [r for r in rows if r["phase"] == "adaptive"]
    frozen = [r for r in rows if r["phase"] == "frozen"]
    if not adaptive:
        return []

    def col(rs, name):
        return np.array([float(r[name]) for r in rs])

    n = col(adaptive, "n")
    end = _adaptive_end(rows, adaptive, frozen)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    axes[0].plot(col(adaptive, "ydot"), col(adaptive, "z"), "-", lw=0.8)
    axes[0].set_xlabel(LABELS["ydot"])
    axes[0].set_ylabel(LABELS["z"])
    axes[0].ticklabel_format(useOffset=False)
    for ax, name in zip(axes[1:], ("ydot", "z")):
        ax.plot(n, col(adaptive, name), "-", lw=0.8)
        ax.set_xlabel("stride n")
        ax.set_ylabel(LABELS[name])
        ax.ticklabel_format(useOffset=False)
        _mark_end(ax, end)
    path_states = _save(fig, _in(out_dir, "adaptive_states.png"), problem=problem)

    # The hip law's controls are the rows' columns that are design quantities but not apex ones.
    controls = [k for k in adaptive[0] if k in ANY_DESIGN and k not in APEX.names]
    panels = (*controls, "eps")
    panel_rows = math.ceil(len(panels) / 3)
    fig, axes = plt.subplots(panel_rows, 3, figsize=(12, 3.25 * panel_rows), squeeze=False)
    for ax in axes.ravel()[len(panels):]:
        ax.set_visible(False)
    for ax, name in zip(axes.ravel(), panels):
        values = col(adaptive, name)
        ax.plot(n, values if name == "eps" else shown(name, values), "-", lw=0.8)
        ax.set_xlabel("stride n")
        ax.set_ylabel(LABELS[name])
        if name == "eps":
            ax.set_yscale("log")
        else:
            ax.ticklabel_format(useOffset=False)
            _unless_round_off(ax, shown(name, values))
        _mark_end(ax, end)
    path_controls = _save(fig, _in(out_dir, "adaptive_controls.png"), problem=problem)

    paths = [path_states, path_controls]
    if frozen:
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
        m = col(frozen, "n")
        ax.semilogy(m, col(frozen, "eps"), "-o", ms=3)
        ax.set_xlabel("stride after freezing the control")
        ax.set_ylabel("|X_n - X_2048| / |X_2048|")
        ax.set_title(f"last control held fixed: {len(frozen)} strides before the fall", fontsize=10)
        path = _in(out_dir, "frozen_control.png")
        paths.append(_save(fig, path, problem=problem))
    return paths


def _adaptive_end(rows: list[dict], adaptive: list[dict], frozen: list[dict]) -> tuple[float, str, str] | None:
    """(stride, words, colour) of how the adaptive phase ended: its control frozen, or a
    fall (a fall row, or a last stride whose solve had no finite residual); None if it ran
    to its end without either."""
    last = float(adaptive[-1]["n"])
    if frozen:
        return last, f"control frozen after stride {last:.0f}", "tab:purple"
    fell = any(r["phase"] == "fall" for r in rows) or not math.isfinite(float(adaptive[-1]["eps"]))
    return (last, f"fall after stride {last:.0f}", "tab:red") if fell else None


def _mark_end(ax, end: tuple[float, str, str] | None) -> None:
    """A dashed line at the end of the adaptive phase, named in the legend."""
    if end is not None:
        ax.axvline(end[0], color=end[2], ls="--", lw=0.9, label=end[1])
        ax.legend(fontsize=7, loc="best")


def _unless_round_off(ax, values) -> None:
    """If ``values`` change only by round-off (a control held fixed), show them as the
    constant they are, on a readable scale, instead of magnifying the noise."""
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return
    middle = float(np.mean(finite))
    if np.ptp(finite) <= 1e-9 * max(1.0, abs(middle)):
        band = 0.05 * max(1.0, abs(middle))
        ax.set_ylim(middle - band, middle + band)
        ax.text(0.5, 0.9, "held constant", transform=ax.transAxes, ha="center", fontsize=8, color="0.4")
