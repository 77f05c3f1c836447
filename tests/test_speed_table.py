"""The README's speed table (``benchmarks/speed_table.py``): it is the render of the figures
that the benchmarks recorded (``benchmarks/figures.py``), each judged against its target
on the right side, with the machine it was measured on; and it cannot drift from them."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCHMARKS = ROOT / "benchmarks"


@pytest.fixture
def tables(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import figures
    import speed_table

    return figures, speed_table


def _check(*arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(BENCHMARKS / "speed_table.py"), "--check", *arguments],
                          capture_output=True, text=True)


def test_the_readme_speed_table_is_the_render_of_the_recorded_figures():
    done = _check()
    assert done.returncode == 0, done.stderr


def test_every_benchmark_that_records_has_its_figures_committed(tables):
    figures, _ = tables
    recording = {p.stem for p in BENCHMARKS.glob("bench_*.py") if "--record" in p.read_text()}
    recorded = {run.benchmark for run in figures.load()}
    assert recording and recorded == recording


def test_every_recorded_figure_names_its_issue_machine_and_measurement(tables):
    figures, _ = tables
    for run in figures.load():
        assert run.machine["cores"] >= 1 and run.machine["cpu"] and run.machine["casadi"]
        for figure in run.figures:
            assert figure.issue in (20, 21, 22, 56) and figure.value > 0 and figure.target > 0 and figure.detail


def test_a_figure_meets_its_target_only_on_the_right_side(tables):
    figures, _ = tables
    Figure = figures.Figure
    assert Figure(22, "a time", 5.0, "ms", 5.0).met and not Figure(22, "a time", 5.01, "ms", 5.0).met
    assert Figure(22, "a rate", 3e4, "/s", 3e4, "higher").met
    assert not Figure(22, "a rate", 29999.0, "/s", 3e4, "higher").met
    with pytest.raises(ValueError, match="better"):
        Figure(22, "a time", 1.0, "s", 2.0, "faster")


def test_the_render_marks_each_figure_and_counts_those_met(tables):
    figures, speed_table = tables
    run = figures.Recorded("bench_x", "2026-12-06", figures.machine(), (
        figures.Figure(22, "r over erk", 0.75, "x", 2.0, "higher", "engine 118 us"),
        figures.Figure(21, "a basin", 29.5, "s", 60.0, "lower", "batched"),
        figures.Figure(22, "strides/s", 31578.0, "/s", 30000.0, "higher", "batched")))
    table = speed_table.render([run])
    rows = [line for line in table.splitlines() if line.startswith("| 2")]
    assert rows == ["| 21 | a basin | 29.5 s | <= 60 s | yes | batched |",
                    "| 22 | r over erk | 0.75x | >= 2x | **no** | engine 118 us |",
                    "| 22 | strides/s | 31,578 /s | >= 30,000 /s | yes | batched |"]
    assert "2 of 3 figures meet their targets." in table and "(`bench_x.py` 2026-12-06)" in table


def test_recorded_figures_load_back_unchanged(tables, tmp_path):
    figures, _ = tables
    figure = figures.Figure(20, "a cell", 14.0, "s", 30.0, "lower", "one seed")
    path = figures.record("bench_y", [figure], tmp_path)
    (run,) = figures.load(tmp_path)
    assert run.figures == (figure,) and run.benchmark == "bench_y" and path == tmp_path / "bench_y.json"
    assert [p.name for p in tmp_path.iterdir()] == ["bench_y.json"]  # no temporary file left


def test_check_fails_when_a_figure_changes_and_leaves_the_readme_alone(tmp_path):
    shutil.copytree(BENCHMARKS / "figures", tmp_path / "figures")
    readme = tmp_path / "README.md"
    shutil.copy(ROOT / "README.md", readme)
    path = sorted((tmp_path / "figures").glob("*.json"))[0]
    data = json.loads(path.read_text())
    data["figures"][0]["value"] *= 2
    path.write_text(json.dumps(data))
    before = readme.read_text()
    done = _check("--readme", str(readme), "--figures", str(tmp_path / "figures"))
    assert done.returncode == 1 and "not the render" in done.stderr and readme.read_text() == before


def test_a_readme_without_the_markers_is_refused_in_one_line(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("# no table here\n")
    done = _check("--readme", str(readme))
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "marker" in done.stderr
    assert readme.read_text() == "# no table here\n"
