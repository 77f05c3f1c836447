"""Specification of baslip.studies.processes: worker processes and the map over both cores.

* The map returns ``task(item)`` in item order, whatever worker ran each item, and the
  same results with one worker (in this process) as with two.
* Each worker builds its task once and is handed items as it becomes free.
* With ``enough``, the map ends at the shortest leading run of results that is enough,
  whichever worker finished first.
* A worker that fails ends the map with :class:`WorkerDied`, not a hang.
"""

import os
import time

import pytest

from baslip.studies.processes import WorkerDied, map_in_processes


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
