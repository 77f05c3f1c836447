"""The branch diagram, drawn from committed branch files: special points marked hollow
(a branch born there stays visible) and labelled inside the frame, clear of the
branches; a branch too small to see zoomed in an inset. And the curve diagram's stable
band, shaded between the curves that carry the branch's stable gaits."""

import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.text import Annotation, Text  # noqa: E402

from baslip.results import open_results  # noqa: E402
from baslip.viz.branchplot import bifurcation_diagram  # noqa: E402
from baslip.viz.figures import curve_diagram  # noqa: E402

RESULTS = pathlib.Path(__file__).resolve().parents[1] / "results"


def _diagram(name: str):
    run = open_results(RESULTS / name)
    return run, bifurcation_diagram(run.rows("branch"), run.record["parameter"], "z", problem=name)


def test_special_points_are_hollow_and_their_labels_stay_in_the_frame_off_the_branch():
    run, fig = _diagram("continuation_slip_attack")
    ax = fig.axes[0]
    fig.canvas.draw()
    labels = [c for c in ax.get_children() if isinstance(c, Annotation)]
    assert len(labels) == sum(1 for r in run.rows("branch") if r["special"]) == 2
    frame = ax.get_window_extent()
    branch = ax.transData.transform(np.column_stack(
        [np.degrees([r["theta_td"] for r in run.rows("branch")]), [r["z"] for r in run.rows("branch")]]))
    for label in labels:
        box = Text.get_window_extent(label)  # the words alone, without the line to the point
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1
        inside = (branch[:, 0] > box.x0) & (branch[:, 0] < box.x1) & (branch[:, 1] > box.y0) & (branch[:, 1] < box.y1)
        assert not inside.any(), label.get_text()
    markers = [line for line in ax.get_lines() if line.get_marker() in ("s", "D")]
    assert markers and all(line.get_markerfacecolor() == "none" for line in markers)
    plt.close(fig)


def test_a_branch_too_small_to_see_is_zoomed_in_an_inset_and_a_visible_one_is_not():
    _, fig = _diagram("continuation_slip_attack")  # its 2-stride branch spans 0.1 deg by 11 mm
    [inset] = fig.axes[0].child_axes
    low, high = inset.get_xlim()
    assert high - low < 0.2  # degrees: the small branch, not the whole diagram
    plt.close(fig)
    _, fig = _diagram("continuation_downward_speed")
    assert fig.axes[0].child_axes == []
    plt.close(fig)


def test_an_unstable_stretch_is_one_dashed_line_whose_dashes_show():
    """Each run of stable or unstable points is one line (dashes drawn per two-point piece
    would be shorter than a dash, and read as solid): on the VPP fold curve's branch,
    unstable throughout, one dashed line carries every point."""
    run, fig = _diagram("curve_vpp_fold")
    rows = run.rows("branch")
    assert not any(r["stable"] for r in rows)
    drawn = [line for line in fig.axes[0].get_lines() if len(line.get_xdata()) > 1]
    assert [line.get_linestyle() for line in drawn] == ["--"] * len({r["branch"] for r in rows})
    assert sum(len(line.get_xdata()) for line in drawn) == len(rows)
    plt.close(fig)


def _band(fig):
    return [c for c in fig.axes[0].collections if isinstance(c, PolyCollection) and "stable gaits" in str(c.get_label())]


def test_the_slip_band_is_shaded_between_its_two_curves_where_the_branch_is_stable():
    run = open_results(RESULTS / "curve_slip_band")
    fig = curve_diagram(run.rows("curve"), "theta_td", "energy", branch=run.rows("branch"))
    [band] = _band(fig)
    x = band.get_paths()[0].vertices[:, 0]
    stable = np.degrees([r["theta_td"] for r in run.rows("branch") if r["stable"]])
    assert x.min() <= stable.min() + 1e-6 and stable.max() - 1e-6 <= x.max()
    plt.close(fig)
    unshaded = curve_diagram(run.rows("curve"), "theta_td", "energy")  # without the branch: nothing to carry
    assert _band(unshaded) == []
    plt.close(unshaded)
