"""Label placement: a label stays inside the frame and clears what is drawn."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from baslip.viz.placement import clear_placement  # noqa: E402


def _axes():
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 10)
    fig.tight_layout()
    return fig, ax


def test_a_label_at_the_right_edge_goes_left_and_one_at_the_top_goes_down():
    fig, ax = _axes()
    placed: list = []
    right = clear_placement(ax, (9.9, 5.0), np.empty((0, 2)), placed)
    top = clear_placement(ax, (5.0, 9.9), np.empty((0, 2)), placed)
    assert right.offset[0] < 0 and right.ha == "right"
    assert top.offset[1] < 0 and top.va == "top"
    frame = ax.get_window_extent()
    for x0, y0, x1, y1 in placed:
        assert frame.x0 <= x0 and x1 <= frame.x1 and frame.y0 <= y0 and y1 <= frame.y1
    plt.close(fig)


def test_a_label_on_a_rising_line_sits_off_the_line_and_off_the_other_label():
    fig, ax = _axes()
    line = np.column_stack([np.linspace(0, 10, 200), np.linspace(0, 10, 200)])
    placed: list = []
    first = clear_placement(ax, (5.0, 5.0), line, placed)
    # On y = x, the free quarters are above-left and below-right.
    assert np.sign(first.offset[0]) == -np.sign(first.offset[1])
    second = clear_placement(ax, (5.0, 5.0), line, placed)
    assert second.offset != first.offset  # not on top of the first label
    plt.close(fig)


def test_labels_of_two_nearby_points_do_not_overlap():
    """Two points near each other beside a falling line, each labelled: the boxes stay
    apart. Their distance is taken box to box; from a few points of the first box only
    (its corners and centre), the second label was placed across the first one's edge."""
    fig, ax = _axes()
    line = np.column_stack([np.linspace(0, 10, 50), np.linspace(10.568, 4.802, 50)])
    placed: list = []
    for point in ((6.307, 6.542), (6.564, 6.237)):
        clear_placement(ax, point, line, placed)
    (a0, b0, a1, b1), (c0, d0, c1, d1) = placed
    assert min(a1, c1) - max(a0, c0) <= 0 or min(b1, d1) - max(b0, d0) <= 0
    plt.close(fig)
