"""Specification of baslip.viz.figures: a sweep's map paints cells only where it has them.

With one value along a swept axis there is no cell width to paint: the map shows each
point as a marker at its own value, and says so, instead of inventing an extent.
"""

import matplotlib.pyplot as plt
import pytest
from matplotlib.image import AxesImage

from baslip.status import Status
from baslip.viz.figures import draw_map


def rows(ydots, zs):
    return [{"sweep_ydot": ydot, "sweep_z": z, "status": Status.CONVERGED, "spectral_radius": 0.5 + ydot / 10,
             "theta_td": 0.1, "stable": True} for ydot in ydots for z in zs]


@pytest.mark.parametrize("quantity", ["spectral_radius", "theta_td"])
@pytest.mark.parametrize(("ydots", "zs"), [([3.0], [1.06]), ([2.5, 3.0, 3.5], [1.06]), ([3.0], [1.0, 1.1])])
def test_a_single_value_along_an_axis_is_drawn_as_points_not_cells(ydots, zs, quantity):
    fig, ax = plt.subplots()
    draw_map(fig, ax, rows(ydots, zs), ["ydot", "z"], quantity)
    assert not [child for child in ax.get_children() if isinstance(child, AxesImage)]
    assert "points, not cells" in ax.get_title()
    if len(ydots) == 1:
        assert list(ax.get_xticks()) == ydots
    if len(zs) == 1:
        assert list(ax.get_yticks()) == zs
    plt.close(fig)


def test_a_grid_is_painted_over_its_cells():
    fig, ax = plt.subplots()
    draw_map(fig, ax, rows([2.5, 3.0, 3.5], [1.0, 1.1]), ["ydot", "z"], "spectral_radius")
    images = [child for child in ax.get_children() if isinstance(child, AxesImage)]
    assert len(images) == 1 and images[0].get_extent() == pytest.approx([2.25, 3.75, 0.95, 1.15])
    plt.close(fig)
