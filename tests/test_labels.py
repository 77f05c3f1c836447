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
    assert "pivot feedback (r_vpp only); 4,000 starts a box" in legend and not any(t.startswith("pivot;") for t in legend)
    assert "receding-horizon re-solve; 4,000 starts a box" in legend
    assert "one-stride re-solve; 4,000 starts a box" in legend


def test_a_controller_that_runs_fewer_starts_says_so_in_the_basin_legend():
    import matplotlib.pyplot as plt

    from baslip.viz.controllersplot import basin_figure

    def basin(samples: int) -> dict:
        return {"per_box": [{"box": box, "returned_fraction": 0.5, "ci95": [0.4, 0.6], "samples": samples}
                            for box in (1.0, 2.0)]}

    before = set(plt.get_fignums())
    basin_figure({"constant": basin(4000), "resolve": basin(1000)}, "a comparison", None)
    (figure,) = [plt.figure(n) for n in plt.get_fignums() if n not in before]  # left open, labelled
    assert figure.get_label() == "basins"
    legend = [text.get_text() for text in figure.axes[0].get_legend().get_texts()]
    plt.close(figure)
    assert legend == ["constant control; 4,000 starts a box", "one-stride re-solve; 1,000 starts a box"]


def test_every_figure_of_a_run_is_titled_with_its_problem_law_and_body():
    from baslip.model.hiplaw import HIP_LAWS
    from baslip.studies.sources import recorded_law
    from baslip.viz.labels import LAW_NAMES

    assert set(LAW_NAMES) == set(HIP_LAWS)
    thesis, human = ("m = 1 kg, I = 0.0033 kg m^2, k = 1000 N/m, rho0 = 0.2 m, d = 0.04 m",
                     "m = 80 kg, I = 4.58 kg m^2, k = 20000 N/m, rho0 = 1 m, d = 0.1 m")
    for name, body in (("grid_downward", thesis), ("controllers_vpp_human", human), ("atlas_vpp", thesis)):
        run = open_results(ROOT / "results" / name)
        law = LAW_NAMES[recorded_law(run.record)]  # pd where a run predates the recorded law
        figures = run.plot()
        assert len(figures) >= 1
        for figure in figures.values():  # the atlas adds a line on what it shows
            assert figure.get_suptitle().startswith(f"{name}\n{law}; {body}")
