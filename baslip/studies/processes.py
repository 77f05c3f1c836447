"""Worker processes: starting them, hearing from them, and a map over both cores.

Two ways of spreading work over the cores rest on this module:

* the resumable study runner (:mod:`baslip.studies.runner`), whose workers take fixed
  lanes of tasks and send one CSV row per task;
* :func:`map_in_processes`, for work that is not a table of rows: a few long, independent
  items (the two directions of each bifurcation curve, the probes of a bisection), handed
  out one at a time to whichever worker is free, the results returned in item order.

Each worker is a fresh interpreter (CasADi's objects are not shared across a fork) started
from baslip's own entry point (:data:`baslip.children.WORKER_BOOTSTRAP`), not from the
caller's ``__main__``: multiprocessing's "spawn" would import the caller's script in every
worker, and a script without an ``if __name__ == "__main__":`` guard would start its run
again there. Workers talk over pipes (no semaphores, so no resource-tracker process can
outlive a killed run), and die with the process that started them (:mod:`baslip.children`).
They are not kept to cores of their own: a worker's threads may then use a core the other
leaves idle. (Kept to one core each, `optimal_upright` took 300 s instead of 257 s, and one
of its 108 cells ended at another local optimum, so its answers depended on the worker
count.) Each reports the code its libraries ran on (:class:`WorkerCode`) before the first
message that follows a library's loading, so the parent's provenance record holds it.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import multiprocessing.spawn
import os
import pickle
import signal
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any, cast

from baslip.children import WORKER_BOOTSTRAP, WORKER_OF, worker_start
from baslip.engine.codegen import leave_notices_to_parent, note_code, recording_code
from baslip.errors import RunError


class WorkerDied(RunError):
    """A worker process ended without finishing its work: the run stopped short."""


@dataclass(frozen=True)
class WorkerCode:
    """What the libraries of a worker ran on (see :func:`baslip.engine.codegen.recording_code`),
    sent before the first row that follows a library's loading."""

    routes: dict[str, str]


def worker_count(jobs: int | None, lanes: int) -> int:
    """Worker processes for ``lanes`` lanes (or items): ``jobs`` if given, else one per
    core; never more than the lanes."""
    wanted = jobs if jobs is not None else (os.cpu_count() or 1)
    return max(1, min(wanted, lanes))


class Reporting:
    """The queue a worker function puts its rows on: rows go to ``send`` as they are,
    each after a :class:`WorkerCode` if the worker has loaded libraries since the last,
    so that the parent records (and tells the user) what ran as soon as it is known."""

    def __init__(self, send: Callable[[object], None], used: dict[str, str]):
        self._send, self._used = send, used
        self._sent: dict[str, str] = {}

    def put(self, item) -> None:
        if item is None:  # a lane ends by end() alone, once its function has returned
            return
        self._send_code()
        self._send(item)

    def end(self, failure: str | None = None) -> None:
        """Send the lane's end: None, or, if its function raised, :class:`LaneFailed`."""
        self._send_code()
        self._send(None if failure is None else LaneFailed(failure))

    def _send_code(self) -> None:
        if self._used != self._sent:
            self._sent = dict(self._used)
            self._send(WorkerCode(self._sent))


@dataclass(frozen=True)
class LaneFailed:
    """A lane's function raised in its worker: what, in one line. The parent stops the run
    with it (:class:`WorkerDied`), keeping the rows that came before."""

    text: str


def start_workers(main: Callable, arguments: Sequence[tuple], duplex: bool = False) -> tuple[list, list]:
    """Start one worker process per entry of ``arguments``, running
    ``main(*entry, connection)``; return (processes, this process's ends of their pipes).
    Without ``duplex`` the pipes only carry messages from the workers. ``main`` and the
    entries travel pickled: they must be importable by name from outside ``__main__``.

    Raises
    ------
    WorkerDied
        If a worker's interpreter cannot be started.
    """
    pipes = [multiprocessing.Pipe(duplex=duplex) for _ in arguments]
    processes = []
    try:
        for entry, (_, theirs) in zip(arguments, pipes):
            processes.append(WorkerProcess(pickle.dumps((main, entry)), theirs))
    except BaseException:
        for process in processes:
            process.terminate()
            process.join()
        raise
    finally:
        for _, theirs in pipes:
            theirs.close()  # the worker holds its own copy; its end closes when it ends
    return processes, [ours for ours, _ in pipes]


class WorkerProcess:
    """One worker: a Python interpreter running :data:`~baslip.children.WORKER_BOOTSTRAP`,
    with what :class:`multiprocessing.Process` offers that this module uses (``pid``,
    ``exitcode``, ``is_alive``, ``terminate``, ``join``).

    The interpreter is multiprocessing's (``multiprocessing.set_executable`` changes it,
    as a frozen or embedded application must); ``end``, the worker's end of its pipe, is
    inherited by it, and its start (:func:`~baslip.children.worker_start`) goes on its
    standard input, which stays open, unread, until the worker is joined: the worker ends
    when it closes. Its environment names this process in ``BASLIP_WORKER_OF``.
    """

    def __init__(self, payload: bytes, end: Connection):
        executable = os.fsdecode(multiprocessing.spawn.get_executable())  # bytes on POSIX
        if getattr(sys, "frozen", False) and executable == sys.executable:
            raise WorkerDied("a frozen application starts baslip's worker processes only with a Python interpreter: "
                             "call multiprocessing.set_executable(<path of python>) first, or run with jobs=1")
        try:
            self._popen = subprocess.Popen([executable, "-c", WORKER_BOOTSTRAP], stdin=subprocess.PIPE,
                                           pass_fds=(end.fileno(),), env={**os.environ, WORKER_OF: str(os.getpid())})
        except OSError as err:
            raise WorkerDied(f"cannot start a worker process with {executable}: {err}") from None
        self.pid = self._popen.pid
        stdin = cast("Any", self._popen.stdin)
        try:
            stdin.write(pickle.dumps(worker_start(payload, end)))
            stdin.flush()
        except BrokenPipeError:
            pass  # it ended at once; the Inbox reads its exit code as that of any worker that died

    @property
    def exitcode(self) -> int | None:
        """The worker's exit code (negative: the signal that ended it), or None while it runs."""
        return self._popen.poll()

    def is_alive(self) -> bool:
        return self.exitcode is None

    def terminate(self) -> None:
        """Send SIGTERM (unless it has ended)."""
        if self.is_alive():
            self._popen.terminate()

    def join(self, timeout: float | None = None) -> None:
        """Wait up to ``timeout`` seconds (None: for ever) for the worker to end, then
        close its standard input, which ends it if it still runs."""
        try:
            self._popen.wait(timeout)
        except subprocess.TimeoutExpired:
            pass
        finally:
            self._close_stdin()

    def _close_stdin(self) -> None:
        stdin = self._popen.stdin
        if stdin is not None and not stdin.closed:
            with contextlib.suppress(BrokenPipeError):
                stdin.close()


def stop_workers(processes: list, inbox: Inbox) -> None:
    """End the workers that are still running and close their pipes."""
    for process in processes:
        if process.is_alive():
            process.terminate()
        process.join(timeout=5)
    inbox.close()


class Inbox:
    """The reading ends of the workers' pipes: the next message from any worker."""

    def __init__(self, readers: list, processes: list, poll: float = 1.0):
        self.readers, self.processes, self.poll = list(readers), processes, poll
        self._silent = dict(zip(readers, processes))  # workers that have sent nothing yet

    def next_row(self):
        """The next row (or WorkerCode, or None) from the workers; raises
        :class:`WorkerDied` if one ended before finishing its lanes."""
        return self.next_message()[1]

    def next_message(self) -> tuple[Any, object]:
        """(the pipe it came on, the next message from any worker); raises
        :class:`WorkerDied` if one ended before finishing its work."""
        while True:
            # wait() gives back the readers it was given: connections.
            ready = cast("list[Connection]", multiprocessing.connection.wait(self.readers, timeout=self.poll))
            for reader in ready:
                try:
                    message = reader.recv()
                except EOFError:  # that worker has ended; its exit code says how
                    self.readers.remove(reader)
                    continue
                self._silent.pop(reader, None)
                return reader, message
            dead = [p for p in self.processes if p.exitcode not in (None, 0)]
            if dead or not self.readers:
                raise WorkerDied(self._death(dead[0] if dead else None))

    def _death(self, process) -> str:
        code = process.exitcode if process is not None else 0
        silent = process is not None and process in self._silent.values()
        when = "before sending any row" if silent else "before finishing its tasks"
        # A worker's stderr is this process's: what it printed as it died is shown above.
        return f"a worker process ended with exit code {code} {when} (its error, if it printed one, is above)"

    def close(self) -> None:
        for reader in self.readers:
            reader.close()


def map_in_processes(make_task: Callable[[Any], Callable[[Any], Any]], items: Sequence, context: Any = None,
                     jobs: int | None = None, enough: Callable[[list], bool] | None = None) -> list:
    """``[task(item) for item in items]`` with ``task = make_task(context)``, the items
    handed out one at a time to worker processes (one per core, or ``jobs``, never more
    than the items) as each becomes free.

    With ``enough``, the map ends early: it returns the results of the shortest leading
    run of items for which ``enough(those results)`` holds (the workers still busy with
    later items are stopped), whatever order the results came in.

    ``make_task`` runs once per worker (so what it builds, such as a solver, is built once
    there) and must be a module-level function; items, context and results travel
    pickled. With one worker the map runs in this process. The results are the same
    either way, provided a task's result depends on its item alone (a task must start
    from no state that an earlier task left).

    Raises
    ------
    WorkerDied
        If a worker ends before returning all its results (an exception in a task ends its
        worker, with the traceback on stderr).
    """
    items = list(items)
    count = worker_count(jobs, len(items))
    results: dict[int, Any] = {}
    done = _LeadingRun(results, len(items), enough)
    if count <= 1:
        task = make_task(context)
        for index, item in enumerate(items):
            results[index] = task(item)
            if done.complete():
                break
        return done.results()
    processes, pipes = start_workers(_map_worker, [(make_task, context)] * count, duplex=True)
    inbox = Inbox(pipes, processes)
    pending = iter(enumerate(items))
    try:
        for pipe in pipes:
            pipe.send(next(pending, None))
        while not done.complete():
            pipe, message = inbox.next_message()
            if isinstance(message, WorkerCode):
                note_code(message.routes)
                continue
            index, result = cast("tuple[int, Any]", message)
            results[index] = result
            pipe.send(next(pending, None))  # the next item, or None: no more
    finally:
        stop_workers(processes, inbox)
    return done.results()


class _LeadingRun:
    """The results of a map so far, read as their longest leading run (items 0, 1, ...
    all answered): complete when that run is every item, or ``enough`` holds for it."""

    def __init__(self, results: dict[int, Any], total: int, enough: Callable[[list], bool] | None):
        self._results, self._total, self._enough = results, total, enough
        self._length, self._ended = 0, False

    def complete(self) -> bool:
        while not self._ended and self._length in self._results:
            self._length += 1
            # Checked at each length in turn: the shortest run that is enough, however
            # the results arrived.
            self._ended = self._enough is not None and self._enough(self.results())
        return self._ended or self._length == self._total

    def results(self) -> list:
        return [self._results[k] for k in range(self._length)]


def _map_worker(make_task, context, connection) -> None:
    """A worker of :func:`map_in_processes`: build the task, then answer each item sent
    ((index, item)) with (index, result) until None comes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops the workers itself
    leave_notices_to_parent()
    with recording_code() as used:
        reporting = Reporting(connection.send, used)
        task = make_task(context)
        while (job := connection.recv()) is not None:
            index, item = job
            reporting.put((index, task(item)))
