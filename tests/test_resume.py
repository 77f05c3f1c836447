"""Specification of a study's life on the command line: killed, resumed, raced, changed.

* A study killed with SIGKILL at any moment and run again gives the same points.csv as an
  uninterrupted run, bit for bit (the timing column aside).
* Its worker processes (and multiprocessing's helper) do not outlive it.
* One run writes into a folder at a time; a second is refused naming the holder, and a
  lock left by a dead process is taken over.
* A folder holding results of a changed problem is refused unless ``--fresh`` is given.
* Exit codes: 0 complete, 1 solved nothing or stopped short, 2 bad input or busy/stale
  folder; every failed row says why.
"""

import csv
import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from processes import descendants, gone

from baslip.cli.solve import main
from baslip.files.lock import LOCK_NAME

ROOT = Path(__file__).resolve().parents[1]
# 10 x 3 = 30 fixed points of the hanging-trunk grid: a couple of seconds on two cores.
GRID = (ROOT / "problems" / "grid_downward.yaml").read_text().replace(
    "vary: {ydot: [0.1, 1.0, 0.1], z: [0.3, 0.7, 0.05]}", "vary: {ydot: [0.1, 1.0, 0.1], z: [0.4, 0.5, 0.05]}"
).replace("name: grid_downward", "name: small_grid")
POINTS = 30

pytestmark = pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to watch processes")


def start(problem: Path, out: Path, *extra) -> subprocess.Popen:
    # Ctrl-C reaches the run as it would from a terminal, even when these tests run as a
    # background job, which starts with SIGINT ignored (and Python then keeps it ignored).
    return subprocess.Popen([sys.executable, "-m", "baslip.solve", str(problem), "--out", str(out), "--quiet", *extra],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def rows_written(out: Path) -> int:
    try:
        return max(len((out / "points.csv").read_text().splitlines()) - 1, 0)
    except FileNotFoundError:
        return 0


def wait_for_rows(process: subprocess.Popen, out: Path, rows: int) -> None:
    """Return as soon as ``rows`` rows are in points.csv (or the run has ended)."""
    deadline = time.monotonic() + 300
    while process.poll() is None and rows_written(out) < rows and time.monotonic() < deadline:
        time.sleep(0.002)


def kill_after(process: subprocess.Popen, out: Path, rows: int) -> None:
    """SIGKILL ``process`` as soon as ``rows`` rows are in points.csv."""
    wait_for_rows(process, out, rows)
    process.kill()
    process.wait()


def table_without_timing(out: Path) -> list[list[str]]:
    with open(out / "points.csv", newline="") as handle:
        table = list(csv.reader(handle))
    drop = table[0].index("time_s")
    return [row[:drop] + row[drop + 1:] for row in table]


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    """The problem file and one uninterrupted run of it."""
    folder = tmp_path_factory.mktemp("resume")
    problem = folder / "small_grid.yaml"
    problem.write_text(GRID)
    reference = folder / "uninterrupted"
    run = start(problem, reference)
    assert run.wait() == 0, run.stderr.read()
    return problem, reference


def test_killed_three_times_and_resumed_gives_the_same_answers(grid, tmp_path):
    problem, reference = grid
    out = tmp_path / "resumed"
    for rows in (2, 9, 20):
        kill_after(start(problem, out), out, rows)
        assert rows <= rows_written(out) < POINTS  # killed mid-study, rows saved
    assert start(problem, out).wait() == 0
    assert table_without_timing(out) == table_without_timing(reference)
    assert len(table_without_timing(out)) == POINTS + 1
    assert not any(p.name.endswith(".states") for p in out.iterdir())  # nothing left to resume
    record = json.loads((out / "result.json").read_text())
    assert record["complete"] and record["done_before_this_run"] >= 20


def test_workers_do_not_outlive_a_killed_run(grid, tmp_path):
    problem, _ = grid
    out = tmp_path / "orphans"
    run = start(problem, out)
    wait_for_rows(run, out, 1)
    children = descendants(run.pid)
    assert len(children) >= 2  # the two workers
    run.kill()
    run.wait()
    deadline = time.monotonic() + 10
    while not all(gone(pid) for pid in children) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert [pid for pid in children if not gone(pid)] == []


@pytest.mark.parametrize("delay", [0.0, 0.05, 0.15, 0.4])
def test_a_run_killed_while_its_workers_start_leaves_no_process(grid, tmp_path, delay):
    """kill -9 a few moments after the first worker appears, while the workers are still
    starting (importing baslip, building their solvers): half a second later no process
    the run started is alive, and nothing complains of leaked semaphores."""
    problem, _ = grid
    out = tmp_path / "startup"
    run = start(problem, out)
    deadline = time.monotonic() + 60
    while not descendants(run.pid) and time.monotonic() < deadline:
        time.sleep(0.002)
    time.sleep(delay)
    children = descendants(run.pid)
    assert children
    run.kill()
    run.wait()
    time.sleep(0.5)
    assert [pid for pid in children if not gone(pid)] == []
    assert "leaked" not in run.stderr.read()


def test_two_runs_started_together_give_one_writer(grid, tmp_path):
    problem, reference = grid
    out = tmp_path / "race"
    first, second = start(problem, out), start(problem, out)
    codes = sorted([first.wait(), second.wait()])
    assert codes == [0, 2]
    loser = first if first.returncode == 2 else second
    message = loser.stderr.read()
    assert message.count("\n") == 1 and f"{out} is in use by process" in message
    assert table_without_timing(out) == table_without_timing(reference)
    assert json.loads((out / "result.json").read_text())["points"] == POINTS
    assert not (out / LOCK_NAME).exists()


def test_a_busy_folder_is_refused_naming_the_process(grid, tmp_path, capsys):
    problem, _ = grid
    out = tmp_path / "busy"
    run = start(problem, out)
    deadline = time.monotonic() + 60
    while not (out / LOCK_NAME).exists() and time.monotonic() < deadline:
        time.sleep(0.005)
    assert main([str(problem), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"process {run.pid} " in err
    run.wait()


def test_a_lock_left_by_a_dead_process_is_taken_over(tmp_path):
    out = tmp_path / "downward"
    out.mkdir()
    (out / LOCK_NAME).write_text("process 999999 on elsewhere (python -m baslip.solve)\n")
    assert main([str(ROOT / "problems" / "downward.yaml"), "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / "result.json").read_text())["status"] == "converged"
    assert not (out / LOCK_NAME).exists()


def test_a_lock_that_is_a_link_is_never_followed(tmp_path, capsys):
    out = tmp_path / "downward"
    out.mkdir()
    target = tmp_path / "precious.txt"
    target.write_text("not baslip's\n")
    (out / LOCK_NAME).symlink_to(target)
    assert main([str(ROOT / "problems" / "downward.yaml"), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "has a link at .baslip.lock" in err
    assert target.read_text() == "not baslip's\n" and not (out / "result.json").exists()


def test_a_changed_problem_is_refused_unless_fresh(grid, tmp_path, capsys):
    problem, reference = grid
    out = tmp_path / "stale"
    kill_after(start(problem, out), out, 4)
    changed = tmp_path / "changed.yaml"
    changed.write_text(GRID.replace("k: 1000.0", "k: 1200.0"))
    assert main([str(changed), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "params.k" in err and "--fresh" in err
    assert main([str(changed), "--out", str(out), "--quiet", "--fresh"]) == 0
    record = json.loads((out / "result.json").read_text())
    assert record["provenance"]["problem"]["params"]["k"] == 1200.0
    assert record["done_before_this_run"] == 0 and record["points"] == POINTS


def test_more_lanes_are_recorded_answers_follow_lanes_not_workers(grid, tmp_path, capsys):
    """Three lanes: the same rows with one worker or three, and the count kept on resume;
    asking a resumed run for another count is refused, one line, exit 2."""
    problem, _ = grid
    one, three = tmp_path / "one", tmp_path / "three"
    assert main([str(problem), "--out", str(one), "--quiet", "--lanes", "3", "--jobs", "1"]) == 0
    run = start(problem, three, "--lanes", "3", "--jobs", "3")
    assert run.wait() == 0, run.stderr.read()
    assert table_without_timing(one) == table_without_timing(three)
    assert json.loads((three / "result.json").read_text())["provenance"]["lanes"] == 3
    assert main([str(problem), "--out", str(three), "--quiet"]) == 0  # resumes in its 3 lanes
    assert json.loads((three / "result.json").read_text())["provenance"]["lanes"] == 3
    capsys.readouterr()
    assert main([str(problem), "--out", str(three), "--lanes", "2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "3 lanes, not 2" in err and "--fresh" in err


def test_results_without_provenance_are_not_resumed(grid, tmp_path, capsys):
    problem, reference = grid
    out = tmp_path / "legacy"
    out.mkdir()
    (out / "points.csv").write_text((reference / "points.csv").read_text())
    assert main([str(problem), "--out", str(out)]) == 2
    assert "no provenance" in capsys.readouterr().err


def test_a_study_that_solves_nothing_exits_1_and_says_why_per_row(tmp_path, capsys):
    problem = tmp_path / "hopeless.yaml"
    problem.write_text(GRID.replace("vary: {ydot: [0.1, 1.0, 0.1], z: [0.4, 0.5, 0.05]}", "vary: {ydot: [0.4, 0.5, 0.1]}")
                       .replace("objective: nearest_guess", "objective: nearest_guess\nsolver: {max_iter: 1}"))
    out = tmp_path / "out"
    assert main([str(problem), "--out", str(out), "--quiet"]) == 1
    assert "no fixed point was found" in capsys.readouterr().err
    with open(out / "points.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 and all(r["status"] == "failed" and "Maximum_Iterations_Exceeded" in r["reason"] for r in rows)
    record = json.loads((out / "result.json").read_text())
    assert record["complete"] and [r["status"] for r in record["not_solved"]] == ["failed", "failed"]


def test_a_study_stopped_short_exits_1(tmp_path):
    # A grid of 3,731 points: too many to finish between the third row and the signal
    # (the 30-point grid can, now that a point takes a few milliseconds).
    problem = tmp_path / "large_grid.yaml"
    problem.write_text(GRID.replace("vary: {ydot: [0.1, 1.0, 0.1], z: [0.4, 0.5, 0.05]}",
                                    "vary: {ydot: [0.1, 1.0, 0.01], z: [0.3, 0.7, 0.01]}"))
    out = tmp_path / "short"
    run = start(problem, out)
    wait_for_rows(run, out, 3)
    run.send_signal(signal.SIGINT)
    assert run.wait() == 1
    assert "stopped short" in run.stderr.read()
    assert json.loads((out / "result.json").read_text())["complete"] is False


def test_a_row_changed_by_hand_is_solved_again_with_one_note(grid, tmp_path, caplog):
    """Issue 57: a sweep whose points.csv had a row's z set to NaN resumed and kept the NaN row."""
    problem, reference = grid
    out = tmp_path / "changed"
    kill_after(start(problem, out), out, 6)
    with open(out / "points.csv", newline="") as handle:
        table = list(csv.reader(handle))
    z = table[0].index("z")
    table[3][z] = "nan"
    (out / "points.csv").write_text("".join(",".join(row) + "\n" for row in table))
    assert main([str(problem), "--out", str(out)]) == 0
    notes = [line for line in caplog.messages if "dropped line" in line]
    assert notes == ["note: points.csv: dropped line 4 (its z is 'nan', not a finite number); its task runs again"]
    assert table_without_timing(out) == table_without_timing(reference)


def test_a_full_disk_mid_study_is_one_line_and_a_later_resume_completes(grid, tmp_path, capsys, monkeypatch):
    """Issue 57: a full disk stopped a sweep with "internal error: OSError: [Errno 28]"."""
    import builtins

    import baslip.studies.runner as runner

    problem, reference = grid
    out = tmp_path / "full"
    appended = []

    def filling(path, mode="r", *args, **kwargs):
        if mode == "a" and Path(path).name == "points.csv":
            appended.append(path)
            if len(appended) > 6:  # the seventh row finds the disk full
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return builtins.open(path, mode, *args, **kwargs)

    monkeypatch.setattr(runner, "open", filling, raising=False)  # the runner's writes only
    assert main([str(problem), "--out", str(out), "--quiet"]) == 1
    assert capsys.readouterr().err == f"error: small_grid: no space left on device: {out / 'points.csv'}\n"
    assert rows_written(out) == 6
    monkeypatch.undo()
    assert main([str(problem), "--out", str(out), "--quiet"]) == 0
    assert table_without_timing(out) == table_without_timing(reference)


@pytest.fixture
def small_disk(tmp_path):
    """A 200 kB tmpfs, unmounted afterwards; skipped where mounting is not permitted."""
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=200k", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    yield disk
    subprocess.run(["umount", str(disk)], check=True)


def test_a_study_on_a_disk_that_fills_exits_1_and_resumes_once_there_is_room(grid, small_disk):
    """Issue 57: a sweep into a 200 kB filesystem once exited 0 although the disk had filled."""
    problem, reference = grid
    filler = small_disk / "filler"
    filler.write_bytes(bytes(150_000))  # about 50 kB left: the rows fit, the figures do not
    out = small_disk / "grid"
    run = start(problem, out)
    assert run.wait() == 1
    err = run.stderr.read()
    assert err.count("\n") == 1 and err.startswith("error: small_grid: no space left on device: ") and str(out) in err
    filler.unlink()
    assert start(problem, out).wait() == 0
    assert table_without_timing(out) == table_without_timing(reference)
    assert json.loads((out / "result.json").read_text())["complete"] is True


def test_a_sweep_and_a_gait_started_together_into_one_folder_give_one_run(tmp_path):
    """Issue 57: both exited 0 and the folder held the sweep: each checked the folder before
    either had written. The lock is now taken before the folder's kind is decided."""
    sweep = tmp_path / "tiny_grid.yaml"
    sweep.write_text(GRID.replace("vary: {ydot: [0.1, 1.0, 0.1], z: [0.4, 0.5, 0.05]}",
                                  "vary: {ydot: [0.5, 0.6, 0.1], z: [0.4, 0.45, 0.05]}"))
    gait = ROOT / "problems" / "downward.yaml"
    for trial in range(6):
        out = tmp_path / f"race{trial}"
        runs = [start(sweep, out), start(gait, out)] if trial % 2 else [start(gait, out), start(sweep, out)]
        codes = [run.wait() for run in runs]
        assert sorted(codes) == [0, 2], [run.stderr.read() for run in runs]
        (winner,) = [run for run in runs if run.returncode == 0]
        (loser,) = [run for run in runs if run.returncode == 2]
        message = loser.stderr.read()
        assert message.count("\n") == 1 and (" is in use by process " in message or " run, not a " in message)
        kind = json.loads((out / "result.json").read_text()).get("kind", "gait")
        assert kind == ("sweep" if winner.args[3] == str(sweep) else "gait")
