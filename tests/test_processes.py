"""Specification of baslip.studies.processes: worker processes and the map over both cores.

* The map returns ``task(item)`` in item order, whatever worker ran each item, and the
  same results with one worker (in this process) as with two.
* Each worker builds its task once and is handed items as it becomes free.
* With ``enough``, the map ends at the shortest leading run of results that is enough,
  whichever worker finished first.
* A worker that fails ends the map with :class:`WorkerDied`, not a hang.
* Workers never import the caller's ``__main__``, and none outlives its parent, whether
  the parent is stopped by Ctrl-C or killed.
"""

import os
import signal
import subprocess
import sys
import time

import pytest
from processes import descendants, gone

from baslip.studies.processes import WorkerDied, map_in_processes, start_workers


def squarer(offset):
    """A task that says which process ran it."""
    return lambda x: (x * x + offset, os.getpid())


def failing(_context):
    def task(x):
        if x == 3:
            raise ValueError("a task that fails")
        return x

    return task


def test_results_come_in_item_order_and_do_not_depend_on_the_worker_count():
    items = list(range(9))
    one = map_in_processes(squarer, items, 5, jobs=1)
    two = map_in_processes(squarer, items, 5, jobs=2)
    assert [r[0] for r in one] == [r[0] for r in two] == [x * x + 5 for x in items]
    assert {r[1] for r in one} == {os.getpid()}
    assert len({r[1] for r in two}) == 2 and os.getpid() not in {r[1] for r in two}


def sleeper(_context):
    """A task that takes longer for later items, and far longer for item 5."""

    def task(x):
        time.sleep(30.0 if x == 5 else 0.05 * x)
        return x

    return task


@pytest.mark.parametrize("jobs", [1, 2])
def test_enough_ends_the_map_at_the_shortest_leading_run_that_is_enough(jobs):
    started = time.perf_counter()
    results = map_in_processes(sleeper, list(range(8)), None, jobs=jobs, enough=lambda run: run[-1] >= 3)
    assert results == [0, 1, 2, 3]
    assert time.perf_counter() - started < 20  # item 5, if started, was stopped


def test_a_failing_task_ends_the_map_with_worker_died(capfd):
    with pytest.raises(WorkerDied):
        map_in_processes(failing, list(range(6)), None, jobs=2)
    assert "a task that fails" in capfd.readouterr().err


SLOW = """
import pathlib, time

def slow(folder):
    def task(x):
        (pathlib.Path(folder) / f"started-{x}").touch()
        time.sleep(60)
        return x

    return task
"""

# No `if __name__ == "__main__":` guard: the workers never import this script.
MAPPER = """
import os, sys
import slow
from baslip.studies.processes import map_in_processes

map_in_processes(slow.slow, [0, 1], os.getcwd(), jobs=2)
"""


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to watch processes")
@pytest.mark.parametrize("how", ["ctrl-c", "kill"])
def test_no_worker_outlives_a_parent_stopped_by_ctrl_c_or_killed(tmp_path, how):
    """A script without a main guard maps two slow items over two workers. Ctrl-C (SIGINT
    to the whole process group, as a terminal sends it) or SIGKILL of the script alone,
    once both workers are busy: the script ends, and within seconds no process it started
    is alive."""
    (tmp_path / "slow.py").write_text(SLOW)
    (tmp_path / "mapper.py").write_text(MAPPER)
    # A new session, so that the group's SIGINT reaches this run alone; SIGINT restored to
    # its default, which a test run in the background would leave ignored.
    run = subprocess.Popen([sys.executable, "mapper.py"], cwd=tmp_path, stderr=subprocess.PIPE, text=True,
                           start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while len(list(tmp_path.glob("started-*"))) < 2 and run.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    children = descendants(run.pid)
    assert len(children) >= 2 and run.poll() is None, run.stderr.read() if run.poll() is not None else ""
    if how == "ctrl-c":
        os.killpg(run.pid, signal.SIGINT)
    else:
        run.kill()
    run.wait(timeout=30)
    deadline = time.monotonic() + 5
    while not all(gone(pid) for pid in children) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert [pid for pid in children if not gone(pid)] == []
    if how == "ctrl-c":
        assert "KeyboardInterrupt" in run.stderr.read()  # the script, not a worker, was interrupted


def ready_then_sleep(seconds, connection):
    connection.send("ready")
    time.sleep(seconds)


def test_a_worker_ends_when_its_standard_input_closes():
    """The watch that needs no Linux parent-death signal: a worker whose standard input
    closes (as when its parent dies, or joins it) ends at once, long before its work would."""
    processes, pipes = start_workers(ready_then_sleep, [(60,)])
    assert pipes[0].recv() == "ready" and processes[0].is_alive()
    processes[0].join(timeout=0)  # gives up waiting at once, and closes its standard input
    processes[0].join(timeout=30)  # the work alone would take 60 s, and end with exit code 0
    assert processes[0].exitcode == 1
    pipes[0].close()


def test_a_frozen_application_is_told_to_name_a_python_interpreter(monkeypatch):
    """A frozen executable cannot run ``-c``: unless multiprocessing.set_executable names
    an interpreter, starting workers is refused with what to do, and nothing is started."""
    monkeypatch.setattr(sys, "frozen", True, raising=False)
    with pytest.raises(WorkerDied, match=r"multiprocessing.set_executable.*or run with jobs=1"):
        start_workers(ready_then_sleep, [(60,)])
