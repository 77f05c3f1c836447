"""Specification of baslip.engine.setuptime: a thread's set-up is timed apart from its work
(a fake clock throughout: no test here waits)."""

import threading

import pytest

from baslip.engine import setuptime
from baslip.engine.setuptime import Stopwatch, setting_up, setup_seconds


@pytest.fixture
def clock(monkeypatch):
    """A clock that moves only when the test moves it: ``clock.advance(seconds)``."""

    class Clock:
        now = 1000.0

        def advance(self, seconds: float) -> None:
            self.now += seconds

    fake = Clock()
    monkeypatch.setattr(setuptime.time, "perf_counter", lambda: fake.now)
    return fake


def test_nested_set_up_counts_once(clock):
    before = setup_seconds()
    with setting_up():
        clock.advance(2.0)
        with setting_up():  # a library loaded while an NLP is built
            clock.advance(3.0)
        assert setup_seconds() == before  # counted when the outermost block ends
    assert setup_seconds() - before == pytest.approx(5.0)


def test_a_stopwatch_splits_work_from_the_set_up_it_waited_for(clock):
    unreported = setup_seconds()
    with setting_up():  # the solver's own set-up, before the solve
        clock.advance(40.0)
    watch = Stopwatch.start(unreported)
    clock.advance(0.25)  # work
    with setting_up():  # a library compiled on the way
        clock.advance(7.0)
    clock.advance(0.5)  # work
    work, setup = watch.split()
    assert work == pytest.approx(0.75) and setup == pytest.approx(47.0)


def test_another_threads_set_up_is_its_own(clock):
    before = setup_seconds()

    def compile_elsewhere():
        with setting_up():
            clock.advance(30.0)

    thread = threading.Thread(target=compile_elsewhere)
    thread.start()
    thread.join()
    assert setup_seconds() == before  # a background compile counts only where a thread waits for it
