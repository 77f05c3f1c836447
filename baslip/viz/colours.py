"""Colour scales of the figures: spectral radii on either side of 1, and angles.

Drawing only, shared by :mod:`baslip.viz.figures` and :mod:`baslip.viz.atlasmap`.
"""

from __future__ import annotations

import math

from baslip.viz.backend import use_file_backend

use_file_backend()
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import Colormap, ListedColormap, LogNorm  # noqa: E402

from baslip.model.quantities import UNITS  # noqa: E402

#: Spectral radii labelled on colour bars, where they fall within the bar's range.
RADIUS_TICKS = (0.001, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0, 1.1, 1.5, 2.0, 3.0, 10.0, 100.0, 1000.0)


def radius_colours(radii) -> tuple[Colormap, LogNorm]:
    """(colour map, norm) for spectral radii: blues below 1, darker the more stable, and
    reds above, meeting at 1 without passing through white, so that a radius of 0.97 is
    plainly on the stable side. Log scale, symmetric about 1, at least 0.5 to 2."""
    radii = np.asarray(radii, dtype=float)
    finite = radii[np.isfinite(radii) & (radii > 0)]
    span = max(float(np.abs(np.log10(finite)).max()), math.log10(2.0)) if finite.size else 1.0
    below = plt.get_cmap("Blues")(np.linspace(0.95, 0.4, 128))
    above = plt.get_cmap("Reds")(np.linspace(0.4, 0.95, 128))
    colours = ListedColormap(np.vstack([below, above])).with_extremes(bad="0.85")
    return colours, LogNorm(vmin=10**-span, vmax=10**span)


def radius_colorbar(fig, image, ax, label: str):
    """A colour bar for spectral radii, ticked at round radii (1 among them)."""
    bar = fig.colorbar(image, ax=ax, label=label)
    ticks = spaced_radius_ticks(image.norm.vmin, image.norm.vmax)
    bar.set_ticks(ticks)
    bar.set_ticklabels([f"{t:g}" for t in ticks])
    bar.minorticks_off()
    return bar


#: Least gap between two ticks of a radius colour bar, as a share of its log range: about
#: a label's height on a bar of the figures' size.
TICK_GAP_SHARE = 0.06


def spaced_radius_ticks(lo: float, hi: float) -> list[float]:
    """The ticks of :data:`RADIUS_TICKS` within [``lo``, ``hi``] that a bar can label
    without their text running together: 1, then outwards from it each tick at least
    :data:`TICK_GAP_SHARE` of the bar's log range from the last one kept."""
    gap = TICK_GAP_SHARE * math.log10(hi / lo)
    kept = [1.0] if lo <= 1.0 <= hi else []
    for side in (sorted(t for t in RADIUS_TICKS if 1.0 < t <= hi), sorted((t for t in RADIUS_TICKS if lo <= t < 1.0), reverse=True)):
        last = 0.0
        for tick in side:
            if abs(math.log10(tick)) - last >= gap:
                kept.append(tick)
                last = abs(math.log10(tick))
    return sorted(kept)


#: Least span of an angle's colour bar [deg]: a map whose angles differ by a quarter of a
#: degree should not look as varied as one that spans a right angle.
MIN_ANGLE_SPAN_DEG = 10.0


def colour_limits(quantity: str, values: np.ndarray) -> dict:
    """vmin and vmax of a map of ``values`` (as shown): an angle's span is at least
    :data:`MIN_ANGLE_SPAN_DEG`, centred on its values; others take their own range."""
    finite = values[np.isfinite(values)]
    if not finite.size or UNITS.get(quantity) != "rad" or np.ptp(finite) >= MIN_ANGLE_SPAN_DEG:
        return {}
    middle = (finite.min() + finite.max()) / 2
    return {"vmin": middle - MIN_ANGLE_SPAN_DEG / 2, "vmax": middle + MIN_ANGLE_SPAN_DEG / 2}
