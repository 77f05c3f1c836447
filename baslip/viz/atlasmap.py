"""The figure of an atlas study: its charts in two chosen quantities, coloured by the
spectral radius on a log scale, with the stability boundary (radius 1), the stable part
shaded and the most stable chart marked; one panel per cell."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.tri import Triangulation

from baslip.model.quantities import quantity_text
from baslip.viz.colours import radius_colorbar, radius_colours
from baslip.viz.figures import LABELS, _in, _save, plt, shown


def atlas_figure(charts: list[dict], names: list[str], plot: tuple[str, str], out_dir: Path | None,
                 title: str) -> Path | None:
    """``atlas.png``: a panel per cell (the values of ``names``) of its verified charts.

    Parameters
    ----------
    charts : list of dict
        atlas.csv rows (numbers as floats).
    names : list of str
        The swept quantities that name a cell.
    plot : (str, str)
        The two quantities on the axes (angles shown in degrees).
    out_dir : Path or None
        Where to write the figure (None: lay it out and leave it open).
    title : str
        The figure's title: the problem's name, hip law and body
        (:func:`baslip.viz.labels.figure_title`).
    """
    cells = sorted({tuple(c[f"sweep_{n}"] for n in names) for c in charts})
    columns = min(3, max(len(cells), 1))
    rows_count = max(1, math.ceil(len(cells) / columns))
    # At least 9 in wide, so that the two title lines fit above a single cell.
    fig, axes = plt.subplots(rows_count, columns, figsize=(max(4.6 * columns + 1.2, 9.0), 3.9 * rows_count + 0.6),
                             squeeze=False, layout="constrained")
    radii = np.array([c["spectral_radius"] for c in charts if c["status"] == "converged"], dtype=float)
    colours = radius_colours(radii)  # blues below 1, reds above
    image = None
    for ax, cell in zip(axes.flat, cells):
        mine = [c for c in charts if tuple(c[f"sweep_{n}"] for n in names) == cell and c["status"] == "converged"]
        image = _panel(ax, mine, plot, colours, ", ".join(quantity_text(n, v, 6) for n, v in zip(names, cell))) or image
    for ax in list(axes.flat)[len(cells):]:
        ax.set_visible(False)
    if image is not None:
        radius_colorbar(fig, image, axes, LABELS["spectral_radius"] + " (log scale; blue: stable)")
    fig.suptitle(f"{title}\natlas of the fixed points, coloured by spectral radius; "
                 "stable part shaded, radius 1 drawn, star = most stable chart", fontsize=10)
    return _save(fig, _in(out_dir, "atlas.png"), tight=False)


def _panel(ax, charts: list[dict], plot: tuple[str, str], colours, cell: str):
    """One cell's verified ``charts`` on ``ax``, titled by ``cell``; the colour image (None
    if there is no chart). The least radius goes in the title, not a legend, which would
    sit on the charts."""
    if not charts:
        ax.text(0.5, 0.5, "no verified chart", ha="center", va="center", transform=ax.transAxes)
        ax.set_title(f"{cell}: no verified chart", fontsize=9)
        return None
    x = shown(plot[0], [c[plot[0]] for c in charts])
    y = shown(plot[1], [c[plot[1]] for c in charts])
    radius = np.array([c["spectral_radius"] for c in charts], dtype=float)
    if len(charts) >= 3 and np.ptp(x) > 0 and np.ptp(y) > 0:
        mesh = Triangulation(x, y)
        level = np.log10(radius)
        if level.min() < 0 < level.max():
            ax.tricontourf(mesh, level, levels=[level.min() - 1, 0.0], colors=["#9ecae1"], alpha=0.5)
            ax.tricontour(mesh, level, levels=[0.0], colors="k", linewidths=0.8)
    image = ax.scatter(x, y, c=radius, s=6, cmap=colours[0], norm=colours[1], linewidths=0)
    best = int(np.argmin(radius))
    # Drawn over the frame: the most stable chart often lies on a bound, at the panel's edge.
    ax.plot(x[best], y[best], "*", ms=13, mfc="gold", mec="k", clip_on=False, zorder=5)
    ax.use_sticky_edges = False  # the filled contours would pin the limits to the charts
    ax.margins(0.03)
    ax.set_title(f"{cell}: {len(charts)} charts, least radius {radius[best]:.3g}", fontsize=9)
    ax.set_xlabel(LABELS.get(plot[0], plot[0]))
    ax.set_ylabel(LABELS.get(plot[1], plot[1]))
    return image
