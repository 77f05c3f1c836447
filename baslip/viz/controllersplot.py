"""Figures of a ``controllers`` study: how each stride-to-stride controller fares on
perturbed starts, and the share of starts each brings back by box size.

Drawing only, with the conventions of :mod:`baslip.viz.figures`.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from baslip.problem.study import CONTROLLER_KINDS
from baslip.viz.figures import LABELS, _in, _save, legend_below, plt, shown
from baslip.viz.labels import CONTROLLER_NAMES

OUTCOME_STYLE = {"converged": ("o", "tab:blue"), "settled": ("d", "tab:green"), "bounded": ("s", "tab:orange"),
                 "fell": ("x", "tab:red")}


def controllers_figure(rows: list[dict], perturbation: dict, out_dir: Path | None, *, problem: str = "") -> Path | None:
    """Left: the share of perturbed starts each controller brings back to the gait, keeps
    up without converging, or lets fall. Right, per controller: the starts in the plane of
    the two most perturbed apex quantities, marked by outcome."""
    names = [n for n in CONTROLLER_KINDS if any(r["controller"] == n for r in rows)]
    axes_names = sorted(perturbation, key=lambda n: -perturbation[n] / _NOMINAL_APEX[n])[:2]
    if len(axes_names) < 2:
        axes_names = (axes_names + ["z", "ydot"])[:2]
    fig, axes = plt.subplots(1, 1 + len(names), figsize=(4.0 * (1.5 + len(names)), 3.8),
                             gridspec_kw={"width_ratios": [1.5] + [1] * len(names)})
    outcomes = tuple(OUTCOME_STYLE)
    bottom = np.zeros(len(names))
    for outcome in outcomes:
        share = np.array([np.mean([r["outcome"] == outcome for r in rows if r["controller"] == n]) for n in names])
        axes[0].bar([textwrap.fill(CONTROLLER_NAMES[n], 12) for n in names], share, bottom=bottom,
                    color=OUTCOME_STYLE[outcome][1], label=outcome)
        bottom += share
    axes[0].set_ylabel("share of perturbed starts")
    axes[0].tick_params(axis="x", labelsize=7)
    axes[0].set_ylim(0, 1)
    axes[0].legend(fontsize=8, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=len(outcomes), frameon=False)
    for ax, name in zip(axes[1:], names):
        mine = [r for r in rows if r["controller"] == name]
        for outcome in outcomes:
            pick = [r for r in mine if r["outcome"] == outcome]
            if pick:
                marker, color = OUTCOME_STYLE[outcome]
                ax.plot(shown(axes_names[0], [r[f"d_{axes_names[0]}"] for r in pick]),
                        shown(axes_names[1], [r[f"d_{axes_names[1]}"] for r in pick]),
                        marker, color=color, ms=4, ls="none", label=outcome)
        ax.set_title(CONTROLLER_NAMES[name], fontsize=9)
        ax.set_xlabel("change of " + LABELS[axes_names[0]])
        ax.set_ylabel("change of " + LABELS[axes_names[1]])
        legend_below(ax, fontsize=7)
    path = _in(out_dir, "controllers.png")
    return _save(fig, path, problem=problem)


_NOMINAL_APEX = {"z": 0.1, "theta_h": 0.1, "ydot": 0.1, "theta_h_dot": 1.0}


def basin_figure(basins: dict, title: str, out_dir: Path | None) -> Path | None:
    """The share of starts each controller brings back (to the gait, or onto its family)
    against the box size (a multiple of the perturbation's half-widths), with 95 %
    intervals, and each controller's starts a box in the legend; the 90 % line dashed."""
    fig, ax = plt.subplots(figsize=(8.8, 3.8))
    for k, (name, basin) in enumerate(basins.items()):
        boxes = np.array([b["box"] for b in basin["per_box"]]) * (1 + 0.03 * (k - 1.5))  # spread the bars
        share = np.array([b["returned_fraction"] or 0.0 for b in basin["per_box"]])
        low, high = (np.array([b["ci95"][i] for b in basin["per_box"]]) for i in (0, 1))
        spread = [np.maximum(share - low, 0.0), np.maximum(high - share, 0.0)]  # round-off can cross zero
        # The re-solving controllers run fewer starts than the batched ones: the legend says how many.
        label = f"{CONTROLLER_NAMES.get(name, name)}; {basin['per_box'][0]['samples']:,} starts a box"
        ax.errorbar(boxes, share, yerr=spread, marker="o", ms=4, capsize=3, label=label)
    ax.axhline(0.9, color="0.5", ls="--", lw=0.8)
    ax.set_xscale("log", base=2)
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("box half-widths [multiples of the study's perturbation]")
    ax.set_ylabel("share of starts that return")
    ax.set_title("share of starts that return, by box size (95 % intervals)", fontsize=10)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))  # beside the axes: never over a curve
    return _save(fig, _in(out_dir, "basins.png"), problem=title)
