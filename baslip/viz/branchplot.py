"""The branch diagram of a continuation: its branches, stable segments solid and
unstable dashed, its special points marked and labelled where the labels clear the
branches, and a zoomed inset for a branch too small to see (a short period-doubled one).

Drawing only, like :mod:`baslip.viz.figures`, whose helpers it shares.
"""

from __future__ import annotations

import numpy as np
from matplotlib.ticker import MaxNLocator

from baslip.model.quantities import NOMINAL, quantity_text
from baslip.viz.figures import LABELS, _save, plt, shown
from baslip.viz.labels import SPECIAL_NAMES
from baslip.viz.placement import clear_placement


def bifurcation_diagram(rows: list[dict], parameter: str, quantity: str, path=None, *, problem: str = ""):
    """Branch diagram: stable segments solid, unstable dashed, special points labelled.
    ``path`` is a file name or a binary file object; without one the Figure is returned.

    Rows carry ``branch``, ``strides`` and ``orbit`` (the apexes of the orbit): an orbit
    of N strides is drawn at each of its N apexes, so a period-2 branch shows both.
    """
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    segments = _draw_branches(ax, rows, parameter, quantity)
    markers = {"fold": ("s", "tab:red"), "turning_point": ("<", "tab:brown"), "period_doubling": ("D", "tab:green"),
               "neimark_sacker": ("^", "tab:purple"), "branch_point": ("o", "tab:orange")}
    drawn = np.vstack([np.column_stack(xy) for xy, _ in segments])
    ax.set_xlabel(LABELS.get(parameter, f"{parameter}"))
    ax.set_ylabel(LABELS.get(quantity, quantity))
    fig.tight_layout()  # the frame the labels must stay inside
    placed: list = []
    for r in (r for r in rows if r["special"]):
        marker, color = markers[r["special"]]
        xv, yv = shown(parameter, [r[parameter]])[0], shown(quantity, [_orbit_value(r, 0, quantity)])[0]
        # Hollow, under the branches: a short branch born here stays visible.
        ax.plot(xv, yv, marker, color=color, ms=8, mfc="none", mew=1.5, zorder=1.5)
        # The label goes where it clears the branches and the other labels, inside the
        # frame, in its marker's colour and tied to it by a line.
        where = clear_placement(ax, (xv, yv), drawn, placed)
        ax.annotate(f"{SPECIAL_NAMES[r['special']]}\n{quantity_text(parameter, _rounded(parameter, r[parameter]), 6)}", (xv, yv),
                    textcoords="offset points", xytext=where.offset, ha=where.ha, va=where.va, fontsize=8,
                    color=color, arrowprops={"arrowstyle": "-", "color": color, "lw": 0.7})
    if _zoom_small_branches(ax, segments):  # the legend goes above the frame, clear of the inset
        ax.legend(fontsize=8, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, frameon=False)
    else:
        ax.legend(fontsize=8)
    saved = _save(fig, path, problem=problem)
    return fig if path is None else saved


def _draw_branches(ax, rows, parameter, quantity) -> list:
    """Each branch of ``rows`` on ``ax``, stable segments solid and unstable dashed, with a
    legend entry per style drawn; returns ((x, y), style-and-colour) of every segment."""
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    segments: list = []
    for number in sorted({r["branch"] for r in rows}):
        branch = [r for r in rows if r["branch"] == number]
        color = colors[int(number) % len(colors)]
        stable = [r["stable"] for r in branch]
        for k in range(len(branch[0].get("orbit", [None]))):
            x = shown(parameter, [_orbit_value(r, k, parameter) for r in branch])
            y = shown(quantity, [_orbit_value(r, k, quantity) for r in branch])
            styles = ["-" if stable[i] and stable[i + 1] else "--" for i in range(len(branch) - 1)]
            for first, end in _runs(styles):  # one line a run: a dash is longer than a step
                ax.plot(x[first : end + 1], y[first : end + 1], styles[first], color=color)
            segments.extend(((x[i : i + 2], y[i : i + 2]), (style, color, int(number))) for i, style in enumerate(styles))
        strides = int(branch[0]["strides"])
        for style, word, present in (("-", "stable", any(stable)), ("--", "unstable", not all(stable))):
            if present:  # only the styles drawn get a legend entry
                ax.plot([], [], style, color=color, label=f"{strides}-stride orbits, {word}")
    return segments


#: A special point's parameter below this share of the quantity's nominal size is shown as
#: 0: a point located at 0 by structure lands within the corrector's tolerance of it, and
#: its digits there are noise (r_vpp = 1.7e-10 m at the VPP branch point).
ZERO_SHARE = 1e-6


def _rounded(name: str, value: float) -> float:
    """``value`` of quantity ``name`` for a label: 0 where it is noise about 0 (:data:`ZERO_SHARE`)."""
    return 0.0 if abs(value) < ZERO_SHARE * NOMINAL.get(name, 1.0) else value


def _runs(items: list) -> list[tuple[int, int]]:
    """(first, end) of each run of equal neighbours in ``items``: items[first:end] are
    equal, and the runs cover ``items`` in order."""
    bounds = [0] + [i for i in range(1, len(items)) if items[i] != items[i - 1]] + [len(items)]
    return [(first, end) for first, end in zip(bounds[:-1], bounds[1:]) if end > first]


#: A branch smaller than this on screen, both ways [px], is shown again in a zoomed inset.
SMALL_BRANCH_PX = 60.0


#: The zoomed inset's size and its candidate places (lower left corners), as fractions of
#: the axes: the four corners, then the middles of the top and bottom edges.
INSET_SIZE = (0.35, 0.38)
INSET_PLACES = ((0.04, 0.56), (0.61, 0.56), (0.04, 0.06), (0.61, 0.06), (0.325, 0.56), (0.325, 0.06))
#: Points sampled along each segment to find the emptiest place for the inset.
INSET_SAMPLES = 20


def _zoom_small_branches(ax, segments) -> bool:
    """An inset, in the emptiest corner, that zooms on the first branch after the first
    whose extent on screen is under :data:`SMALL_BRANCH_PX` both ways (a short
    period-doubled branch would otherwise hide under its marker). Says whether it drew one."""
    numbers = sorted({number for _, (_, _, number) in segments if number > 0})
    for number in numbers:
        points = np.vstack([np.column_stack(xy) for xy, (_, _, n) in segments if n == number])
        screen = ax.transData.transform(points)
        if np.ptp(screen[:, 0]) >= SMALL_BRANCH_PX or np.ptp(screen[:, 1]) >= SMALL_BRANCH_PX:
            continue
        # Every segment sampled along its length (a long segment has only its two ends
        # among the points), in axes coordinates: the inset goes where fewest lie.
        along = np.linspace(0.0, 1.0, INSET_SAMPLES)[:, None]
        every = ax.transAxes.inverted().transform(ax.transData.transform(np.vstack(
            [np.column_stack(xy)[0] + along * np.diff(np.column_stack(xy), axis=0) for xy, _ in segments])))
        width, height = INSET_SIZE
        crowding = {where: int(np.sum((every[:, 0] >= where[0]) & (every[:, 0] <= where[0] + width)
                                      & (every[:, 1] >= where[1]) & (every[:, 1] <= where[1] + height)))
                    for where in INSET_PLACES}
        corner = min(INSET_PLACES, key=lambda where: crowding[where])  # ties keep the first
        inset = ax.inset_axes([corner[0], corner[1], width, height])
        for line in ax.get_lines():
            if len(line.get_xdata()) > 1:  # the branches' lines, as drawn (not markers or legend keys)
                inset.plot(line.get_xdata(), line.get_ydata(), line.get_linestyle(), color=line.get_color())
        pad_x, pad_y = 0.15 * max(np.ptp(points[:, 0]), 1e-12), 0.15 * max(np.ptp(points[:, 1]), 1e-12)
        inset.set_xlim(points[:, 0].min() - pad_x, points[:, 0].max() + pad_x)
        inset.set_ylim(points[:, 1].min() - pad_y, points[:, 1].max() + pad_y)
        inset.tick_params(labelsize=7)
        for axis in (inset.xaxis, inset.yaxis):
            axis.set_major_locator(MaxNLocator(3))
        ax.indicate_inset_zoom(inset, edgecolor="0.4")
        return True
    return False


def _orbit_value(row: dict, k: int, quantity: str) -> float:
    """``quantity`` at apex k of the row's orbit (controls and model parameters are the
    same at every apex)."""
    if "orbit" not in row:  # read back from branch.csv: the first apex only
        return row[quantity]
    return row["orbit"][k][quantity] if quantity in row["orbit"][k] else row[quantity]


# --- stability-optimal gaits ----------------------------------------------------------------
