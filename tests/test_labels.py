"""Specification of baslip.viz.labels: every key a reader may meet has its words, and the
controller panels show those words, not the code names."""

from runs import ROOT

from baslip import open_results
from baslip.analysis.bifurcation import CODIM2_TESTS
from baslip.problem.study import CONTROLLER_KINDS
from baslip.viz.labels import CODIM2_NAMES, CONTROLLER_NAMES


def test_every_controller_and_codimension_two_point_has_its_words():
    assert set(CONTROLLER_NAMES) == set(CONTROLLER_KINDS)
    assert {kind for kinds in CODIM2_TESTS.values() for kind in kinds} <= set(CODIM2_NAMES)


def test_the_controller_panels_are_titled_in_words():
    figures = open_results(ROOT / "results" / "controllers_vpp").plot()
    titles = [ax.get_title() for ax in figures["controllers"].axes[1:]]
    assert titles and all(title in CONTROLLER_NAMES.values() for title in titles)
    legend = [text.get_text() for text in figures["basins"].axes[0].get_legend().get_texts()]
    assert "pivot feedback (r_vpp only)" in legend and "pivot" not in legend
