"""Diagnostics through logging: the console handler writes bare messages to the current
stderr, rewrites progress in place and ends that line before the next message; it is
installed once, and not over an application's own logging set-up."""

import logging
import threading

import pytest

from baslip import diagnostics


@pytest.fixture
def bare_logging(monkeypatch):
    """The baslip logger without handlers, and a call that takes the root logger's away
    (pytest's own capture among them, which it adds as the test starts), as in a fresh
    script; both are restored afterwards."""
    base, root = logging.getLogger(diagnostics.ROOT_LOGGER), logging.getLogger()
    monkeypatch.setattr(base, "handlers", [])
    monkeypatch.setattr(root, "handlers", [])
    monkeypatch.setattr(base, "level", logging.NOTSET)
    return base


def _a_fresh_script() -> None:
    logging.getLogger().handlers.clear()


def test_progress_is_rewritten_in_place_and_the_next_message_starts_a_line(bare_logging, capsys):
    _a_fresh_script()
    diagnostics.show_on_stderr()
    log = diagnostics.logger("baslip.studies.runner")
    log.info("grid: 1/4 done", extra=diagnostics.IN_PLACE)
    log.info("grid: 2/4 done", extra=diagnostics.IN_PLACE)
    log.warning("note: a row was repaired")
    log.info("grid: 3/4 done", extra=diagnostics.IN_PLACE)
    diagnostics.end_progress_line()
    diagnostics.end_progress_line()  # nothing left open: nothing written
    err = capsys.readouterr().err
    assert err == "\rgrid: 1/4 done   \rgrid: 2/4 done   \nnote: a row was repaired\n\rgrid: 3/4 done   \n"


def test_it_is_installed_once(bare_logging):
    _a_fresh_script()
    diagnostics.show_on_stderr()
    diagnostics.show_on_stderr()
    assert [type(h) for h in bare_logging.handlers] == [diagnostics.ConsoleHandler]


def test_an_application_that_configured_logging_keeps_its_own_handlers(bare_logging):
    _a_fresh_script()
    logging.getLogger().handlers.append(logging.StreamHandler())
    diagnostics.show_on_stderr()
    assert bare_logging.handlers == []


def test_a_heartbeat_speaks_every_few_seconds_while_its_block_runs_and_stops_with_it(fake_clock):
    clock = fake_clock()
    log = diagnostics.logger("baslip.engine.codegen")
    with diagnostics.heartbeat(log, lambda elapsed: f"still working, {elapsed:.0f} s"):
        clock.advance(35.0)
    clock.advance(60.0)  # after the block: nothing more
    assert clock.messages() == ["still working, 9 s", "still working, 18 s", "still working, 27 s"]
    assert clock.longest_silence(0.0, 35.0) <= 10.0
    assert clock.running() == 0


def test_a_heartbeat_starts_nothing_when_info_is_not_shown(fake_clock):
    clock = fake_clock(shown=False)
    with diagnostics.heartbeat(diagnostics.logger("baslip.x"), lambda elapsed: "still working"):
        assert clock.running() == 0
        clock.advance(35.0)
    assert clock.said == []


def test_the_real_clock_beats_on_a_daemon_thread_that_ends_when_stopped():
    beats = threading.Event()
    stop = diagnostics.Clock().every(0.01, beats.set)
    assert beats.wait(5.0)
    threads = [t for t in threading.enumerate() if t.name == "baslip-heartbeat"]
    assert threads and all(t.daemon for t in threads)
    stop()
    assert not any(t.name == "baslip-heartbeat" for t in threading.enumerate())


def test_progress_hidden_silences_progress_and_heartbeats_in_its_block_only(fake_clock):
    """``--quiet`` and ``progress=False``: inside the block no INFO record and no
    heartbeat, warnings still; after it, progress is shown again."""
    clock = fake_clock()
    log = diagnostics.logger("baslip.gait.tries")
    with diagnostics.progress_hidden():
        log.info("IPOPT try 2 of 2: starting")
        with diagnostics.heartbeat(log, lambda elapsed: "still solving"):
            assert clock.running() == 0
        log.warning("baslip: no working C compiler")
    with diagnostics.progress_hidden(False):
        log.info("shown")
    assert clock.messages() == ["baslip: no working C compiler", "shown"]
