"""Figures of the studies, as PNG files with labelled axes and units.

Angles are shown in degrees. Stable fixed points are drawn as filled blue circles,
unstable ones as red crosses, and points without a verified fixed point as grey dots.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from baslip.viz.backend import hand_over, use_file_backend

use_file_backend()
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from baslip.model.quantities import UNITS  # noqa: E402
from baslip.status import Status
from baslip.viz.colours import colour_limits, radius_colorbar, radius_colours  # noqa: E402
from baslip.viz.placement import clear_placement  # noqa: E402

DEG = 180 / math.pi
ANGLES = ("theta_h", "theta2_des", "theta_td")
LABELS = {
    # Every quantity with its unit, whatever hip law it belongs to; the entries below word them.
    **{name: f"{name} [{unit}]" for name, unit in UNITS.items()},
    "z": "apex height z [m]",
    "ydot": "forward speed ydot [m/s]",
    "theta_h": "body angle theta_h [deg]",
    "theta_h_dot": "body rate theta_h_dot [rad/s]",
    "Kp": "Kp [N m/rad]",
    "Kd": "Kd [N m s/rad]",
    "theta2_des": "theta2_des [deg]",
    "theta2_dot_des": "theta2_dot_des [rad/s]",
    "theta_td": "touchdown angle theta_td [deg]",
    "r_vpp": "virtual pivot above the CoM r_vpp [m]",
    "spectral_radius": "largest |multiplier| (non-trivial)",
    "residual": "residual eps (eq. 4.1)",
    "eps": "eps between consecutive apexes",
    "energy": "apex energy [J]",
    "m": "mass m [kg]", "I": "inertia I [kg m^2]", "k": "leg stiffness k [N/m]",
    "rho0": "leg rest length rho0 [m]", "d": "hip offset d [m]", "g": "gravity g [m/s^2]",
}


def shown(name: str, values):
    """Values as plotted: angles in degrees."""
    values = np.asarray(values, dtype=float)
    return values * DEG if name in ANGLES else values


#: Formats figures can be written in; the run's is matplotlib's ``savefig.format``
#: (``baslip solve --format`` sets it for the run), PNG otherwise.
FORMATS = ("png", "svg", "pdf")
PNG_DPI = 110


def figure_format() -> str:
    """The format figures are written in now: matplotlib's savefig.format if it is one of
    :data:`FORMATS`, else png."""
    chosen = str(plt.rcParams["savefig.format"]).lower()
    return chosen if chosen in FORMATS else "png"


def figure_file(stem: str) -> str:
    """A figure's file name in the current format, e.g. ``diagram.svg``."""
    return f"{stem}.{figure_format()}"


@dataclass(frozen=True)
class Unwritten:
    """Where a figure returned open (not written) goes: nowhere, but under its file's name."""

    name: str


def _in(out_dir: Path | None, name: str) -> Path | Unwritten:
    """Where a figure goes: ``out_dir / name``, or, when the figure is to be returned open
    instead of written (no ``out_dir``), nowhere under that name."""
    return Unwritten(name) if out_dir is None else out_dir / name


def legend_beside(ax, fontsize: float = 8) -> None:
    """The legend of ``ax`` to the right of its frame, where it cannot cover data."""
    ax.legend(fontsize=fontsize, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, frameon=False)


def legend_below(ax, fontsize: float = 8, columns: int = 3) -> None:
    """The legend of ``ax`` under its frame and axis label (for a figure whose right side
    holds a colour bar), in ``columns`` columns, where it cannot cover data."""
    ax.legend(fontsize=fontsize, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=columns, frameon=False)


def _save(fig, path, tight: bool = True, problem: str = "") -> Path | None:
    """Save to ``path`` (a file name, whose suffix becomes the current format, or a
    binary file object) and close the figure; return where it went. With ``path`` None
    only lay the figure out (it is returned to the caller). ``tight`` False keeps a
    layout of the caller's own (constrained layout, which places shared colour bars).
    ``problem`` names the figure's problem at its top left, so that a figure taken out of
    its folder says what it shows."""
    if problem:
        fig.suptitle(problem, x=0.01, ha="left", fontsize=9, color="0.3")
    if tight:
        fig.tight_layout()
    if isinstance(path, Unwritten):
        fig.set_label(Path(path.name).stem)  # the name it is listed under (RunResults.plot, which
        return None  # finds it among pyplot's figures and hands it to a Figures mapping)
    if path is None:
        hand_over(fig)
        return None
    fmt = figure_format()
    if isinstance(path, (str, Path)):
        path = Path(path).with_suffix(f".{fmt}")
    fig.savefig(path, dpi=PNG_DPI if fmt == "png" else None, format=fmt)
    plt.close(fig)
    return path


def _column(rows, name):
    return np.array([r[name] if isinstance(r[name], float) else np.nan for r in rows], dtype=float)


def _classes(rows):
    converged = np.array([r["status"] == Status.CONVERGED for r in rows])
    stable = np.array([r["status"] == Status.CONVERGED and r["stable"] is True for r in rows])
    return stable, converged & ~stable, ~converged


# --- sweeps -------------------------------------------------------------------------------


def sweep_figures(rows: list[dict], names: list[str], out_dir: Path | None, *, problem: str = "") -> list[Path | None]:
    """1-D sweeps: z, theta_h, spectral radius and residual against the swept quantity.
    2-D sweeps: maps of theta_h and of the spectral radius, with the stable region.
    ``problem``: the problem's name, shown on each figure."""
    if not rows:
        return []
    if len(names) == 1:
        return [_sweep_line(rows, names[0], y, out_dir, problem) for y in ("z", "theta_h", "spectral_radius", "residual")
                if _shows_something(rows, names, y)]
    return [_sweep_map(rows, names, value, out_dir, problem) for value in ("theta_h", "spectral_radius")
            if _shows_something(rows, names, value)]


def _shows_something(rows: list[dict], names: list[str], quantity: str) -> bool:
    """Whether a sweep's figure of ``quantity`` shows anything: the spectral radius and the
    residual always do; an apex quantity only if it is not swept and varies (:func:`_varies`)."""
    return quantity in ("spectral_radius", "residual") or (quantity not in names and _varies(rows, quantity))


def _varies(rows: list[dict], quantity: str) -> bool:
    """Whether ``quantity`` takes more than one value over the verified rows: a figure of a
    quantity the problem holds, or that its gaits share by symmetry (theta_h = 90 deg for
    every VPP gait: spread over 1e-11 rad by the solver), or of none verified, would show
    nothing."""
    values = [r[quantity] for r in rows if r["status"] == Status.CONVERGED and isinstance(r[quantity], float)]
    return len(values) > 1 and max(values) - min(values) > 1e-8 * max(1.0, max(abs(v) for v in values))


def _sweep_line(rows, name, quantity, out_dir, problem: str = "") -> Path | None:
    x = shown(name, _column(rows, f"sweep_{name}"))
    y = _column(rows, quantity)
    y = y if quantity in ("spectral_radius", "residual") else shown(quantity, y)
    stable, unstable, missing = _classes(rows)
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for mask, style, color, word in ((stable, "o", "tab:blue", "stable"), (unstable, "x", "tab:red", "unstable")):
        if mask.any():  # only what is there gets a legend entry
            ax.plot(x[mask], y[mask], style, color=color, ms=4, label=word)
    if quantity in ("z", "theta_h", "residual") and missing.any():
        ax.plot(x[missing], y[missing], ".", color="0.6", ms=4, label="not verified / failed")
    elif missing.any():
        for xv in x[missing]:
            ax.axvline(xv, color="0.85", lw=0.8, zorder=0)
        ax.plot([], [], "-", color="0.85", label="no verified fixed point")
    if quantity == "spectral_radius":
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_yscale("log")
    if quantity == "residual":
        ax.axhline(1e-10, color="k", lw=0.8, ls="--", label="verification threshold")
        ax.set_yscale("log")
    ax.set_xlabel(LABELS.get(name, name))
    ax.set_ylabel(LABELS[quantity])
    legend_beside(ax)
    path = _in(out_dir, f"{quantity}.png")
    return _save(fig, path, problem=problem)


def _grid(rows, names, quantity):
    a = sorted({r[f"sweep_{names[0]}"] for r in rows})
    b = sorted({r[f"sweep_{names[1]}"] for r in rows})
    values = np.full((len(b), len(a)), np.nan)
    stable = np.zeros_like(values, dtype=bool)
    for r in rows:
        i, j = b.index(r[f"sweep_{names[1]}"]), a.index(r[f"sweep_{names[0]}"])
        if r["status"] == Status.CONVERGED and isinstance(r[quantity], float):
            values[i, j] = r[quantity]
            stable[i, j] = r["stable"] is True
    return np.array(a), np.array(b), values, stable


def _sweep_map(rows, names, quantity, out_dir, problem: str = "") -> Path | None:
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    draw_map(fig, ax, rows, names, quantity)
    legend_below(ax)
    return _save(fig, _in(out_dir, f"{quantity}_map.png"), problem=problem)


def draw_map(fig, ax, rows, names, quantity) -> None:
    """A sweep's map of ``quantity`` over its two axes on ``ax``, with a colour bar; stable
    cells ringed, unstable ones crossed, cells without a verified fixed point marked. With
    one value along an axis there are no cells (their width would be invented): the points
    are then markers, ticked at their values, and the title says so."""
    a, b, values, stable = _grid(rows, names, quantity)
    A, B = np.meshgrid(shown(names[0], a), shown(names[1], b))
    if quantity == "spectral_radius":
        painted, (cmap, norm) = values, radius_colours(values)
        scale = {"cmap": cmap, "norm": norm}
    else:
        painted, cmap = shown(quantity, values), plt.get_cmap("viridis" if quantity == "theta_h" else "coolwarm")
        scale = {"cmap": cmap.with_extremes(bad="0.85"), **colour_limits(quantity, shown(quantity, values))}
    if len(a) > 1 and len(b) > 1:
        image = ax.imshow(painted, origin="lower", aspect="auto", extent=_extent(A[0], B[:, 0]), **scale)
    else:
        image = ax.scatter(A.ravel(), B.ravel(), c=painted.ravel(), marker="s", s=160, **scale)
        single = [(name, v, tick) for name, v, tick in zip(names, (A[0], B[:, 0]), (ax.set_xticks, ax.set_yticks))
                  if len(v) == 1]
        for _, v, tick in single:
            tick(v)
        ax.set_title(f"one value of {' and '.join(f'{n} {v[0]:.4g}' for n, v, _ in single)}: points, not cells", fontsize=9)
    if quantity == "spectral_radius":
        radius_colorbar(fig, image, ax, LABELS[quantity] + " (log scale; blue: stable)")
    else:
        fig.colorbar(image, ax=ax, label=LABELS[quantity])
    unstable = np.isfinite(values) & ~stable
    if stable.any():  # only what is there gets a legend entry
        ax.plot(A[stable], B[stable], "o", mfc="none", mec="k", ms=7, label="stable")
    if unstable.any():
        ax.plot(A[unstable], B[unstable], "x", color="k", ms=5, mew=0.8, label="unstable")
    if np.isnan(values).any():
        ax.plot(A[np.isnan(values)], B[np.isnan(values)], "s", color="0.5", ms=3, label="no verified fixed point")
    ax.set_xlabel(LABELS.get(names[0], names[0]))
    ax.set_ylabel(LABELS.get(names[1], names[1]))


def _extent(a, b):
    da = (a[1] - a[0]) / 2 if len(a) > 1 else 0.5
    db = (b[1] - b[0]) / 2 if len(b) > 1 else 0.5
    return (a[0] - da, a[-1] + da, b[0] - db, b[-1] + db)


def random_figure(rows: list[dict], region_rows: list[dict], names, out_dir: Path | None, curve_rows=None, *,
                  problem: str = "") -> Path | None:
    """The random points over the region's stable grid points, and over the traced
    stability boundary when there is one."""
    fig, ax = plt.subplots(figsize=(7.2, 4.8) if curve_rows else (6.4, 4.8))
    if curve_rows:  # the region's map of the largest |multiplier|, the boundary over it
        draw_map(fig, ax, region_rows, list(names), "spectral_radius")
        limits = ax.get_xlim(), ax.get_ylim()
        draw_curves(ax, curve_rows, names[0], names[1])
        ax.set_xlim(*limits[0])
        ax.set_ylim(*limits[1])
    else:
        a, b, _, stable_grid = _grid(region_rows, list(names), "spectral_radius")
        A, B = np.meshgrid(a, b)
        ax.plot(A[stable_grid], B[stable_grid], "s", color="tab:blue", alpha=0.25, ms=12, label="stable grid point")
    stable, unstable, missing = _classes(rows)
    x, y = _column(rows, f"sweep_{names[0]}"), _column(rows, f"sweep_{names[1]}")
    # Over a colour map the stable samples are white with a black edge, to stand out.
    stable_color = "white" if curve_rows else "tab:blue"
    for mask, style, color, word in ((stable, "o", stable_color, "stable sample"), (unstable, "x", "tab:red", "unstable sample"),
                                     (missing, ".", "0.5", "not verified / failed")):
        if mask.any():  # only what is there gets a legend entry
            ax.plot(x[mask], y[mask], style, color=color, mec="k" if style == "o" and curve_rows else color,
                    ms=4 if style == "o" else 5, label=f"{word} ({mask.sum()})")
    ax.set_xlabel(LABELS.get(names[0], names[0]))
    ax.set_ylabel(LABELS.get(names[1], names[1]))
    legend_below(ax)
    path = _in(out_dir, "samples.png")
    return _save(fig, path, problem=problem)


# --- convergence regions --------------------------------------------------------------------


def basin_figures(basin_rows, stable, unstable, example_index, example_unstable, trajectories, grid, out_dir: Path | None,
                  *, problem: str = "") -> list[Path | None]:
    """The convergence region of one stable point and the union of all, over the grid of
    starting states ``grid`` = (ydot values [m/s], z values [m]); and each example run
    (``trajectories``: case -> (outcome, strides, _, apexes)) in the (ydot, z) plane and
    stride by stride."""
    paths = []
    ydots, zs = np.array(grid[0], dtype=float), np.array(grid[1], dtype=float)
    converged_by_point: dict[int, set] = {}
    for r in basin_rows:
        if r["outcome"] == "converged":
            converged_by_point.setdefault(int(r["point"]), set()).add((r["sweep_ydot"], r["sweep_z"]))
    union = set().union(*converged_by_point.values()) if converged_by_point else set()
    panels = [("region.png", converged_by_point.get(example_index, set()), "convergence region of one stable point"),
              ("union.png", union, "union of the convergence regions of all stable points")]
    for name, cells, title in panels:
        fig, ax = plt.subplots(figsize=(6.4, 4.8))
        mask = np.array([[(y, z) in cells for y in ydots] for z in zs])
        # The region is a set of grid cells: drawn as cells, edges included (a contour of
        # the 0/1 mask would cut the corners into odd hexagons).
        ax.imshow(mask, origin="lower", aspect="auto", extent=_extent(ydots, zs), cmap="Blues", vmin=0, vmax=1.6)
        if mask.any():
            from matplotlib.patches import Patch

            ax.add_artist(ax.legend(handles=[Patch(color=plt.get_cmap("Blues")(1 / 1.6),
                                                   label=f"starts that converge ({int(mask.sum())} cells)")],
                                    fontsize=8, loc="lower right"))
        xs = [r["ydot"] for r in stable]
        ax.plot(xs, [r["z"] for r in stable], "o", color="tab:blue", ms=4, label="stable fixed points")
        if name == "region.png" and example_index is not None:
            ax.plot(stable[example_index]["ydot"], stable[example_index]["z"], "o", mfc="none", mec="k", ms=12, label="this stable point")
        if example_unstable is not None:
            ax.plot(example_unstable["ydot"], example_unstable["z"], "x", color="tab:red", ms=10, mew=2, label="unstable example")
        ax.set_xlabel(LABELS["ydot"])
        ax.set_ylabel(LABELS["z"])
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=8, loc="upper right")
        path = _in(out_dir, name)
        paths.append(_save(fig, path, problem=problem))
    for case, (outcome, n, _, apexes) in trajectories.items():
        fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
        z, ydot = apexes[:, 0], apexes[:, 2]
        left.plot(ydot, z, "--.", color="tab:blue")
        left.plot(ydot[0], z[0], "x", color="tab:red", ms=10, mew=2, label="start (unstable fixed point)")
        left.set_xlabel(LABELS["ydot"])
        left.set_ylabel(LABELS["z"])
        left.legend(fontsize=8)
        steps = np.arange(len(z))
        # Speed and height on axes of their own: one unit per axis.
        right.plot(steps, ydot, "-o", ms=3, color="tab:blue")
        right.set_ylabel(LABELS["ydot"], color="tab:blue")
        height = right.twinx()
        height.plot(steps, z, "-s", ms=3, color="tab:orange")
        height.set_ylabel(LABELS["z"], color="tab:orange")
        right.set_xlabel("stride n")
        right.set_title(f"{case.replace('_', ' ')}: {outcome} after {n} strides", fontsize=10)
        path = _in(out_dir, f"{case}.png")
        paths.append(_save(fig, path, problem=problem))
    return paths


# --- continuation ---------------------------------------------------------------------------


#: Colours of the curve types, and how they are named in legends.
CURVE_STYLES = {"fold": ("tab:red", "fold (+1)"), "period_doubling": ("tab:green", "period doubling (-1)"),
                "neimark_sacker": ("tab:purple", "Neimark-Sacker"), "neutral_saddle": ("0.6", "neutral saddle (no bifurcation)")}


def curve_diagram(rows: list[dict], first: str, second: str, path=None, *, problem: str = "", params=None,
                  branch=None):
    """Bifurcation curves in the (first, second) plane: solid where they bound a region
    of stable gaits, dotted where the gaits are unstable on both sides; codimension-two
    points marked and named. In (z, ydot) the speed goes across and the height up, as on
    the sweeps' maps. With ``params`` (:class:`~baslip.model.dynamics.Params`) an energy
    axis also reads as a speed. With ``branch`` (branch.csv rows, the branch the curves
    started from), the band between two bounding curves that holds the branch's stable
    gaits at its level is shaded: stable gaits exist there. ``path`` is a file name or a
    binary file object; without one the Figure is returned."""
    from baslip.viz.labels import CODIM2_NAMES

    if (first, second) == ("z", "ydot"):  # the grid maps' axes: speed across, height up
        first, second = second, first
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    draw_curves(ax, rows, first, second)
    if branch:
        _shade_stable_band(ax, rows, branch, first, second)
    specials = [r for r in rows if r["special"]]
    if specials:
        ax.plot([], [], "o", color="k", mfc="none", label="codimension-two point")
    ax.autoscale_view()  # the limits final, so that the labels are placed on the screen they end on
    drawn = np.column_stack([shown(first, [r[first] for r in rows]), shown(second, [r[second] for r in rows])])
    placed: list = []
    for r in specials:
        x, y = shown(first, [r[first]])[0], shown(second, [r[second]])[0]
        ax.plot(x, y, "o", color="k", mfc="none", ms=9)
        # Inside the frame, clear of the curves and of the other labels, tied to the point.
        where = clear_placement(ax, (x, y), drawn, placed, size=(70.0, 12.0))
        ax.annotate(CODIM2_NAMES[r["special"]], (x, y), textcoords="offset points", fontsize=8,
                    xytext=where.offset, ha=where.ha, va=where.va, arrowprops={"arrowstyle": "-", "lw": 0.6})
    ax.set_xlabel(LABELS.get(first, first))
    ax.set_ylabel(LABELS.get(second, second))
    if params is not None and "energy" in (first, second):
        _speed_axis(ax, params, "y" if second == "energy" else "x")
    if ax.get_legend_handles_labels()[0]:
        legend_below(ax, columns=1)
    saved = _save(fig, path, problem=problem)
    return fig if path is None else saved


def _monotone_in(values, along) -> tuple[np.ndarray, np.ndarray] | None:
    """``values`` as a function of ``along`` (sorted), or None where ``along`` turns back."""
    along, values = np.asarray(along, dtype=float), np.asarray(values, dtype=float)
    order = np.argsort(along)
    if not (np.all(np.diff(along) > 0) or np.all(np.diff(along) < 0)):
        return None
    return along[order], values[order]


def _shade_stable_band(ax, rows: list[dict], branch: list[dict], first: str, second: str) -> None:
    """Shade the band between two curves that bound stable gaits, each a function of the
    vertical quantity, where the branch's own stable gaits lie between them at its level:
    the curves then carry that band, where stable gaits exist, over their common range.
    (Unstable gaits may share the band's points: the plane leaves out the other apex
    quantities, and a branch that folds back passes over itself.)"""
    bounding = [[r for r in rows if r["curve"] == n] for n in sorted({r["curve"] for r in rows})]
    bounding = [c for c in bounding if all(r["stability_boundary"] for r in c)]
    if second not in branch[0] or first not in branch[0]:  # a model parameter: no branch column
        return
    level = shown(second, [branch[0][second]])[0]
    stable_x = shown(first, [r[first] for r in branch if r["stable"] and r["branch"] == branch[0]["branch"]])
    for i, a in enumerate(bounding):
        for b in bounding[i + 1:]:
            curve_a, curve_b = (_monotone_in(shown(first, [r[first] for r in c]), shown(second, [r[second] for r in c]))
                                for c in (a, b))
            if curve_a is None or curve_b is None or not len(stable_x):
                continue
            (ya, xa), (yb, xb) = curve_a, curve_b
            low, high = max(ya[0], yb[0]), min(ya[-1], yb[-1])
            if not low <= level <= high:
                continue
            left, right = sorted((np.interp(level, ya, xa), np.interp(level, yb, xb)))
            stable, slack = np.asarray(stable_x, dtype=float), 1e-6 * (right - left)  # a curve starts at the branch
            if np.any((stable < left - slack) | (stable > right + slack)):
                continue
            y = np.linspace(low, high, 200)
            ax.fill_betweenx(y, np.interp(y, ya, xa), np.interp(y, yb, xb), color="tab:blue", alpha=0.15, lw=0,
                             label="stable gaits exist (the branch's, carried by the curves)")
            return


def _speed_axis(ax, params, which: str) -> None:
    """A second scale on the energy axis: the forward speed [m/s] of an apex one rest leg
    length high, without trunk spin, at that energy (E = m g rho0 + m ydot^2 / 2)."""
    floor = params.m * params.g * params.rho0

    def speed(energy):
        return np.sqrt(np.maximum(2 * (np.asarray(energy, dtype=float) - floor) / params.m, 0.0))

    def energy(v):
        return floor + 0.5 * params.m * np.asarray(v, dtype=float) ** 2

    limits = ax.get_ylim() if which == "y" else ax.get_xlim()
    if not speed(max(limits)) > speed(min(limits)):  # no energy above the floor on the axis
        return
    label = f"speed at a {params.rho0:g} m apex, same energy [m/s]"
    if which == "y":
        ax.secondary_yaxis("right", functions=(speed, energy)).set_ylabel(label)
    else:
        ax.secondary_xaxis("top", functions=(speed, energy)).set_xlabel(label)


def draw_curves(ax, rows: list[dict], first: str, second: str) -> None:
    """The curves of ``rows`` (curve.csv rows) on ``ax``, with legend entries for the
    types and styles present."""
    present = set()
    for number in sorted({r["curve"] for r in rows}):
        curve = [r for r in rows if r["curve"] == number]
        x, y = shown(first, [r[first] for r in curve]), shown(second, [r[second] for r in curve])
        for i in range(len(curve) - 1):
            kind = curve[i]["type"] if curve[i]["type"] == curve[i + 1]["type"] else "neutral_saddle"
            bounding = curve[i]["stability_boundary"] and curve[i + 1]["stability_boundary"]
            style = "-" if bounding else ":"
            ax.plot(x[i : i + 2], y[i : i + 2], style, color=CURVE_STYLES[kind][0], lw=1.8 if bounding else 1.2)
            present.add((kind, bounding))
    for kind, (color, name) in CURVE_STYLES.items():
        for bounding, words in ((True, "bounds stable gaits"), (False, "unstable both sides")):
            if (kind, bounding) in present:
                ax.plot([], [], "-" if bounding else ":", color=color, label=f"{name}, {words}")


# --- stability-optimal gaits ----------------------------------------------------------------


def trunk_motion_figure(motions: list[tuple[str, np.ndarray, np.ndarray]], out_dir: Path | None, *,
                        problem: str = "") -> Path | None:
    """Trunk angle over one stride of each gait: (label, t [s], theta_h [rad]), with the
    band of 'upright throughout' (within 45 deg of vertical) shaded where it falls within
    the traces' range: the range follows the traces (at least 10 deg), not the band."""
    fig, ax = plt.subplots(figsize=(9.6, 4.8))
    angles = [shown("theta_h", theta_h) for _, _, theta_h in motions]
    # The band about the vertical the traces keep to: upright (90 deg) or hanging (-90 deg).
    vertical = 90.0 if not angles or np.mean([a.mean() for a in angles]) >= 0 else -90.0
    ax.axhspan(vertical - 45, vertical + 45, color="0.92", label="within 45 deg of vertical")
    # Ten colours, solid then dashed: twenty traces that can be told apart.
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, ((label, t, _), angle) in enumerate(zip(motions, angles)):
        ax.plot(t, angle, "-" if k < len(colours) else "--", color=colours[k % len(colours)], lw=1.2, label=label)
    if angles:
        low, high = min(a.min() for a in angles), max(a.max() for a in angles)
        margin = max(0.1 * (high - low), 5.0)
        ax.set_ylim(low - margin, high + margin)
    ax.set_xlabel("time from apex t [s]")
    ax.set_ylabel(LABELS["theta_h"])
    ax.set_title("Trunk angle over one stride of the most stable gaits")
    legend_beside(ax, fontsize=7)
    path = _in(out_dir, "best_gaits_trunk.png")
    return _save(fig, path, problem=problem)


# --- a gait's motion ----------------------------------------------------------------------


def gait_figure(motion, title: str):
    """Three panels of a gait's motion (a :class:`baslip.engine.trajectory.Motion`): the CoM and
    hip paths [m], the trunk angle [deg], and the ground reaction force [N], with stance
    shaded. Returns the Figure; writes nothing."""
    fig, (path_ax, angle_ax, force_ax) = plt.subplots(3, 1, figsize=(6.4, 7.2))
    stance = np.isin(motion["phase"], ("compression", "decompression"))
    t = motion["t"]
    path_ax.plot(motion["y"], motion["z"], label="CoM")
    path_ax.plot(motion["hip_y"], motion["hip_z"], "--", label="hip")
    path_ax.set_xlabel("forward position y [m]")
    path_ax.set_ylabel("height z [m]")
    path_ax.set_aspect("equal", adjustable="datalim")
    path_ax.legend(fontsize=8)
    path_ax.set_title(title)
    angle_ax.plot(t, shown("theta_h", motion["theta_h"]))
    angle_ax.set_ylabel(LABELS["theta_h"])
    force_ax.plot(t, motion["grf_z"], label="vertical")
    force_ax.plot(t, motion["grf_y"], label="horizontal")
    force_ax.set_ylabel("ground reaction force [N]")
    force_ax.legend(fontsize=8)
    for ax in (angle_ax, force_ax):
        ax.set_xlabel("time t [s]")
        ax.fill_between(t, 0, 1, where=stance, color="0.9", transform=ax.get_xaxis_transform(), label="_stance")
    fig.tight_layout()
    hand_over(fig)
    return fig
