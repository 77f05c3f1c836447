"""Specification of the ``baslip`` command (baslip.cli.main) and of the notebook-facing parts of
a result."""

import errno
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from runs import ROOT

from baslip import __version__, load_problem, solve_problem
from baslip.cli.main import main
from baslip.problem.shipped import shipped_problems


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "baslip", *args], capture_output=True, text=True, cwd=cwd, timeout=600)


def test_python_m_baslip_is_the_command_and_knows_its_version():
    done = run("--version")
    assert done.returncode == 0 and done.stdout.strip() == f"baslip {__version__}"
    assert __version__ not in ("", "unknown")


def test_help_covers_every_command_and_solve_help_covers_studies_and_continuation(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--help"])
    assert stop.value.code == 0
    text = capsys.readouterr().out
    for command in ("solve", "trajectory", "animate", "report", "problems"):
        assert command in text
    with pytest.raises(SystemExit):
        main(["solve", "--help"])
    text = capsys.readouterr().out
    for word in ("study:", "continuation:", "curve", "--jobs", "--verbose", "Exit status"):
        assert word in text


@pytest.mark.parametrize("command", ["solve", "trajectory", "animate", "report", "problems"])
def test_each_command_help_is_plain_text_with_a_line_for_every_option(command, capsys):
    """Issue 56: report and animate printed their docstrings' markup, and --results had no help."""
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = capsys.readouterr().out
    assert "``" not in text and ":mod:" not in text
    lines = text[text.index("options:"):].splitlines()[1:]
    for number, line in enumerate(lines):
        invocation = re.fullmatch(r"  (-[^ ]+(?:, -[^ ]+)*(?: [A-Z]+)?)(\s{2,}\S.*)?", line)
        if invocation and invocation.group(2) is None:  # help, if any, is on the next line
            following = lines[number + 1] if number + 1 < len(lines) else ""
            assert re.match(r" {6,}\S", following), f"{command} {invocation.group(1)} has no help line"


def test_an_unknown_command_is_one_line_and_exit_2():
    done = run("solev", "problems/downward.yaml", cwd=ROOT)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("error: ") and "solev" in done.stderr


def test_problems_are_listed_and_copied_without_overwriting(tmp_path, capsys):
    assert main(["problems"]) == 0
    listing = capsys.readouterr().out
    assert all(path.stem in listing for path in shipped_problems())
    assert len(shipped_problems()) >= 20
    (tmp_path / "downward.yaml").write_text("# mine\n")
    assert main(["problems", "--copy", str(tmp_path)]) == 0
    assert (tmp_path / "downward.yaml").read_text() == "# mine\n"
    assert sorted(p.name for p in tmp_path.glob("*.yaml")) == sorted(p.name for p in shipped_problems())
    assert (tmp_path / "models" / "hopper.py").is_file()  # the model a shipped problem names comes along


def test_problem_descriptions_are_cut_at_a_word_with_an_ellipsis(capsys):
    """Issue 56: ``baslip problems`` cut descriptions mid-word, with no sign of the cut."""
    from baslip.problem.shipped import describe

    assert main(["problems"]) == 0
    lines = capsys.readouterr().out.splitlines()[1:]
    width = max(len(path.stem) for path in shipped_problems())  # the longest name sets the column
    cut = 0
    for path, line in zip(shipped_problems(), lines):
        assert line[2:2 + width + 1].rstrip() == path.stem
        full, shown = " ".join(describe(path).split()), line[2 + width + 1:]
        if shown != full:
            cut += 1
            assert shown.endswith(" …") and full.startswith(shown[:-2]), line
            assert full[len(shown) - 2] == " ", line  # the cut falls between words
    assert cut > 0  # some shipped descriptions are longer than a line


def test_solve_through_the_command_with_one_job(tmp_path):
    done = run("solve", "problems/downward.yaml", "--out", str(tmp_path / "out"), "--jobs", "1", cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "converged" in done.stdout and (tmp_path / "out" / "result.json").exists()
    bad = run("solve", "problems/downward.yaml", "--jobs", "0", cwd=ROOT)
    assert bad.returncode == 2 and "--jobs" in bad.stderr and bad.stderr.count("\n") == 1


def test_trajectory_writes_a_csv_and_refuses_a_study(tmp_path):
    out = tmp_path / "motion.csv"
    done = run("trajectory", "problems/downward.yaml", "--strides", "1", "--samples", "10", "--out", str(out), cwd=ROOT)
    assert done.returncode == 0, done.stderr
    lines = out.read_text().splitlines()
    assert lines[0].startswith("t [s],stride,phase") and len(lines) == 1 + 10 + 21 + 10
    study = run("trajectory", "problems/grid_downward.yaml", "--out", str(tmp_path / "x.csv"), cwd=ROOT)
    assert study.returncode == 2 and "single gait" in study.stderr and not (tmp_path / "x.csv").exists()


def test_a_result_is_short_in_text_and_a_table_in_a_notebook():
    result = solve_problem(load_problem(ROOT / "problems" / "downward.yaml"))
    text = repr(result)
    assert text.startswith("<FixedPointResult downward: converged, stable") and len(text) < 120
    html = result._repr_html_()
    assert "<table>" in html and "spectral radius" in html and "0.899" in html
    # Angles as people read them, with the unit in the row's name.
    assert "theta_h [deg]" in html and f"{math.degrees(result.apex['theta_h']):.6g}" in html
    assert "theta_h_dot [deg/s]" in html and "z [m]" in html
    assert result.summary().splitlines()[0] == "downward: converged (verified fixed point)"
    figure = result.plot()
    assert len(figure.axes) == 3 and figure.axes[2].get_ylabel() == "ground reaction force [N]"


def test_figures_can_be_written_as_svg_or_pdf(tmp_path):
    text = (ROOT / "problems" / "continuation_slip_attack.yaml").read_text().replace(
        'range: ["20 deg", "25 deg"]', 'range: ["21 deg", "22 deg"]').replace("  switch: period_doubling\n", "")
    path = tmp_path / "band.yaml"
    path.write_text(text)
    done = run("solve", str(path), "--out", str(tmp_path / "svg"), "--format", "svg", "--quiet", cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "<svg" in (tmp_path / "svg" / "diagram.svg").read_text()[:1000]
    assert not (tmp_path / "svg" / "diagram.png").exists()
    grid = (ROOT / "problems" / "grid_downward.yaml").read_text().replace(
        "vary: {ydot: [0.1, 1.0, 0.1], z: [0.3, 0.7, 0.05]}", "vary: {ydot: [0.4, 0.5, 0.1], z: [0.4, 0.45, 0.05]}")
    (tmp_path / "grid.yaml").write_text(grid)
    done = run("solve", str(tmp_path / "grid.yaml"), "--out", str(tmp_path / "pdf"), "--format", "pdf", "--quiet", cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "pdf" / "spectral_radius_map.pdf").read_bytes()[:5] == b"%PDF-"
    assert not list((tmp_path / "pdf").glob("*.png"))


def test_strides_simulations_and_stability_are_short_too():
    from baslip import ReturnMap, Tolerances

    result = solve_problem(load_problem(ROOT / "problems" / "downward.yaml"))
    rmap = ReturnMap(Tolerances(1e-10, 1e-10))
    stride, run = rmap.stride(result.X, result.u, result.params), rmap.simulate(result.X, result.u, result.params, 3)
    for thing, start in ((stride, "<Stride to z = 0.4 m"), (run, "<Simulation: 3 strides>"),
                         (result.stability, "<Stability: stable, radius 0.899")):
        assert repr(thing).startswith(start) and len(repr(thing)) < 200
        assert "&lt;" in thing._repr_html_()


UNWRITABLE = "/proc/baslip-unwritable"  # not writable even by root


@pytest.mark.parametrize("argv, names", [
    (["trajectory", "problems/downward.yaml", "--out", f"{UNWRITABLE}.csv"], "--out"),
    (["problems", "--copy", UNWRITABLE], "--copy"),
    (["report", "--results", "/proc"], "--results"),
    (["report", "--results", "problems/downward.yaml"], "--results"),
])
def test_an_output_place_that_cannot_be_written_is_refused_before_any_work(argv, names, capsys, monkeypatch):
    import baslip.gait.from_problem

    def no_solve(*args, **kwargs):
        raise AssertionError("solved before the output place was checked")

    monkeypatch.setattr(baslip.gait.from_problem, "solve_start", no_solve)
    monkeypatch.chdir(ROOT)
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1 and captured.err.startswith(f"error: {names} ")


def test_report_on_a_folder_of_junk_is_one_line_not_a_traceback(tmp_path, capsys):
    (tmp_path / "grid_downward").mkdir()
    (tmp_path / "grid_downward" / "result.json").write_text("not json")
    (tmp_path / "grid_downward" / "points.csv").write_text("a,b\n1,2\n")
    assert main(["report", "--results", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot read the studies' results" in err
    assert not (tmp_path / "REPORT.md").exists()


def test_report_on_a_damaged_table_names_the_file_and_line(tmp_path, capsys):
    """Issue 57: a junk row stopped the report with a bare "ValueError: its line 6 has 1 cells"."""
    shutil.copytree(ROOT / "results" / "grid_downward", tmp_path / "grid_downward")
    points = tmp_path / "grid_downward" / "points.csv"
    lines = points.read_text().splitlines(keepends=True)
    points.write_text("".join([*lines[:5], "junk\n", *lines[5:]]))
    assert main(["report", "--results", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err == f"error: --results {tmp_path}: {points}: line 6: it has 1 cells, its header 22\n"
    assert not (tmp_path / "REPORT.md").exists()


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_trajectory_never_replaces_a_device_or_a_fifo(tmp_path, capsys, kind):
    """Issue 57: --out naming /dev/null or a named pipe replaced it with a regular file."""
    if kind == "fifo":
        out = tmp_path / "motion.csv"
        os.mkfifo(out)
    else:
        out = Path("/dev/null")
    before = os.stat(out)
    assert main(["trajectory", str(ROOT / "problems" / "downward.yaml"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    what = "a FIFO" if kind == "fifo" else "a character device"
    assert err == f"error: --out {out} is {what}, not a file; baslip writes no file in its place\n"
    after = os.stat(out)
    assert (after.st_ino, after.st_mode, after.st_rdev) == (before.st_ino, before.st_mode, before.st_rdev)


def test_a_full_disk_keeps_the_earlier_gait_whole_and_says_so_in_one_line(tmp_path, capsys, monkeypatch):
    """Issue 57: a full disk ended in "internal error: OSError: [Errno 28]"."""
    import baslip.files.atomic as atomic

    out = tmp_path / "downward"
    problem = str(ROOT / "problems" / "downward.yaml")
    assert main(["solve", problem, "--out", str(out), "--quiet"]) == 0
    earlier = (out / "result.json").read_bytes()
    capsys.readouterr()

    def full_disk(descriptor, mode="r", *args, **kwargs):
        if "w" in mode:  # a result being written: the disk is full
            os.close(descriptor)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return fdopen(descriptor, mode, *args, **kwargs)

    fdopen = os.fdopen
    monkeypatch.setattr(atomic.os, "fdopen", full_disk)
    assert main(["solve", problem, "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err == f"error: downward: no space left on device: {out / 'result.json'}\n"
    assert (out / "result.json").read_bytes() == earlier  # kept whole
    assert sorted(p.name for p in out.iterdir()) == ["multipliers.csv", "result.json"]
    monkeypatch.undo()
    assert main(["solve", problem, "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / "result.json").read_bytes())["status"] == "converged"
