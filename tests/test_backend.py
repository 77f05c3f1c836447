"""The matplotlib backend: off-screen outside notebooks, a notebook's own kept; a returned
figure is left to pyplot only in a notebook."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from baslip.viz import backend  # noqa: E402


def test_a_notebook_is_recognised_by_its_backend(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    assert backend.in_notebook()
    monkeypatch.setenv("MPLBACKEND", "TkAgg")
    assert not backend.in_notebook()
    monkeypatch.delenv("MPLBACKEND")
    assert not backend.in_notebook()


def test_a_figure_handed_over_outside_a_notebook_is_forgotten_by_pyplot_but_still_draws(monkeypatch, tmp_path):
    monkeypatch.delenv("MPLBACKEND", raising=False)
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    backend.hand_over(fig)
    assert fig.number not in plt.get_fignums()
    fig.savefig(tmp_path / "still.png")
    assert (tmp_path / "still.png").stat().st_size > 0


def test_in_a_notebook_pyplot_keeps_the_figure_to_show_it_at_the_end_of_the_cell(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    fig, _ = plt.subplots()
    backend.hand_over(fig)
    assert fig.number in plt.get_fignums()
    backend.release(fig)
    assert fig.number not in plt.get_fignums()
