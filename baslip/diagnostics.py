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
"""

from __future__ import annotations

import logging
import sys

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


def end_progress_line() -> None:
    """End the console's open progress line (before a result is printed on stdout)."""
    for handler in logging.getLogger(ROOT_LOGGER).handlers:
        if isinstance(handler, ConsoleHandler):
            handler.end_line()
