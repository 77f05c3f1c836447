"""Specification of baslip.results: runs read back from their folders, for notebooks; their
figures come back by the names of the files the run wrote, and show themselves."""

import math
import os
import re
import shutil
from pathlib import Path

import pytest
from runs import ROOT

from baslip import open_results
from baslip.errors import InputError

RESULTS = ROOT / "results"


@pytest.fixture(autouse=True)
def close_figures():
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


def test_a_sweep_reads_back_with_a_short_repr_a_table_and_figures():
    grid = open_results(RESULTS / "grid_downward")
    assert grid.kind == "sweep" and "points" in grid.tables
    assert repr(grid).startswith("<RunResults grid_downward: sweep, points 90") and len(repr(grid)) < 200
    assert "<table>" in grid._repr_html_()
    frame = grid.to_dataframe()
    assert len(frame) == 90 and str(frame["stable"].dtype) == "boolean"
    assert int(frame["stable"].sum()) == grid.record["stable"]
    figures = grid.plot()
    assert list(figures) == ["theta_h_map", "spectral_radius_map"]  # the names of the files the run wrote
    assert all((RESULTS / "grid_downward" / f"{name}.png").exists() for name in figures)
    assert "multiplier" in figures["spectral_radius_map"].axes[1].get_ylabel()
    page = figures._repr_html_()  # a notebook shows each, named, with no display() call
    assert page.count('<img src="data:image/png;base64,') == 2 and "<h4>theta_h_map</h4>" in page


def test_dataframe_columns_have_their_types_and_rows_their_swept_order():
    """Text stays text where every row is empty, and a study's rows come sorted by their
    swept values (points.csv holds them in the order the lanes finished)."""
    grid = open_results(RESULTS / "grid_downward").to_dataframe()
    assert str(grid["reason"].dtype) == "string" and (grid.loc[grid["status"] == "converged", "reason"] == "").all()
    keys = list(zip(grid["sweep_ydot"], grid["sweep_z"]))
    assert keys == sorted(keys) and len(set(keys)) == len(keys)
    branch = open_results(RESULTS / "continuation_downward_height").to_dataframe()
    assert str(branch["special"].dtype) == "string" and (branch["special"] == "").sum() > 0
    assert not branch["special"].isna().any()
    optimal = open_results(RESULTS / "optimal_vpp").to_dataframe()
    order = list(zip(optimal["sweep_ydot"], optimal["sweep_z"], optimal["start"]))
    assert order == sorted(order) and str(optimal["start"].dtype) == "int64"


def test_failed_rows_keep_a_boolean_stable_column_and_say_why():
    scan = open_results(RESULTS / "body_angle_scan").to_dataframe()
    assert str(scan["stable"].dtype) == "boolean"
    failed = scan[scan["status"] != "converged"]
    assert len(failed) > 0 and failed["stable"].isna().all() and failed["reason"].notna().all()


def test_a_continuation_with_curves_reads_back():
    band = open_results(RESULTS / "curve_slip_band")
    assert band.kind == "continuation" and {"branch", "curve"} <= set(band.tables)
    curve = band.to_dataframe("curve")
    assert {"theta_td", "energy", "special", "stability_boundary"} <= set(curve.columns)
    assert str(curve["stability_boundary"].dtype) == "boolean"
    figures = band.plot()
    assert list(figures) == ["diagram", "curve"] and figures["curve"].axes[0].get_ylabel() == "apex energy [J]"
    with pytest.raises(KeyError, match="no nothing.csv"):
        band.to_dataframe("nothing")


def test_summaries_show_angles_in_degrees_and_other_values_with_their_units():
    band = open_results(RESULTS / "curve_slip_band")
    for point in band.record["special_points"]:  # stored in radians, shown in degrees
        assert f"{point['type']} at theta_td = {math.degrees(point['theta_td']):.4f} deg" in band.summary()
    # The fold-flip, where the period-doubling and the fold curves of the human-scale VPP gait
    # meet, located on each curve (each deflated its own way), in metres and m/s: the two
    # agree to the regula falsi's 1e-5 in arclength.
    where = [re.search(r"fold-flip at r_vpp = (\S+) m, ydot = (\S+) m/s", open_results(RESULTS / name).summary())
             for name in ("curve_vpp_pivot", "curve_vpp_fold")]
    assert all(where)
    assert abs(float(where[0][1]) - float(where[1][1])) < 1e-5 and abs(float(where[0][2]) - float(where[1][2])) < 1e-5


def test_a_folder_without_results_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="run the problem first"):
        open_results(tmp_path)


@pytest.mark.parametrize("name, count", [("stable_region_traced", 1), ("adaptive_upright", 2), ("controllers_downward", 2),
                                         ("convergence_regions", 4), ("optimal_downward", 3), ("speed_sweep", 4)])
def test_other_studies_draw_their_figures_without_writing(name, count):
    folder = RESULTS / name
    before = {p: p.stat().st_mtime_ns for p in folder.iterdir()}
    figures = open_results(folder).plot()
    assert len(figures) == count
    assert all(any(ax.get_xlabel() or ax.get_ylabel() for ax in fig.axes) for fig in figures.values())
    assert all((folder / f"{name}.png").exists() for name in figures)  # named as the run's files
    assert all(fig.get_suptitle().split("\n")[0] == name for fig in figures.values())  # a figure names its problem
    assert {p: p.stat().st_mtime_ns for p in folder.iterdir()} == before


def test_a_sweep_draws_no_figure_of_a_quantity_that_does_not_vary():
    """A scan of theta_h with z held draws no theta_h or z line (the swept angle against
    itself, a constant), and a VPP sweep no theta_h map (its gaits all share 90 deg);
    the spectral radius and the residual are always drawn."""
    scan = open_results(RESULTS / "body_angle_scan").plot()
    assert set(scan) == {"spectral_radius", "residual"}
    vpp = open_results(RESULTS / "vpp_sweep_thesis")
    angles = [r["theta_h"] for r in vpp.rows() if r["status"] == "converged"]
    assert max(angles) - min(angles) < 1e-8  # the symmetric family: theta_h = 90 deg to round-off
    assert set(vpp.plot()) == {"spectral_radius_map"}
    assert "theta_h_map" in open_results(RESULTS / "grid_upward").plot()  # theta_h varies there


def test_convergence_regions_redrawn_from_files_hold_the_counted_cells():
    """The regions read back are those the run counted: one stable point's and the union."""
    basin = open_results(RESULTS / "convergence_regions")
    figures = basin.plot()
    region, union = figures["region"], figures["union"]
    labels = [text.get_text() for fig in (region, union) for legend in fig.axes[0].artists + [fig.axes[0].get_legend()]
              for text in legend.get_texts() if "cells" in text.get_text()]
    assert labels == [f"starts that converge ({basin.record['example_region_states']} cells)",
                      f"starts that converge ({basin.record['union_region_states']} cells)"]


def test_optimal_gaits_redrawn_show_the_least_radius_per_cell():
    optimal = open_results(RESULTS / "optimal_downward")
    frame = optimal.to_dataframe()
    least = frame[frame["status"] == "converged"]["spectral_radius"].min()
    trunk = optimal.plot()["best_gaits_trunk"]
    assert f"radius {least:.3g}" in trunk.axes[0].get_legend().get_texts()[1].get_text()


def test_the_trunk_figure_spans_the_traces_not_the_upright_band():
    """The VPP gaits swing 2 deg about vertical: the axis must show that swing, not the
    45-135 deg band (in which they were flat lines)."""
    trunk = open_results(RESULTS / "optimal_vpp").plot()["best_gaits_trunk"]
    low, high = trunk.axes[0].get_ylim()
    lines = [line.get_ydata() for line in trunk.axes[0].get_lines()]
    assert 80 < low < min(min(y) for y in lines) and max(max(y) for y in lines) < high < 100


def test_figures_save_under_their_names_as_a_run_writes_them(tmp_path):
    from PIL import Image

    figures = open_results(RESULTS / "grid_downward").plot()
    paths = figures.save(tmp_path / "maps")
    assert [p.name for p in paths] == ["theta_h_map.png", "spectral_radius_map.png"]
    width, height = figures["theta_h_map"].get_size_inches() * 110  # the runs' PNG resolution
    assert Image.open(paths[0]).size == (round(width), round(height))
    with pytest.raises(KeyError, match="the figures are theta_h_map, spectral_radius_map"):
        figures["nothing"]


def test_the_traced_boundary_has_the_grid_maps_axes():
    """curve_downward_boundary is traced in (z, ydot); it is drawn as grid_downward's maps
    are, speed across and height up, so that the two can be laid over each other."""
    curve = open_results(RESULTS / "curve_downward_boundary").plot()["curve"].axes[0]
    grid = open_results(RESULTS / "grid_downward").plot()["spectral_radius_map"].axes[0]
    assert (curve.get_xlabel(), curve.get_ylabel()) == (grid.get_xlabel(), grid.get_ylabel())


def test_an_energy_axis_also_reads_as_the_speed_at_a_leg_length_high_apex():
    """curve_slip_band's energies 1424.8 to 2224.8 J are 4 to 6 m/s at a 1 m apex (80 kg)."""
    ax = open_results(RESULTS / "curve_slip_band").plot()["curve"].axes[0]
    (speed,) = ax.child_axes
    low, high = ax.get_ylim()
    assert "speed at a 1 m apex" in speed.get_ylabel()
    assert speed.get_ylim() == pytest.approx(tuple(math.sqrt(2 * (e - 80 * 9.81) / 80) for e in (low, high)))


def damaged_copy(tmp_path, name: str, table: str, change) -> Path:
    """A copy of results/``name`` whose ``table`` has had ``change`` (lines -> lines) done to it."""
    folder = tmp_path / name
    shutil.copytree(RESULTS / name, folder)
    lines = (folder / table).read_text().splitlines(keepends=True)
    (folder / table).write_text("".join(change(lines)))
    return folder


def junk_row(lines):
    return [*lines[:5], "junk\n", *lines[5:]]


def nan_state(lines):
    cells = lines[3].split(",")
    cells[lines[0].split(",").index("z")] = "nan"
    return [*lines[:3], ",".join(cells), *lines[4:]]


def torn_last_row(lines):
    return [*lines[:-1], lines[-1][: len(lines[-1]) // 2]]


@pytest.mark.parametrize("change, words", [(junk_row, "line 6: it has 1 cells"), (nan_state, "line 4: its z is 'nan'"),
                                           (torn_last_row, "line 91: it has")])
def test_a_damaged_table_is_refused_naming_its_file_and_line(tmp_path, change, words):
    """Issue 57: a junk row in points.csv gave a bare ValueError from rows() and to_dataframe()
    read it as data; a row's z set to NaN by hand was read as a gait."""
    folder = damaged_copy(tmp_path, "grid_downward", "points.csv", change)
    results = open_results(folder)
    for read in (results.rows, results.to_dataframe):
        with pytest.raises(InputError) as err:
            read()
        assert str(err.value).startswith(f"{folder / 'points.csv'}: {words}") and "\n" not in str(err.value)


def test_a_table_without_its_header_is_refused_when_the_folder_is_opened(tmp_path):
    """Issue 57: a branch.csv without its header gave KeyError."""
    folder = damaged_copy(tmp_path, "continuation_downward_height", "branch.csv", lambda lines: lines[1:])
    with pytest.raises(InputError, match=re.escape(f"{folder / 'branch.csv'}: its first line is no header")):
        open_results(folder)


def test_a_table_that_is_a_fifo_is_refused_unread(tmp_path):
    folder = tmp_path / "grid_downward"
    shutil.copytree(RESULTS / "grid_downward", folder)
    (folder / "points.csv").unlink()
    os.mkfifo(folder / "points.csv")
    with pytest.raises(InputError, match="points.csv: it is a FIFO, not a file"):
        open_results(folder)
