"""Diagnostics through :mod:`logging`: notes, progress and compile notices.

Every message baslip writes for a person while it works (a repaired results file, a
study's progress, a library being compiled, running without a C compiler) goes to the
logger of its module, under ``"baslip"``. Results and summaries are not diagnostics: the
command line prints those on stdout.

Nothing below the warning level is shown until someone asks. The command line, and
:func:`baslip.run` with ``progress=True``, call :func:`show_on_stderr`, which attaches
one :class:`ConsoleHandler` to the ``"baslip"`` logger unless the application has
configured logging itself (a handler on ``"baslip"`` or on the root logger): then the
application's handlers decide. Warnings reach stderr
either way (logging's last resort shows them when no handler is configured).

A progress line that should replace the previous one on a terminal is logged with
``extra=IN_PLACE``; the console handler rewrites it in place, and any other handler
writes it as an ordinary record.

A stage that may run long without news of its own (gcc compiling a library, an IPOPT
solve, a study's task) runs inside :func:`heartbeat`, which logs a line at least every
:data:`HEARTBEAT_S` seconds saying what still runs and for how long: nothing stays silent
for more than 10 s. When INFO records are not shown (``progress=False``, ``--quiet``, a
worker process) no heartbeat thread is started at all.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import threading
import time
from collections.abc import Callable, Iterator

#: The logger every baslip module's logger descends from.
ROOT_LOGGER = "baslip"
#: ``extra`` of a progress record that replaces the previous one on a terminal.
IN_PLACE = {"in_place": True}


def logger(module: str) -> logging.Logger:
    """The logger of a baslip module.

    Parameters
    ----------
    module : str
        The module's ``__name__`` (``baslip.studies.runner``, say).

    Returns
    -------
    logging.Logger
        Its logger, a descendant of ``"baslip"``.
    """
    return logging.getLogger(module)


class ConsoleHandler(logging.Handler):
    """Writes records as bare messages to the current ``sys.stderr``.

    The stream is looked up at each record, so a redirected ``sys.stderr`` (pytest's
    capture, ``contextlib.redirect_stderr``) receives them. A record logged with
    ``extra=IN_PLACE`` is written after a carriage return and without a line end, so the
    next one replaces it on a terminal; the next ordinary record first ends that line.
    """

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self._line_open = False

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = self.format(record)
            stream = sys.stderr
            if getattr(record, "in_place", False):
                stream.write(f"\r{text}   ")
                self._line_open = True
            else:
                stream.write(("\n" if self._line_open else "") + text + "\n")
                self._line_open = False
            stream.flush()
        except Exception:  # logging's own convention: a failing handler reports, never raises
            self.handleError(record)

    def end_line(self) -> None:
        """End a progress line left open by an in-place record, if there is one."""
        if self._line_open:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self._line_open = False


def show_on_stderr() -> None:
    """Show baslip's diagnostics of level INFO and above on stderr, unless the
    application configured logging itself; calling it again changes nothing."""
    base = logging.getLogger(ROOT_LOGGER)
    if base.handlers or logging.getLogger().handlers:
        return
    base.addHandler(ConsoleHandler())
    base.setLevel(logging.INFO)


@contextlib.contextmanager
def progress_hidden(hidden: bool = True) -> Iterator[None]:
    """Within the block, if ``hidden``, baslip's progress (INFO records: compiles, IPOPT
    tries, studies) is not shown, whatever handler shows it; warnings still are. For
    ``--quiet`` and ``progress=False``."""
    if not hidden:
        yield
        return
    base = logging.getLogger(ROOT_LOGGER)
    level = base.level
    base.setLevel(max(level, logging.WARNING))  # setLevel: the loggers' cached answers are cleared
    try:
        yield
    finally:
        base.setLevel(level)


def end_progress_line() -> None:
    """End the console's open progress line (before a result is printed on stdout)."""
    for handler in logging.getLogger(ROOT_LOGGER).handlers:
        if isinstance(handler, ConsoleHandler):
            handler.end_line()


#: Seconds between heartbeat lines: under 10, so that with a thread's scheduling delay no
#: stage stays silent for more than 10 s.
HEARTBEAT_S = 9.0


class Clock:
    """Time for heartbeats: the monotonic clock, and a call repeated on a daemon thread.

    Tests replace :data:`CLOCK` with a clock of their own whose time moves only when they
    move it, so that a stage's silences are measured without waiting.
    """

    def now(self) -> float:
        """Seconds on a monotonic clock [s]."""
        return time.monotonic()

    def every(self, seconds: float, beat: Callable[[], None]) -> Callable[[], None]:
        """Call ``beat`` every ``seconds`` [s] on a daemon thread until the returned
        function is called; that stops the thread and waits for it to end."""
        stop = threading.Event()

        def run() -> None:
            while not stop.wait(seconds):
                beat()

        thread = threading.Thread(target=run, name="baslip-heartbeat", daemon=True)
        thread.start()

        def halt() -> None:
            stop.set()
            thread.join()

        return halt


#: The clock heartbeats run on (a constant: only tests put another in its place).
CLOCK = Clock()


@contextlib.contextmanager
def heartbeat(log: logging.Logger, say: Callable[[float], str], *, in_place: bool = False) -> Iterator[None]:
    """Log ``say(elapsed)`` every :data:`HEARTBEAT_S` seconds while the block runs.

    Parameters
    ----------
    log : logging.Logger
        The logger of the module whose stage runs; nothing is started unless it shows
        INFO records.
    say : callable
        The line, from the seconds since the block began [s]; called on the heartbeat's
        thread, so it should only read state.
    in_place : bool
        Whether the line replaces the previous one on a terminal (``extra=IN_PLACE``).
    """
    if not log.isEnabledFor(logging.INFO):
        yield
        return
    clock = CLOCK
    start = clock.now()
    extra = IN_PLACE if in_place else None
    halt = clock.every(HEARTBEAT_S, lambda: log.info(say(clock.now() - start), extra=extra))
    try:
        yield
    finally:
        halt()
