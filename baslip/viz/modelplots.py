"""Figures of a described model's runs: its branch, its atlas's chart centres, its basins, and
several branches' spectral radii side by side.

They take plain rows (dicts of values by name), so that they know nothing of the model
beyond the names and units they are given.
"""

from __future__ import annotations

import io

import matplotlib.pyplot as plt
import numpy as np

from baslip.viz.backend import use_file_backend

use_file_backend()


def _label(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def png(figure) -> bytes:
    """The figure as PNG bytes (then closed)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=120)
    plt.close(figure)
    return buffer.getvalue()


def branch_figure(rows: list[dict], parameter: str, quantity: str, units: dict, title: str):
    """``quantity`` (above) and the spectral radius (below) along the branch against
    ``parameter``: stable points solid, unstable dashed, special points marked and named."""
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(6.4, 6.0), sharex=True)
    x = np.array([r[parameter] for r in rows])
    stable = np.array([r["spectral_radius"] < 1.0 for r in rows])
    for ax, name in ((top, quantity), (bottom, "spectral_radius")):
        y = np.array([r[name] for r in rows])
        for flag, style, label in ((True, "-", "stable"), (False, "--", "unstable")):
            ax.plot(np.where(stable == flag, x, np.nan), np.where(stable == flag, y, np.nan), style,
                    color="C0" if flag else "C3", label=label)
        for row in rows:
            if row["special"]:
                ax.plot(row[parameter], row[name], "ko", markersize=4)
                ax.annotate(row["special"].replace("_", " "), (row[parameter], row[name]), fontsize=8,
                            xytext=(4, 4), textcoords="offset points")
    top.set_ylabel(_label(quantity, units.get(quantity, "")))
    bottom.axhline(1.0, color="0.6", linewidth=0.8)
    bottom.set_ylabel("spectral radius")
    bottom.set_xlabel(_label(parameter, units.get(parameter, "")))
    top.set_title(title)
    top.legend(loc="best", fontsize=8)
    figure.tight_layout()
    return figure


def atlas_figure(rows: list[dict], x: str, y: str, units: dict, title: str):
    """Gaits (an atlas's chart centres, a sweep's points) in (``x``, ``y``), coloured by
    spectral radius, the stable ones ringed."""
    figure, ax = plt.subplots(figsize=(6.4, 4.6))
    radius = np.array([r["spectral_radius"] for r in rows])
    points = ax.scatter([r[x] for r in rows], [r[y] for r in rows], c=np.minimum(radius, 3.0), cmap="viridis", s=18)
    stable = [r for r in rows if r["spectral_radius"] < 1.0]
    ax.scatter([r[x] for r in stable], [r[y] for r in stable], facecolors="none", edgecolors="k", s=40)
    # Said in the title, not a legend, which would hide points in its corner.
    figure.colorbar(points, ax=ax, label="spectral radius (capped at 3); stable ringed")
    ax.set_xlabel(_label(x, units.get(x, "")))
    ax.set_ylabel(_label(y, units.get(y, "")))
    ax.set_title(title)
    figure.tight_layout()
    return figure


def curves_figure(rows: list[dict], first: str, second: str, units: dict, title: str):
    """The bifurcation curves in the plane of their two parameters, one line per curve,
    codimension-two points marked and named."""
    figure, ax = plt.subplots(figsize=(6.4, 4.6))
    for number in sorted({r["curve"] for r in rows}):
        points = [r for r in rows if r["curve"] == number]
        ax.plot([r[first] for r in points], [r[second] for r in points], "-",
                label=points[0]["type"].replace("_", " "))
        for r in points:
            if r["special"]:
                ax.plot(r[first], r[second], "ko", markersize=4)
                ax.annotate(r["special"].replace("_", " "), (r[first], r[second]), fontsize=8, xytext=(4, 4),
                            textcoords="offset points")
    ax.set_xlabel(_label(first, units.get(first, "")))
    ax.set_ylabel(_label(second, units.get(second, "")))
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    figure.tight_layout()
    return figure


def basins_figure(rows: list[dict], x: str, y: str, units: dict, title: str):
    """One panel per controller: its grid of starts in (``x``, ``y``), those that returned
    to the gait filled, the others open."""
    names = list(dict.fromkeys(r["controller"] for r in rows))
    figure, axes = plt.subplots(1, len(names), figsize=(3.4 * len(names), 3.6), sharex=True, sharey=True,
                                squeeze=False)
    for ax, name in zip(axes[0], names):
        mine = [r for r in rows if r["controller"] == name]
        back = [r for r in mine if r["returned"]]
        ax.scatter([r[x] for r in mine], [r[y] for r in mine], facecolors="none", edgecolors="0.6", s=16,
                   label="falls or strays")
        ax.scatter([r[x] for r in back], [r[y] for r in back], color="C0", s=16, label="returns")
        ax.set_title(f"{name}: {len(back)} of {len(mine)}", fontsize=9)
        ax.set_xlabel(_label(x, units.get(x, "")))
    axes[0][0].set_ylabel(_label(y, units.get(y, "")))
    axes[0][0].legend(loc="best", fontsize=7)
    figure.suptitle(title)
    figure.tight_layout()
    return figure


def radii_figure(branches: list[tuple[str, list[dict]]], parameter: str, unit: str, title: str):
    """The spectral radius (log scale) along several labelled branches against one
    ``parameter`` [``unit``], each in its own colour, stable points solid and unstable
    dashed: gaits of different kinds (walks and runs, say) at one body, side by side."""
    figure, ax = plt.subplots(figsize=(6.4, 4.2))
    for index, (label, rows) in enumerate(branches):
        x = np.array([r[parameter] for r in rows])
        y = np.array([r["spectral_radius"] for r in rows])
        stable = y < 1.0
        ax.plot(np.where(stable, x, np.nan), np.where(stable, y, np.nan), "-", color=f"C{index}",
                label=f"{label}, stable")
        ax.plot(np.where(~stable, x, np.nan), np.where(~stable, y, np.nan), "--", color=f"C{index}",
                label=f"{label}, unstable")
    ax.axhline(1.0, color="0.6", linewidth=0.8)
    ax.set_yscale("log")
    ax.set_xlabel(_label(parameter, unit))
    ax.set_ylabel("spectral radius (log scale)")
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    figure.tight_layout()
    return figure
