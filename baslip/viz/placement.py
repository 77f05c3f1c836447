"""Where to put a label so that it clears what is drawn, and stays inside the frame.

A label of a marked point (a special point of a branch, say) is tried at a few offsets
around its point; the one kept lies inside the axes and farthest from the drawn points
and from the boxes of the labels already placed (box to box: two labels whose boxes
overlap are as close as can be). Distances are taken on the screen, in pixels, so
that axes of very different scales (degrees against metres) weigh alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Offsets [pt] of a label from its point, tried in this order (ties keep the first): a
#: near ring, then a far one for a point whose near ring is crowded (by the branches, the
#: frame or a neighbour's label).
OFFSETS = ((14, 12), (14, -12), (-14, 12), (-14, -12), (0, 22), (0, -22), (26, 0), (-26, 0),
           (14, 36), (14, -36), (-14, 36), (-14, -36), (0, 48), (0, -48))


@dataclass(frozen=True)
class Placement:
    """A label's offset from its point [pt] and its alignment, for ``Axes.annotate``."""

    offset: tuple[float, float]
    ha: str
    va: str


def _box(anchor, offset, size, scale):
    """The label's box in pixels, (x0, y0, x1, y1), for an offset and a size in points."""
    (dx, dy), (width, height) = offset, size
    x = anchor[0] + dx * scale
    y = anchor[1] + dy * scale
    x0 = x if dx > 0 else (x - width * scale if dx < 0 else x - width * scale / 2)
    y0 = y if dy > 0 else (y - height * scale if dy < 0 else y - height * scale / 2)
    return x0, y0, x0 + width * scale, y0 + height * scale


def _clearance(box, points: np.ndarray) -> float:
    """The least distance [px] from the box to any of ``points`` (0 for one inside it)."""
    if len(points) == 0:
        return np.inf
    x0, y0, x1, y1 = box
    dx = np.maximum(np.maximum(x0 - points[:, 0], points[:, 0] - x1), 0.0)
    dy = np.maximum(np.maximum(y0 - points[:, 1], points[:, 1] - y1), 0.0)
    return float(np.min(np.hypot(dx, dy)))


def _gap(a, b) -> float:
    """The distance [px] between two boxes (x0, y0, x1, y1); 0 where they overlap."""
    dx = max(a[0] - b[2], b[0] - a[2], 0.0)
    dy = max(a[1] - b[3], b[1] - a[3], 0.0)
    return float(np.hypot(dx, dy))


def clear_placement(ax, xy, drawn, placed: list, size=(120.0, 24.0)) -> Placement:
    """The offset of the label of the point ``xy`` that keeps it inside ``ax`` and
    farthest from ``drawn`` and from the boxes in ``placed``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The axes, with their limits final.
    xy : tuple of float
        The labelled point, in data coordinates.
    drawn : array_like
        Points drawn on the axes (n x 2, data coordinates) that the label should clear.
    placed : list
        Boxes (pixels) of the labels already placed; the chosen box is appended.
    size : tuple of float
        The label's width and height [pt], about.

    Returns
    -------
    Placement
        The offset [pt] and alignment to pass to ``Axes.annotate``.
    """
    to_pixels = ax.transData.transform
    anchor = to_pixels(np.asarray(xy, dtype=float).reshape(1, 2))[0]
    drawn = np.asarray(drawn, dtype=float).reshape(-1, 2)
    points = to_pixels(drawn[np.all(np.isfinite(drawn), axis=1)]) if len(drawn) else np.empty((0, 2))
    frame = ax.get_window_extent()
    scale = ax.figure.dpi / 72.0
    best, best_score = OFFSETS[0], -np.inf
    for offset in OFFSETS:
        box = _box(anchor, offset, size, scale)
        inside = box[0] >= frame.x0 and box[1] >= frame.y0 and box[2] <= frame.x1 and box[3] <= frame.y1
        # Any box inside the frame beats every box outside it (clearances are capped well
        # below the penalty: with nothing drawn every clearance is infinite).
        clearance = min([_clearance(box, points), *(_gap(box, other) for other in placed)])
        score = min(clearance, 1e5) - (0.0 if inside else 1e6)
        if score > best_score:
            best, best_score = offset, score
    placed.append(_box(anchor, best, size, scale))
    dx, dy = best
    return Placement(best, "left" if dx > 0 else ("right" if dx < 0 else "center"),
                     "bottom" if dy > 0 else ("top" if dy < 0 else "center"))
