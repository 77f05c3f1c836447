"""How long a thread spends setting up compiled libraries, apart from the work they do.

A first run on a new machine spends most of its time generating C and running gcc; a warm
one still loads libraries and builds what they need. A result that times "the solve"
should not hide that set-up in its solve time, nor the other way round (issue 56). The
set-up's wall time is counted per thread, so a background compile's own time is not
counted twice: only the time a thread spends waiting for it.

Blocks nest: only the outermost :func:`setting_up` block of a thread counts, so a
library loaded while an NLP is being built is counted once.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass


class _ThreadSetup(threading.local):
    """Each thread's set-up seconds so far, and how deep in set-up blocks it is. Process
    state on purpose, like :mod:`baslip.engine.codegen`'s record: the time a thread has
    spent is a fact about the thread, not about one object."""

    seconds = 0.0
    depth = 0


_SETUP = _ThreadSetup()


@contextlib.contextmanager
def setting_up() -> Iterator[None]:
    """Count the block's wall time as the calling thread's set-up (building, compiling or
    loading a library, or waiting for one compiled in the background)."""
    _SETUP.depth += 1
    start = time.perf_counter()
    try:
        yield
    finally:
        _SETUP.depth -= 1
        if _SETUP.depth == 0:
            _SETUP.seconds += time.perf_counter() - start


def setup_seconds() -> float:
    """The calling thread's set-up so far [s]: the wall time of its finished outermost
    set-up blocks."""
    return _SETUP.seconds


@dataclass(frozen=True)
class Stopwatch:
    """The start of a timed piece of work that may wait for set-up on the way.

    Attributes
    ----------
    wall : float
        :func:`time.perf_counter` at the start [s].
    setup : float
        :func:`setup_seconds` at the start [s].
    unreported : float
        :func:`setup_seconds` when set-up not yet reported by anyone began (the set-up
        between that and ``setup`` is reported with this piece of work) [s].
    """

    wall: float
    setup: float
    unreported: float

    @classmethod
    def start(cls, unreported: float | None = None) -> Stopwatch:
        """A stopwatch started now; ``unreported`` as the attribute (default: now)."""
        now = setup_seconds()
        return cls(time.perf_counter(), now, now if unreported is None else min(unreported, now))

    def split(self) -> tuple[float, float]:
        """(the work's wall time without set-up, the set-up to report with it) [s]."""
        setup_now = setup_seconds()
        work = time.perf_counter() - self.wall - (setup_now - self.setup)
        return max(work, 0.0), setup_now - self.unreported
