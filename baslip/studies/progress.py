"""A study's progress on stderr: a bar on a terminal, a plain line every few seconds in a
log, and a heartbeat while no task finishes."""

from __future__ import annotations

import contextlib
import sys
from collections import deque

from baslip.diagnostics import HEARTBEAT_S, IN_PLACE, end_progress_line, heartbeat, logger

_log = logger(__name__)

#: Characters of the progress bar on a terminal.
BAR_WIDTH = 30
#: Seconds of recent progress from which the rate and time left are estimated.
RATE_WINDOW_S = 60.0


class Progress:
    """Progress on stderr: a bar rewritten in place on a terminal, and a plain line at
    most every ``every_s`` seconds otherwise, so that log files stay readable. (A small
    bar of our own rather than tqdm: no dependency, and the counts include the tasks
    done before a resume.) The rate is that of the last :data:`RATE_WINDOW_S` seconds: a
    study whose tasks differ in cost (the controllers study's batched runs, then its
    re-solves) would otherwise promise the fast tasks' pace for the slow ones."""

    def __init__(self, label: str, total: int, quiet: bool, every_s: float = HEARTBEAT_S):
        self.label, self.total, self.quiet, self.every_s = label, total, quiet, every_s
        self.terminal = sys.stderr.isatty()
        self._last = -every_s
        self._history: deque[tuple[float, int]] = deque([(0.0, 0)])
        self._done = 0
        self._note = ""

    def running(self, done: int = 0):
        """A context in which the state is said again at least every 10 s (with the time
        so far and the latest note from inside a task), even while no task finishes: a
        task may take minutes. ``done``: the tasks done before (on a resume)."""
        self._done = done
        if self.quiet:
            return contextlib.nullcontext()
        _log.info(f"{self.label}: {done}/{self.total} done, starting the rest", extra=IN_PLACE if self.terminal else None)
        return heartbeat(_log, self._still, in_place=self.terminal)

    def _still(self, elapsed: float) -> str:
        text = f"{self.label}: {self._done}/{self.total} done, {elapsed:.0f} s so far, tasks running"
        return f"{text}; {self._note}" if self._note else text

    def note(self, text: str) -> None:
        """Keep ``text``, news from inside a running task, for the next line."""
        self._note = text

    def rate(self, ran: int, elapsed: float) -> float:
        """Tasks a second over the last :data:`RATE_WINDOW_S` seconds (since the start
        while younger), once ``ran`` tasks have run by ``elapsed`` seconds."""
        while len(self._history) > 1 and elapsed - self._history[1][0] >= RATE_WINDOW_S:
            self._history.popleft()
        then, ran_then = self._history[0]
        self._history.append((elapsed, ran))
        return (ran - ran_then) / (elapsed - then) if elapsed > then else 0.0

    def update(self, done: int, ran: int, elapsed: float) -> None:
        self._done, self._note = done, ""  # a task ended: its news are old
        if self.quiet:
            return
        rate = self.rate(ran, elapsed)
        eta = (self.total - done) / rate if rate > 0 else float("inf")
        text = f"{self.label}: {done}/{self.total} done, {rate:.2f}/s, about {eta:.0f} s left"
        if self.terminal:  # a bar, rewritten in place
            filled = int(BAR_WIDTH * done / self.total) if self.total else BAR_WIDTH
            bar = "#" * filled + "-" * (BAR_WIDTH - filled)
            _log.info(f"{self.label} [{bar}] {done}/{self.total}, {rate:.2f}/s, about {eta:.0f} s left", extra=IN_PLACE)
        elif elapsed - self._last >= self.every_s or done == self.total:
            self._last = elapsed
            _log.info(text)

    def interrupted(self, done: int, why: str = "interrupted") -> None:
        # "done", not "saved": a run without an output folder keeps none of them.
        if not self.quiet:
            _log.warning(f"{self.label}: {why}; {done} of {self.total} rows were done")

    def close(self) -> None:
        if not self.quiet:
            end_progress_line()
