"""A clock for heartbeat tests, in place of :data:`baslip.diagnostics.CLOCK`.

Its time moves only when a test, or a slow stub standing in for gcc, IPOPT or a worker,
moves it with :meth:`FakeClock.advance`; the heartbeats due meanwhile run at once, in the
caller's thread, each at its own (fake) time. Every baslip record is kept with the fake
time it was logged at, so a test measures a stage's longest silence without waiting.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Iterator

from baslip import diagnostics


class FakeClock(logging.Handler):
    """A fake :class:`~baslip.diagnostics.Clock`, and a handler keeping ``said``: (fake
    time [s], message) of each record."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.time = 0.0
        self.said: list[tuple[float, str]] = []
        self._beats: dict[int, list] = {}
        self._count = 0

    def now(self) -> float:
        return self.time

    def every(self, seconds, beat):
        self._count += 1
        key = self._count
        self._beats[key] = [self.time + seconds, seconds, beat]
        return lambda: self._beats.pop(key, None)

    def advance(self, seconds: float) -> None:
        """Move time on by ``seconds``, running each heartbeat that falls due on the way."""
        end = self.time + seconds
        while due := [(entry[0], key) for key, entry in self._beats.items() if entry[0] <= end]:
            when, key = min(due)
            self.time = when
            entry = self._beats[key]
            entry[0] += entry[1]
            entry[2]()
        self.time = end

    def running(self) -> int:
        """Heartbeats not stopped yet."""
        return len(self._beats)

    def emit(self, record: logging.LogRecord) -> None:
        self.said.append((self.time, record.getMessage()))

    def longest_silence(self, start: float = 0.0, end: float | None = None) -> float:
        """The longest time [s] between ``start``, the records and ``end`` (now)."""
        times = [start, *sorted(t for t, _ in self.said if t >= start), self.time if end is None else end]
        return max(b - a for a, b in zip(times, times[1:]))

    def messages(self) -> list[str]:
        return [message for _, message in self.said]


@contextlib.contextmanager
def clock_in_place(shown: bool = True) -> Iterator[FakeClock]:
    """A :class:`FakeClock` in place of baslip's clock for the block, hearing baslip's
    records; with ``shown`` INFO records are shown (as the command line and
    ``progress=True`` show them), else only warnings (``progress=False``, ``--quiet``)."""
    clock = FakeClock()
    base = logging.getLogger(diagnostics.ROOT_LOGGER)
    level, real_clock = base.level, diagnostics.CLOCK
    diagnostics.CLOCK = clock
    base.addHandler(clock)
    base.setLevel(logging.INFO if shown else logging.WARNING)  # setLevel: the loggers' caches are cleared
    try:
        yield clock
    finally:
        base.setLevel(level)
        base.removeHandler(clock)
        diagnostics.CLOCK = real_clock


def collect_in_thread(worker, lane: list[dict], context, progress, table) -> tuple[int, bool, str]:
    """Run a study's ``worker`` on ``lane`` in a thread of this process (in place of a
    worker process, so that it shares the fake clock), its rows collected on this thread
    as a study collects them; what the collection returns."""
    from baslip.studies.processes import Reporting
    from baslip.studies.runner import _collect, run_lane

    items: queue.Queue = queue.Queue()
    thread = threading.Thread(target=run_lane, args=(worker, lane, context, Reporting(items.put, {})), daemon=True)

    def next_row():
        if thread.ident is None:  # started once the collection (and its heartbeat) has begun
            thread.start()
        return items.get()

    collected = _collect(next_row, 1, table, progress, 0, time.perf_counter())
    thread.join()
    return collected
