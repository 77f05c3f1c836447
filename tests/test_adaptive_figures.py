"""Specification of baslip.viz.adaptive: an adaptive run's figures say how its adaptive phase
ended, a fall or the control frozen, at the stride where it did."""

import pytest
from runs import ROOT

from baslip import open_results


@pytest.mark.parametrize("name, words", [("adaptive_upright", "fall after stride 779"),
                                         ("adaptive_upright_tracking", "control frozen after stride 2047")])
def test_the_end_of_the_adaptive_phase_is_marked_on_every_stride_panel(name, words):
    run = open_results(ROOT / "results" / name)
    figures = run.plot()
    last = max(r["n"] for r in run.rows("strides") if r["phase"] == "adaptive")
    assert words.endswith(f"stride {last:.0f}")
    panels = figures["adaptive_states"].axes[1:3] + [ax for ax in figures["adaptive_controls"].axes if ax.get_visible()]
    for ax in panels:
        assert [text.get_text() for text in ax.get_legend().get_texts()] == [words]
