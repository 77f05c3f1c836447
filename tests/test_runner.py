"""Specification of baslip.studies.runner: the resumable CSV and the worker processes.

A study's CSV survives anything a kill or a crash can leave: a row cut short, an empty
file, a torn header, junk, repeated keys. What cannot be repaired is set aside, never
lost and never an internal error. Workers never outlive the process that started them,
and a task that fails in its worker fails the run, saying why.
The time left is estimated from the recent pace, not the pace since the start.
"""

import csv
import logging
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest
from processes import gone
from runs import ROOT

from baslip.studies.progress import RATE_WINDOW_S, Progress
from baslip.studies.runner import ResumableCsv, StateLog


def test_an_empty_file_gets_its_header_back(tmp_path):
    path = tmp_path / "points.csv"
    path.write_bytes(b"")
    table = ResumableCsv(path, ["a", "b"], ["a"])
    assert table.rows == [] and path.read_text() == "a,b\n"


def test_a_header_cut_short_is_written_again(tmp_path):
    path = tmp_path / "points.csv"
    path.write_text("a,")
    table = ResumableCsv(path, ["a", "b"], ["a"])
    assert table.rows == [] and path.read_text() == "a,b\n"
    assert "cut short" in " ".join(table.notes)


@pytest.mark.parametrize("content", [b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe", b"x,y\n1,2\n"], ids=["binary", "foreign header"])
def test_an_unreadable_file_is_set_aside_and_started_afresh(tmp_path, content):
    path = tmp_path / "points.csv"
    path.write_bytes(content)
    table = ResumableCsv(path, ["a", "b"], ["a"])
    assert table.rows == [] and path.read_text() == "a,b\n"
    (aside,) = [p for p in tmp_path.iterdir() if p.name.startswith("points.csv.set-aside-")]
    assert aside.read_bytes() == content
    assert aside.name in table.notes[-1]


def test_repeated_keys_keep_the_first_row_and_say_so(tmp_path):
    path = tmp_path / "points.csv"
    path.write_text("a,b\n0.1,1.0\n0.2,2.0\n0.1,9.0\n0.2,9.0\n0.3,3.0\n")
    table = ResumableCsv(path, ["a", "b"], ["a"])
    assert [(r["a"], r["b"]) for r in table.rows] == [("0.1", "1.0"), ("0.2", "2.0"), ("0.3", "3.0")]
    assert "2 rows repeat a key" in table.notes[-1]
    assert path.read_text() == "a,b\n0.1,1.0\n0.2,2.0\n0.3,3.0\n"


def test_rows_with_the_wrong_number_of_cells_are_dropped(tmp_path):
    path = tmp_path / "points.csv"
    path.write_text("a,b\n0.1,1.0\n0.2\n0.3,3.0,extra\n")
    table = ResumableCsv(path, ["a", "b"], ["a"])
    assert table.done() == {("0.1",)}
    assert table.notes == ["points.csv: dropped line 3 (it has 1 cells, its header 2); its task runs again",
                           "points.csv: dropped line 4 (it has 3 cells, its header 2); its task runs again"]


def test_saved_states_round_trip_exactly_and_finish_orders_the_rows(tmp_path):
    path = tmp_path / "points.csv"
    table = ResumableCsv(path, ["a", "b"], ["a"])
    state = [0.1 + 0.2, 1e-310, -2.0 / 3.0]
    table.append({"a": 0.2, "b": 2.0, "state": state})
    table.append({"a": 0.1, "b": 1.0})
    assert StateLog(table.states.path).read() == {("0.2",): state}
    table.finish([{"a": 0.1}, {"a": 0.2}])
    assert path.read_text() == "a,b\n0.1,1.0\n0.2,2.0\n"
    assert not table.states.path.exists()


SLEEPY = """
import time

def sleeper(lane, context, queue):
    time.sleep(60)
"""

# No `if __name__ == "__main__":` guard: the worker never imports this script. It finds
# the module beside it because it is given this process's sys.path.
PARENT = """
import time
import sleepy
from baslip.studies.processes import start_workers
from baslip.studies.runner import _worker_main

processes, _ = start_workers(_worker_main, [(sleepy.sleeper, [[]], None)])  # one empty lane
print(processes[0].pid, flush=True)
time.sleep(60)
"""


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to watch processes")
def test_a_worker_dies_when_its_parent_is_killed(tmp_path):
    (tmp_path / "sleepy.py").write_text(SLEEPY)
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=tmp_path)
    child = int(parent.stdout.readline())
    time.sleep(1.0)  # let the child set up its watch
    assert not gone(child)
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 10
    while not gone(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert gone(child)


def test_fewer_workers_than_lanes_give_the_same_rows(tmp_path):
    """--jobs 1 runs both lanes in one process, in turn: the rows are the same."""
    from baslip.problem.reader import load_problem
    from baslip.studies.registry import run_study

    text = (ROOT / "problems" / "grid_downward.yaml").read_text().replace(
        "vary: {ydot: [0.1, 1.0, 0.1], z: [0.3, 0.7, 0.05]}", "vary: {ydot: [0.3, 0.6, 0.1], z: [0.4, 0.45, 0.05]}")
    tables = []
    for jobs in (1, 2):
        path = tmp_path / f"grid_{jobs}.yaml"
        path.write_text(text)
        out = tmp_path / f"out_{jobs}"
        summary = run_study(load_problem(path), out, quiet=True, jobs=jobs)
        assert summary["solved"] == 8
        rows = list(csv.DictReader(open(out / "points.csv")))
        tables.append([{k: v for k, v in r.items() if k != "time_s"} for r in rows])
    assert tables[0] == tables[1]


def test_rows_that_are_no_task_of_the_study_are_dropped(tmp_path):
    table = ResumableCsv(tmp_path / "points.csv", ["sweep_z", "value"], ["sweep_z"])
    table.append({"sweep_z": 0.4, "value": 1.0})
    with open(tmp_path / "points.csv", "a") as handle:
        handle.write("junk,junk\n0.45,2.0\n")  # right number of cells, no task of this study
    again = ResumableCsv(tmp_path / "points.csv", ["sweep_z", "value"], ["sweep_z"])
    assert len(again.rows) == 3
    note = again.keep_tasks([{"sweep_z": 0.4}, {"sweep_z": 0.5}])
    assert note == "points.csv: dropped 2 rows that are no task of this study"
    assert (tmp_path / "points.csv").read_text() == "sweep_z,value\n0.4,1.0\n" and again.done() == {("0.4",)}


def test_the_rate_is_the_recent_pace_once_slow_tasks_follow_fast_ones():
    """1,000 fast tasks in 10 s, then one a second for two windows: the rate is then 1/s,
    where the average since the start (more than 7/s) would promise a seventh of the time
    left."""
    progress = Progress("study", 2000, quiet=True)
    for k in range(1, 1001):
        progress.rate(k, k / 100)
    seconds = int(2 * RATE_WINDOW_S)
    for k in range(1, seconds + 1):
        rate = progress.rate(1000 + k, 10 + k)
    assert rate == pytest.approx(1.0)  # the average since the start, (1000 + 120) / (10 + 120), is above 8
    assert Progress("study", 10, quiet=True).rate(0, 0.0) == 0.0


UNGUARDED = """
import multiprocessing, sys
from pathlib import Path
import baslip
from baslip.errors import RunError

if len(sys.argv) > 3:
    multiprocessing.set_executable(sys.argv[3])
out = Path(sys.argv[2]) if sys.argv[2] != "-" else None
try:
    baslip.run(Path(sys.argv[1]), out, progress=False)
except RunError as err:
    print("RunError:", err)
    sys.exit(3)
print("returned")
"""


@pytest.fixture
def two_point_study(tmp_path):
    problem = tmp_path / "grid.yaml"
    problem.write_text((ROOT / "problems" / "grid_downward.yaml").read_text().replace(
        "vary: {ydot: [0.1, 1.0, 0.1], z: [0.3, 0.7, 0.05]}", "vary: {ydot: [0.3, 0.4, 0.1]}"))
    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED)
    return problem, script


def run_unguarded(script, *arguments) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(script), *map(str, arguments)], capture_output=True, text=True,
                          timeout=300, cwd=script.parent)


def test_a_script_without_a_main_guard_runs_a_study(two_point_study, tmp_path):
    """A script that starts a study at its top level, with no ``if __name__ ==
    "__main__":``: the workers do not import it, so the study runs once and returns."""
    problem, script = two_point_study
    run = run_unguarded(script, problem, tmp_path / "out")
    assert run.returncode == 0, run.stdout + run.stderr[-2000:]
    assert run.stdout.splitlines() == ["returned"]  # the script ran once: no worker re-ran it
    assert len((tmp_path / "out" / "points.csv").read_text().splitlines()) == 3


@pytest.mark.parametrize("out", ["out", "-"])
def test_workers_that_die_at_start_are_a_run_error_true_about_what_was_kept(two_point_study, tmp_path, out):
    """Workers that cannot start (here multiprocessing's executable, which they honour,
    is ``false``) make a RunError, not an empty result. With an ``out`` folder the done
    tasks are kept for a rerun; without one the error says that nothing was kept."""
    problem, script = two_point_study
    run = run_unguarded(script, problem, tmp_path / out if out != "-" else "-", shutil.which("false"))
    assert run.returncode == 3, run.stdout + run.stderr[-2000:]
    assert "ended with exit code 1 before sending any row" in run.stdout
    if out == "-":
        assert "0 of 2 tasks were done, not kept: the run had no `out` folder" in run.stdout
        assert "rerun resumes" not in run.stdout
    else:
        assert "0 of 2 tasks were done, kept, and a rerun resumes from them" in run.stdout


def _row_then_exit(lane, context, queue) -> None:
    """A worker that sends its lane's first row and then ends with exit code 7."""
    queue.put({"task": lane[0]["task"], "value": 1.0, "state": None})
    os._exit(7)


def test_a_worker_that_fails_midway_is_a_failure_with_its_rows_kept(tmp_path):
    """A lane whose worker process ends early (here: it exits after its first row) makes
    the run a failure, not a complete result; the rows it sent are kept for a rerun."""
    from baslip.studies.runner import run_tasks

    table = ResumableCsv(tmp_path / "points.csv", ["task", "value"], ["task"])
    lanes = [[{"task": 0}, {"task": 1}], [{"task": 2}, {"task": 3}]]
    report = run_tasks(lanes, _row_then_exit, None, table, "test", quiet=True)
    assert not report.complete and not report.interrupted
    assert "exit code 7 before finishing its tasks" in report.worker_failure
    kept = ResumableCsv(tmp_path / "points.csv", ["task", "value"], ["task"]).done()
    assert len(kept) == report.ran >= 1


def _row_then_raise(lane, context, queue) -> None:
    """A worker function that sends its lane's first row, then raises, putting a stray
    None (a lane's end) on the way out."""
    try:
        queue.put({"task": lane[0]["task"], "value": 1.0, "state": None})
        raise ArithmeticError("the stride cannot be vouched for")
    finally:
        queue.put(None)


def test_a_task_that_raises_in_its_worker_is_a_failure_that_says_why_with_its_rows_kept(tmp_path, capfd):
    """A stray None put on the way out of an exception is not taken for the lane's end: the run is a failure naming the exception, not a complete
    result with tasks missing, and the worker's stderr holds no traceback."""
    from baslip.studies.runner import run_tasks

    table = ResumableCsv(tmp_path / "points.csv", ["task", "value"], ["task"])
    report = run_tasks([[{"task": 0}, {"task": 1}]], _row_then_raise, None, table, "test", quiet=True)
    assert not report.complete and not report.interrupted
    assert report.worker_failure == "a task failed in its worker: ArithmeticError: the stride cannot be vouched for"
    assert "Traceback" not in capfd.readouterr().err
    assert len(ResumableCsv(tmp_path / "points.csv", ["task", "value"], ["task"]).done()) == report.ran == 1


def test_a_study_whose_tasks_take_minutes_is_heard_from_every_10_s_and_quiet_silences_it(tmp_path, fake_clock):
    """Eight tasks of 150 s each on two lanes (rows arriving from a stub moving a fake
    clock), the case of the piped optimal study that said nothing for 307 s: a line comes
    at least every 10 s, with the tasks done, the time so far and the latest news from
    inside a task; quiet says nothing and runs no heartbeat."""
    from baslip import diagnostics
    from baslip.studies.runner import TaskNote, _collect

    def arrivals():
        for k in range(8):
            diagnostics.CLOCK.advance(40.0)
            yield TaskNote(f"IPOPT try 1 of up to 2 (stability NLP): still solving, {k} s")
            diagnostics.CLOCK.advance(35.0)
            yield {"task": k, "value": 1.0, "state": None}
        yield from (None, None)

    for shown in (True, False):
        clock = fake_clock(shown)
        table = ResumableCsv(tmp_path / f"points_{shown}.csv", ["task", "value"], ["task"])
        progress = Progress("optimal", 8, quiet=not shown)
        assert _collect(arrivals().__next__, 2, table, progress, 0, time.perf_counter()) == (8, False, "")
        assert clock.time == 600.0 and clock.running() == 0
        if not shown:
            assert clock.said == []
            continue
        assert clock.longest_silence(0.0, 600.0) <= 10.0
        said = clock.messages()
        assert said[0] == "optimal: 0/8 done, starting the rest"
        assert "optimal: 0/8 done, 36 s so far, tasks running" in said
        assert "optimal: 0/8 done, 45 s so far, tasks running; IPOPT try 1 of up to 2 (stability NLP): still solving, 0 s" in said
        assert said[-1].startswith("optimal: 8/8 done")


def test_a_workers_progress_records_go_to_the_parent_and_its_warnings_to_stderr(capsys):
    from baslip.studies.runner import TaskNote, _NoteRelay

    sent = []
    relay = _NoteRelay(sent.append)
    log = logging.getLogger("baslip.gait.tries")
    relay.handle(log.makeRecord(log.name, logging.INFO, __file__, 1, "IPOPT try 2 of 2: starting", (), None))
    relay.handle(log.makeRecord(log.name, logging.WARNING, __file__, 1, "baslip: no working C compiler", (), None))
    assert sent == [TaskNote("IPOPT try 2 of 2: starting")]
    assert capsys.readouterr().err == "baslip: no working C compiler\n"


def _noting_worker(lane, context, queue) -> None:
    """A worker whose task logs a progress line before its row."""
    from baslip.diagnostics import logger

    for task in lane:
        logger("baslip.gait.tries").info(f"task {task['task']}: still solving")
        queue.put({"task": task["task"], "value": 1.0, "state": None})


def test_a_task_s_progress_lines_reach_the_parent_s_progress(tmp_path, monkeypatch):
    from baslip.studies.runner import run_tasks

    notes = []
    monkeypatch.setattr(Progress, "note", lambda self, text: notes.append(text))
    table = ResumableCsv(tmp_path / "points.csv", ["task", "value"], ["task"])
    report = run_tasks([[{"task": 0}, {"task": 1}], [{"task": 2}]], _noting_worker, None, table, "study", quiet=True)
    assert report.complete
    assert sorted(notes) == ["task 0: still solving", "task 1: still solving", "task 2: still solving"]


@pytest.mark.parametrize("cell, why", [("nan", "its z is 'nan'"), ("inf", "its z is 'inf'"), ("junk", "its z is 'junk'")])
def test_a_converged_row_whose_state_is_not_finite_is_dropped_naming_its_line(tmp_path, cell, why):
    """Issue 57: a sweep whose points.csv had a row's z set to NaN by hand resumed and kept it."""
    path = tmp_path / "points.csv"
    columns = ["sweep_z", "z", "theta_h", "status"]
    path.write_text(f"{','.join(columns)}\n0.3,0.3,1.5,converged\n0.4,{cell},1.5,converged\n0.5,0.5,1.5,converged\n")
    table = ResumableCsv(path, columns, ["sweep_z"])
    assert table.done() == {("0.3",), ("0.5",)}
    (note,) = table.notes
    assert note.startswith("points.csv: dropped line 3 (") and why in note and "runs again" in note
    assert path.read_text() == f"{','.join(columns)}\n0.3,0.3,1.5,converged\n0.5,0.5,1.5,converged\n"


def test_a_failed_rows_state_may_be_anything(tmp_path):
    """Only a converged gait's apex state must be finite: a failed solve keeps its row."""
    path = tmp_path / "points.csv"
    path.write_text("sweep_z,z,status\n0.3,nan,failed\n0.4,,not_verified\n")
    table = ResumableCsv(path, ["sweep_z", "z", "status"], ["sweep_z"])
    assert table.done() == {("0.3",), ("0.4",)} and table.notes == []


def test_a_state_line_cut_short_does_not_swallow_the_next(tmp_path):
    """A full disk or a kill can leave half a line in the state log; the next state is kept whole."""
    log = StateLog(tmp_path / ".points.csv.states")
    log.append(("0.1",), [1.0])
    with open(log.path, "a") as handle:
        handle.write('{"key": ["0.2"], "sta')
    log.append(("0.3",), [3.0])
    assert log.read() == {("0.1",): [1.0], ("0.3",): [3.0]}
